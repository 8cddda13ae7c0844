"""Reading user YAML files into Spec dataclasses: syntax, nesting, duplicated keys, structure, loading.

Task files (``task_files.py``), people files (``people_files.py``) and guidance scripts
(``guidance_scripts.py``) are YAML loaded with ``pydrake.common.yaml.yaml_load_typed``
into ``*Spec`` dataclasses. Run alone, that function names only the leaf of a bad value,
and PyYAML silently keeps the last of two equal keys. So :func:`load_spec` first reads
the raw YAML (refusing duplicated keys) and checks it against the Spec types
(:func:`check_schema`), and only then calls ``yaml_load_typed``. Before any of that, the
YAML's nesting is checked without recursion (at most :data:`MAX_YAML_DEPTH` levels: a
file nested 500 deep would otherwise exhaust Python's recursion limit), and a value that
an explicit tag cannot convert (``!!float abc``, ``!!int 0.5``) is refused with its line.
Every problem becomes one :class:`~drake_lfd.core.errors.InputError` that names the file
and the field (``waypoints[2].euler_zyx[0]``, list indices from 0); the values are then
checked one by one by ``yaml_values.py``.

Conventions of the Spec dataclasses: a field made with :func:`required` must be
present; a field's ``metadata["expected"]`` says in words what a union field accepts;
angles can be written as numbers, as multiples of pi or in degrees
(``yaml_values.angle_from_text``); orientations are ``euler_zyx: [yaw, pitch, roll]``,
``R = Rz(yaw) Ry(pitch) Rx(roll)`` (docs/method.rst, Conventions;
:func:`~drake_lfd.core.tasks.rigid_transform_from_euler_zyx`).

Reading and checking the structure (:func:`check_yaml_file`, :func:`check_schema`)
imports neither Drake nor numpy, so the command line refuses a typo'd key at once;
:func:`plain_load` makes the Spec ``yaml_load_typed`` would, in plain Python, so the
values are checked before Drake loads too (``task_checks.py``); Drake is imported when
a Spec is loaded (:func:`load_spec`).

Not for: the values (``yaml_values.py``) or what a file means (its own module checks
that: ranges, ordering, names), nor logs and libraries (``demonstration_logs.py``,
``library.py``).
"""

# No ``from __future__ import annotations``: :data:`Scalar` is used in the Spec
# dataclasses' annotations, and yaml_load_typed reads those as types, not as strings.
import dataclasses
import re
import sys
import types
import typing
from pathlib import Path
from typing import Union

import yaml

from drake_lfd.core.errors import InputError

__all__ = [
    "MAX_YAML_DEPTH",
    "MAX_YAML_FILE_BYTES",
    "Scalar",
    "required",
    "PoseSpec",
    "UniqueKeyLoader",
    "yaml_error",
    "check_yaml_depth",
    "read_text",
    "load_spec",
    "check_yaml_file",
    "kind_of",
    "check_schema",
    "NeedsDrake",
    "plain_load",
]

#: Largest YAML file read, in bytes: a task file is a few kilobytes; parsing megabytes
#: of YAML takes seconds per megabyte before anything could be checked.
MAX_YAML_FILE_BYTES = 1 << 20
#: Deepest nesting of mappings and lists a file may have (a task file needs 5).
MAX_YAML_DEPTH = 32

# One number-like token: a YAML number, or a string such as "-pi/2", "90deg", "1e-3".
Scalar = Union[float, int, str]

_DESCRIPTIONS = {Scalar: "a number"}


def required(factory):
    """A Spec dataclass field that :func:`check_schema` requires in the file."""
    return dataclasses.field(default_factory=factory, metadata={"required": True})


@dataclasses.dataclass
class PoseSpec:
    """A fixed pose: ``p`` in metres, ``euler_zyx`` = [yaw, pitch, roll] in radians
    (identity if absent); :func:`pose` checks it into a ``RigidTransform``."""

    p: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0])
    euler_zyx: list[Scalar] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0])


# ----------------------------------------------------------------------------- reading


# libyaml's parser when PyYAML has it (about 10 times faster on a large file), else PyYAML's own.
_SafeLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class UniqueKeyLoader(_SafeLoader):
    """A SafeLoader that refuses a key written twice in one mapping (PyYAML silently
    keeps the last one) and says where."""

    def construct_mapping(self, node, deep=False):
        if not isinstance(node, yaml.MappingNode):  # ``!!map [1, 2]``: a tag on another kind
            raise yaml.constructor.ConstructorError(
                None, None, f"the tag {node.tag.replace('tag:yaml.org,2002:', '!!')} needs a mapping", node.start_mark,
            )
        seen = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=deep)
            try:
                if key in seen:
                    raise yaml.constructor.ConstructorError(
                        None,
                        None,
                        f"key {key!r} appears twice in one mapping (first on line {seen[key] + 1})",
                        key_node.start_mark,
                    )
                seen[key] = key_node.start_mark.line
            except TypeError:
                pass  # unhashable keys are reported by the schema check
        return super().construct_mapping(node, deep=deep)

    def _decimal_only(self, node):
        text = str(node.value)
        if "_" in text or ":" in text or re.match(r"^[-+]?0[0-9box]", text):
            raise yaml.constructor.ConstructorError(
                None, None,
                f"{text!r} is a number only YAML 1.1 spells so (digit separators '_', octal, hex, binary or "
                "base-60); write it in decimal digits, such as 0.5 or 5",
                node.start_mark,
            )

    def construct_yaml_int(self, node):
        self._decimal_only(node)
        return super().construct_yaml_int(node)

    def construct_yaml_float(self, node):
        self._decimal_only(node)
        return super().construct_yaml_float(node)

    def construct_object(self, node, deep=False):
        # A tag that cannot convert its value (``!!float abc``, ``!!int 0.5``) raises a
        # bare ValueError in PyYAML; make it a YAML error that knows the line.
        try:
            return super().construct_object(node, deep=deep)
        except yaml.YAMLError:
            raise
        except (ValueError, TypeError, OverflowError, LookupError, AttributeError):  # ``!!bool maybe``
            tag = node.tag.replace("tag:yaml.org,2002:", "!!")
            raise yaml.constructor.ConstructorError(
                None, None, f"the tag {tag} cannot read {getattr(node, 'value', '')!r}",
                node.start_mark,
            ) from None


UniqueKeyLoader.add_constructor("tag:yaml.org,2002:int", UniqueKeyLoader.construct_yaml_int)
UniqueKeyLoader.add_constructor("tag:yaml.org,2002:float", UniqueKeyLoader.construct_yaml_float)


def check_yaml_depth(text, file, limit=MAX_YAML_DEPTH):
    """Refuses YAML nested more than ``limit`` levels deep, reading its events (no
    recursion, so any depth is safe to check).

    Raises
    ------
    InputError
        Naming the line where the limit is passed, or a YAML syntax error.
    """
    depth = 0
    try:
        for event in yaml.parse(text, Loader=_SafeLoader):
            if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                depth += 1
                if depth > limit:
                    mark = event.start_mark
                    raise InputError(
                        f"nested more than {limit} levels deep (mappings and lists); no drake-lfd file needs that",
                        file=file, field=f"line {mark.line + 1} column {mark.column + 1}",
                    )
            elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                depth -= 1
    except yaml.YAMLError as error:
        raise yaml_error(error, file) from None


def yaml_error(error, file):
    """The :class:`InputError` for a ``yaml.YAMLError``, naming the line and column."""
    mark = getattr(error, "problem_mark", None)
    problem = getattr(error, "problem", None) or getattr(error, "reason", None) or str(error)
    problem = " ".join(str(problem).split())  # one line (PyYAML's messages have several)
    field = None if mark is None else f"line {mark.line + 1} column {mark.column + 1}"
    if mark is None and isinstance(error, yaml.reader.ReaderError):  # a character YAML forbids
        field = f"character {error.position + 1}"
        code = error.character if isinstance(error.character, int) else ord(error.character)
        problem = f"{problem} (U+{code:04X})"
    if "could not determine a constructor" in problem:
        problem = "YAML tags (!Name) are not used in task files"
    return InputError(f"not valid YAML: {problem}", file=file, field=field)


def read_text(path, *, directory_problem=None):
    """The text of the user file ``path`` (UTF-8).

    Raises
    ------
    InputError
        The file is missing or unreadable. If ``directory_problem`` is given, it is the
        message when ``path`` is a directory; otherwise the generic "cannot read" is used.
    """
    path = Path(path)
    try:
        with path.open("rb") as file:
            data = file.read(MAX_YAML_FILE_BYTES + 1)
        if len(data) > MAX_YAML_FILE_BYTES:
            raise InputError(f"larger than {MAX_YAML_FILE_BYTES // 2**20} MiB; a drake-lfd YAML file is a few kilobytes",
                             file=path)
        return data.decode("utf-8")
    except FileNotFoundError:
        raise InputError("no such file", file=path) from None
    except IsADirectoryError as error:
        problem = directory_problem or f"cannot read: {error}"
        raise InputError(problem, file=path) from None
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(f"cannot read: {error}", file=path) from None


def load_spec(text, schema, *, file, document, keys):
    """Loads YAML text into the Spec dataclass ``schema``, checking its structure first.

    Root keys starting with ``_`` are ignored, as in pydrake's ``yaml_load`` (they hold
    anchors for reuse).

    Parameters
    ----------
    text : str
    schema : dataclass type
    file : str or Path or None
        Named in errors.
    document, keys : str
        Used in the messages "``{document}`` is empty" and "expected a mapping of
        ``{keys}``", for example ``"the task file"`` and ``"task keys"``.

    Raises
    ------
    InputError
        Invalid YAML, a duplicated or unknown key, or a value of the wrong kind.
    """
    check_yaml_file(text, schema, file=file, document=document, keys=keys)
    from pydrake.common.yaml import yaml_load_typed

    try:
        return yaml_load_typed(schema=schema, data=text)
    except Exception as error:  # anything left is still the file's fault
        raise InputError(f"cannot load: {error}", file=file) from None


def check_yaml_file(text, schema, *, file, document, keys):
    """The first half of :func:`load_spec`, in plain Python: the YAML's nesting, its
    syntax, duplicated keys, and its structure against the Spec dataclass ``schema``
    (key names, kinds of values, required keys). Parameters and errors as
    :func:`load_spec`.

    Returns
    -------
    dict
        The raw YAML mapping, root keys starting with ``_`` left out.
    """
    check_yaml_depth(text, file)
    try:
        raw = yaml.load(text, Loader=UniqueKeyLoader)
    except yaml.YAMLError as error:
        raise yaml_error(error, file) from None
    except RecursionError:  # deep aliases; the depth check above covers plain nesting
        raise InputError(f"nested too deeply (more than {MAX_YAML_DEPTH} levels)", file=file) from None
    except (ValueError, TypeError, OverflowError, LookupError, AttributeError) as error:  # a lazily built tag
        raise InputError(f"not valid YAML: {error}", file=file) from None
    if raw is None:
        raise InputError(f"{document} is empty", file=file)
    if not isinstance(raw, dict):
        raise InputError(f"expected a mapping of {keys}, got {kind_of(raw)}", file=file)
    raw = {key: value for key, value in raw.items() if not (isinstance(key, str) and key.startswith("_"))}
    check_schema(raw, schema, "", file)
    return raw


# ------------------------------------------------------------------------------ schema


def kind_of(value):
    """A short description of a raw YAML value for use in error messages."""
    if value is None:
        return "nothing (an empty value)"
    if isinstance(value, bool):
        return f"{str(value).lower()} (YAML reads yes/no/on/off/true/false as booleans)"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    return repr(value)


def _describe(schema):
    if schema in _DESCRIPTIONS:
        return _DESCRIPTIONS[schema]
    if schema is float:
        return "a number"
    if schema is int:
        return "an integer"
    if schema is str:
        return "a string"
    origin = typing.get_origin(schema)
    if origin is list:
        return "a list"
    if origin in (Union, types.UnionType):
        return " or ".join(dict.fromkeys(_describe(alternative) for alternative in typing.get_args(schema)))
    return "a mapping"


def _matches_scalar(value, schema):
    if isinstance(value, bool) or value is None:
        return False
    if schema is float:
        if isinstance(value, float):
            return True
        if isinstance(value, int):  # an integer of hundreds of digits is no float
            return abs(value) < 2**1023
        if isinstance(value, str):  # PyYAML reads 1e-3 (no dot) as a string
            try:
                float(value)
            except ValueError:
                return False
            return True
        return False
    if schema is int:
        return isinstance(value, int) or (isinstance(value, float) and value.is_integer())
    if schema is str:
        return isinstance(value, str)
    raise TypeError(schema)


def _join(path, key):
    return f"{path}.{key}" if path else str(key)


def check_schema(value, schema, path, file, expected=None):
    """Checks raw YAML data against a Spec type, so that errors name the exact field.

    Run alone, ``yaml_load_typed`` names only the leaf, and it iterates over mappings
    given where a list is expected. ``path`` is the field's name so far (``""`` at the
    root); ``expected`` says in words what a union accepts (from the field's metadata).

    Raises
    ------
    InputError
        A value of the wrong kind, an unknown key, or a missing :func:`required` field.
    """
    if schema is bool:
        if not isinstance(value, bool):
            raise InputError(f"expected true or false, got {kind_of(value)}", file=file, field=path)
        return
    if schema in (float, int, str):
        if not _matches_scalar(value, schema):
            raise InputError(f"expected {_describe(schema)}, got {kind_of(value)}", file=file, field=path)
        return
    origin = typing.get_origin(schema)
    if origin in (Union, types.UnionType):
        alternatives = typing.get_args(schema)
        if isinstance(value, list):
            for alternative in alternatives:
                if typing.get_origin(alternative) is list:
                    check_schema(value, alternative, path, file)
                    return
        elif isinstance(value, dict):  # an optional block: Optional[SomeSpec] or Optional[dict[...]]
            for alternative in alternatives:
                if dataclasses.is_dataclass(alternative) or typing.get_origin(alternative) is dict:
                    check_schema(value, alternative, path, file)
                    return
        elif any(
            alternative in (float, int, str) and _matches_scalar(value, alternative)
            for alternative in alternatives
        ) or (bool in alternatives and isinstance(value, bool)):
            return
        raise InputError(f"expected {expected or _describe(schema)}, got {kind_of(value)}", file=file, field=path)
    if origin is list:
        if not isinstance(value, list):
            raise InputError(f"expected a list, got {kind_of(value)}", file=file, field=path)
        (item_schema,) = typing.get_args(schema)
        for index, item in enumerate(value):
            check_schema(item, item_schema, f"{path}[{index}]", file, expected)
        return
    if origin is dict:
        if not isinstance(value, dict):
            raise InputError(f"expected a mapping, got {kind_of(value)}", file=file, field=path)
        _, item_schema = typing.get_args(schema)
        for key, item in value.items():
            if not isinstance(key, str):
                raise InputError(
                    f"key {kind_of(key)} is not a name; quote it", file=file, field=path
                )
            check_schema(item, item_schema, _join(path, key), file)
        return
    if schema is typing.Any:  # a block checked by its own loader (a task file's simulation: block)
        return
    numpy = sys.modules.get("numpy")  # no schema can name numpy's array before numpy is imported
    if numpy is not None and schema is numpy.ndarray:  # a vector in one of Drake's structs (Rgba's rgba)
        if not isinstance(value, list) or not all(_matches_scalar(item, float) for item in value):
            raise InputError(f"expected a list of numbers, got {kind_of(value)}", file=file, field=path)
        return
    drake_fields = None if dataclasses.is_dataclass(schema) else getattr(schema, "__fields__", None)
    if drake_fields is not None:
        # One of Drake's config structs bound with DefAttributesUsingSerialize
        # (MultibodyPlantConfig, SimulatorConfig, VisualizationConfig, Rgba): every field
        # optional, none with metadata.
        if not isinstance(value, dict):
            raise InputError(f"expected a mapping, got {kind_of(value)}", file=file, field=path or None)
        hints = {field.name: field.type for field in drake_fields}
        for key in value:
            if not isinstance(key, str):
                raise InputError(f"key {kind_of(key)} is not a name; quote it", file=file, field=path or None)
            if key not in hints:
                raise InputError(f"unknown key {key!r} (allowed: {', '.join(hints)})", file=file,
                                 field=_join(path, key))
            check_schema(value[key], hints[key], _join(path, key), file)
        return
    if dataclasses.is_dataclass(schema):
        if not isinstance(value, dict):
            raise InputError(f"expected a mapping, got {kind_of(value)}", file=file, field=path or None)
        fields = {field.name: field for field in dataclasses.fields(schema)}
        hints = typing.get_type_hints(schema)
        for key in value:
            if not isinstance(key, str):
                raise InputError(f"key {kind_of(key)} is not a name; quote it", file=file, field=path or None)
            if key not in fields:
                allowed = ", ".join(fields)
                problem = f"unknown key {key!r} (allowed: {allowed})"
                if key == "_tag":
                    problem = "YAML tags (!Name) are not used in task files"
                raise InputError(problem, file=file, field=_join(path, key))
        for name, field in fields.items():
            if name not in value:
                if field.metadata.get("required"):
                    raise InputError("missing", file=file, field=_join(path, name))
                continue
            check_schema(value[name], hints[name], _join(path, name), file, field.metadata.get("expected"))
        return
    raise TypeError(f"unsupported schema {schema!r}")


# ------------------------------------------------------------------- loading, plainly


class NeedsDrake(Exception):
    """Raised by a check in plain Python where only Drake's loader, or a record that
    imports Drake, can say what comes next (a Drake config struct in the file, a body's
    proportions, a track file): the early check stops there, and loading the file
    finds the rest in its own order."""


_NONE_TYPE = type(None)


def plain_load(raw, schema):
    """What ``yaml_load_typed(schema=schema, ...)`` makes of ``raw``, YAML data that
    :func:`check_schema` accepted against ``schema``, in plain Python.

    The same conversions as Drake's loader for the kinds of fields the Spec dataclasses
    use: an integer into a float field becomes a float, a numeric string into a float
    field the float it spells, a whole float into an integer field an integer; unions of
    numbers and strings keep the value as written; a mapping into a nested Spec updates
    that Spec's defaults; an absent key keeps its default.

    Raises
    ------
    NeedsDrake
        For anything else (a Drake config struct among the types, or a value Drake's
        loader would refuse where :func:`check_schema` did not).
    """
    try:
        return _plain_value(raw, schema, None)
    except NeedsDrake:
        raise
    except Exception as error:  # the loader would judge it: let it
        raise NeedsDrake(f"{type(error).__name__}: {error}") from None


def _plain_value(value, schema, current):
    if schema in (float, int, str, bool):
        converted = _plain_scalar(value, schema)
        if converted is None:
            raise NeedsDrake(f"{value!r} into {schema.__name__}")
        return converted
    origin = typing.get_origin(schema)
    arguments = typing.get_args(schema)
    if origin in (Union, types.UnionType):
        if len(arguments) == 2 and arguments[1] is _NONE_TYPE:  # Optional[X]
            if value is None:
                return None
            (inner,) = arguments[:1]
            if current is None:
                current = _plain_default(inner)
            return _plain_value(value, inner, current)
        if not isinstance(value, (dict, list)):
            if type(value) in arguments:
                return value
            raise NeedsDrake(f"{value!r} into {schema}")
        if "_tag" in value:  # the loader reads a variant's tag there
            raise NeedsDrake("a _tag")
        inner = arguments[0]
        inner_origin = typing.get_origin(inner) or inner
        return _plain_value(value, inner, current if isinstance(current, inner_origin) else _plain_default(inner))
    if origin is list:
        (item,) = arguments
        return [_plain_value(entry, item, _plain_default(item)) for entry in value]
    if origin is dict:
        _, item = arguments
        merged = dict(current or {})
        for key, entry in value.items():
            merged[key] = _plain_value(entry, item, merged[key] if key in merged else _plain_default(item))
        return merged
    if dataclasses.is_dataclass(schema):
        instance = current if current is not None else schema()
        instance = dataclasses.replace(instance)  # the loader merges into a copy
        hints = typing.get_type_hints(schema)
        for field in dataclasses.fields(schema):
            if field.name in value:
                setattr(instance, field.name, _plain_value(value[field.name], hints[field.name],
                                                           getattr(instance, field.name)))
        return instance
    raise NeedsDrake(f"a field of type {schema!r}")


def _plain_default(schema):
    """``_create_from_schema``'s value: None for a union, else ``schema()``."""
    if typing.get_origin(schema) in (Union, types.UnionType):
        return None
    return (typing.get_origin(schema) or schema)()


def _plain_scalar(value, schema):
    """``_convert_yaml_primitive_to_schema_type``: the value as ``schema``, or None."""
    if type(value) is schema:
        return value
    if type(value) is int and schema is float:
        return float(value)
    if type(value) is float and schema is int and value.is_integer():
        return int(value)
    if type(value) is str and schema in (float, int):
        return schema(value)
    if type(value) is str and schema is bool and value in ("true", "false"):
        return value == "true"
    return None
