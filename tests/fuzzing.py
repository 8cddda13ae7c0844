"""Seeded mutation fuzzing of the files users hand to drake-lfd: task files and joint logs.

Each generator turns a few valid inputs (the paper's task files, the bundled
demonstrations' joint logs) into damaged ones, one :class:`FuzzCase` at a time, the
same cases for the same seed. The mutation classes are those of the reliability issue,
each named so a finding can be traced to its class:

- task files (:data:`TASK_MUTATIONS`): truncated text and lines, missing and extra
  fields, wrong types, YAML tags (``!!float abc``, ``!!int 0.5``, ``!!python/object``),
  deep nesting, alias bombs, huge, NaN, infinite and ``1e300`` numbers, bounded angles
  with huge ranges, tiny angle grids, many free angles, many configurations, undefined
  variables, Unicode digits, ``0_5``, duplicate keys, empty files, binary garbage; and
  combinations of two or three of these;
- joint logs (:data:`LOG_MUTATIONS`): truncation anywhere and inside the last value,
  joint jumps (teleports), timestamps in milliseconds or nanoseconds, reversed or
  repeated timestamps, reordered, duplicated, missing and extra columns, non-numeric,
  empty, NaN and infinite cells, Unicode digits and ``0_5``, stationary logs, degrees
  for radians, comma, space, tab and mixed separators, CRLF, a byte-order mark, empty
  files and binary garbage; a few cases also get a damaged ``--name`` (too long, not
  ASCII) or go to a new library directory.

A case carries the field a refusal should name where the mutation knows it (the task
file's top-level key it changed); the harness that runs the cases through the command
line and judges the outcome is ``benchmarks/fuzz_inputs.py`` (docs/cli.rst, Fuzzed inputs),
its seeded sample ``tests/test_fuzz_inputs.py``. Test tooling, kept beside its tests and
out of the installed package (the benchmark imports it from ``tests/``). :func:`non_finite_json_tokens` counts
``NaN``/``Infinity`` in a JSON text.

Not for: running commands, judging results (the harness does), valid-input generation
for experiments (``planning/random_tasks.py``).
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import random
import re
from typing import Callable, Iterator

import yaml

from drake_lfd.core.resources import scenarios_directory

__all__ = [
    "FuzzCase",
    "TASK_MUTATIONS",
    "LOG_MUTATIONS",
    "default_task_bases",
    "default_log_bases",
    "task_cases",
    "log_cases",
    "non_finite_json_tokens",
]

# A bounded angle's refusal names the angle, or (the problem-size check) the grid.
_ANGLE_FIELDS = "critical_configurations|angle_grid_deg"
_UNICODE_DIGITS = (
    "\u0660\u0661\u0662\u0663\u0664\u0665\u0666\u0667\u0668\u0669",  # Arabic-Indic
    "\uff10\uff11\uff12\uff13\uff14\uff15\uff16\uff17\uff18\uff19",  # fullwidth
    "\u0966\u0967\u0968\u0969\u096a\u096b\u096c\u096d\u096e\u096f",  # Devanagari
)
_HUGE_NUMBERS = ("1e300", "-1e300", "1e309", "-1e309", ".nan", ".NaN", ".inf", "-.inf", "nan", "inf",
                 "1e-320", "9" * 400, "-" + "9" * 40, "1e18", "0x7fffffff", "1e3000")
_TAGS = ("!!float abc", "!!int 0.5", "!!int abc", "!!float", "!!python/object:os.system", "!!python/name:os.system",
         "!!python/object/apply:os.system ['true']", "!!binary AAAA", "!!timestamp yesterday", "!!bool maybe",
         "!!str 1", "!!null x", "!!set {a, b}", "!!omap [a: 1]", "!Custom 3", "!!map [1, 2]", "!!seq {a: 1}")
_WRONG_VALUES = ("abc", "", "~", "true", "[]", "{}", "[1, 2]", "{a: 1}", "[[1, 2], [3]]", "-", "'1'", "0.5.5",
                 "pi/0", "0/0", "1/0", "pipi", "deg", "90 deg deg", "1,5", "[1, 2, 3, 4, 5]", "[a, b, c]",
                 "2pi/", "*pi", "inf*pi", "1e400deg", "[null, null, null]")


@dataclasses.dataclass(frozen=True)
class FuzzCase:
    """One fuzzed input.

    Attributes
    ----------
    index : int
        Its number in the seeded sequence.
    kind : str
        ``"task"`` (a task file for ``plan``) or ``"log"`` (a joint log for ``library add``).
    mutation : str
        The mutation classes applied, joined by ``+``.
    data : bytes
        The file's content.
    field : str or None
        The top-level field a refusal of this case should name, if known; ``a|b``: either.
        (A refusal by the YAML reader names the line and column instead.)
    name : str
        The ``--name`` for a log (``fuzz_<index>`` unless the name is fuzzed).
    new_library : bool
        For a log: add it to a new library directory instead of an existing library.
    """

    index: int
    kind: str
    mutation: str
    data: bytes
    field: str | None = None
    name: str = ""
    new_library: bool = False


# ---------------------------------------------------------------------------- task files


def default_task_bases() -> dict[str, str]:
    """The paper's task files (``sims/*.yaml``): name -> text."""
    directory = scenarios_directory()
    return {path.stem: path.read_text(encoding="utf-8") for path in sorted(directory.glob("*.yaml"))}


_Dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _dump(data) -> str:
    return yaml.dump(data, Dumper=_Dumper, default_flow_style=None, sort_keys=False, width=10_000)


def _paths(value, prefix=()):
    """Every (path, value) of a nested structure, containers included."""
    yield prefix, value
    if isinstance(value, dict):
        for key, item in value.items():
            yield from _paths(item, prefix + (key,))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            yield from _paths(item, prefix + (index,))


def _get(data, path):
    for key in path:
        data = data[key]
    return data


def _set(data, path, value):
    _get(data, path[:-1])[path[-1]] = value


def _top(path):
    return str(path[0]) if path else None


def _structured(rng, text):
    data = yaml.load(text, Loader=_Loader)
    return data if isinstance(data, dict) else {"name": "x"}


def _leaf_paths(data):
    return [path for path, value in _paths(data) if path and not isinstance(value, (dict, list))]


def _angle_paths(data):
    found = []
    for index, con in enumerate(data.get("critical_configurations") or []):
        if isinstance(con, dict) and isinstance(con.get("euler_zyx"), list):
            found += [("critical_configurations", index, "euler_zyx", axis) for axis in range(len(con["euler_zyx"]))]
    return found


def _replace_leaf_text(rng, data, path, raw):
    """``data`` dumped with the value at ``path`` replaced by the raw YAML text ``raw``."""
    marker = f"FUZZMARKER{rng.randrange(10**9)}"
    _set(data, path, marker)
    return _dump(data).replace(marker, raw, 1)


def truncate_text(rng, text):
    return text[: rng.randrange(len(text) + 1)], None


def truncate_line(rng, text):
    lines = text.splitlines(keepends=True)
    index = rng.randrange(len(lines))
    line = lines[index]
    lines[index] = line[: rng.randrange(len(line) + 1)] if rng.random() < 0.7 else ""
    return "".join(lines), None


def missing_field(rng, text):
    data = _structured(rng, text)
    candidates = [path for path, _ in _paths(data) if path and isinstance(path[-1], str)]
    path = rng.choice(candidates)
    del _get(data, path[:-1])[path[-1]]
    return _dump(data), _top(path)


def missing_list_item(rng, text):
    data = _structured(rng, text)
    candidates = [path for path, value in _paths(data) if isinstance(value, list) and value]
    if not candidates:
        return missing_field(rng, text)
    path = rng.choice(candidates)
    items = _get(data, path)
    del items[rng.randrange(len(items))]
    # One configuration fewer can make a path constraint's numbers the first problem.
    return _dump(data), (None if _top(path) == "critical_configurations" else _top(path))


def extra_field(rng, text):
    data = _structured(rng, text)
    candidates = [path for path, value in _paths(data) if isinstance(value, dict)]
    path = rng.choice(candidates)
    key = rng.choice(["extra", "P", "eulerzyx", "angle_grid", "notes", "obstacle", "velocity", "_ignored"])
    _get(data, path)[key] = rng.choice([1, "x", [1, 2, 3], {"a": 1}])
    return _dump(data), (key if not path else _top(path))


def extra_list_item(rng, text):
    data = _structured(rng, text)
    candidates = [path for path, value in _paths(data) if isinstance(value, list) and value]
    if not candidates:
        return extra_field(rng, text)
    path = rng.choice(candidates)
    items = _get(data, path)
    items.insert(rng.randrange(len(items) + 1), copy.deepcopy(rng.choice(items)) if rng.random() < 0.5 else 0.1)
    return _dump(data), _top(path)


def wrong_type(rng, text):
    data = _structured(rng, text)
    path = rng.choice([path for path, _ in _paths(data) if path])
    return _replace_leaf_text(rng, data, path, rng.choice(_WRONG_VALUES)), _top(path)


def yaml_tag(rng, text):
    data = _structured(rng, text)
    path = rng.choice(_leaf_paths(data))
    return _replace_leaf_text(rng, data, path, rng.choice(_TAGS)), None


def deep_nesting(rng, text):
    data = _structured(rng, text)
    path = rng.choice([path for path, _ in _paths(data) if path])
    depth = rng.choice([20, 33, 64, 200, 500, 2000, 10_000])
    if rng.random() < 0.5:
        raw = "[" * depth + "1" + "]" * depth
    else:
        raw = "{a: " * depth + "1" + "}" * depth
    return _replace_leaf_text(rng, data, path, raw), None


def block_nesting(rng, text):
    depth = rng.choice([40, 300, 1000])
    lines = ["_deep:"] + ["  " * level + "-" for level in range(1, depth)] + ["  " * depth + "- x"]
    return text + "\n" + "\n".join(lines) + "\n", None


def alias_bomb(rng, text):
    levels = rng.choice([6, 9, 12])
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for level in range(1, levels):
        previous = f"*a{level - 1}"
        lines.append(f"a{level}: &a{level} [{', '.join([previous] * 9)}]")
    if rng.random() < 0.5:  # as ignored root keys (anchors for reuse)
        return text + "\n" + "\n".join("_" + line for line in lines) + "\n", None
    data = _structured(rng, text)
    path = rng.choice([path for path, _ in _paths(data) if path])
    body = _replace_leaf_text(rng, data, path, f"*a{levels - 1}")
    return "_bomb:\n" + "\n".join("  " + line for line in lines) + "\n" + body, None


def huge_number(rng, text):
    data = _structured(rng, text)
    numbers = [path for path in _leaf_paths(data) if isinstance(_get(data, path), (int, float))]
    path = rng.choice(numbers or _leaf_paths(data))
    return _replace_leaf_text(rng, data, path, rng.choice(_HUGE_NUMBERS)), _top(path)


def huge_position(rng, text):
    data = _structured(rng, text)
    cons = [i for i, con in enumerate(data.get("critical_configurations") or []) if isinstance(con, dict) and "p" in con]
    if not cons:
        return huge_number(rng, text)
    index = rng.choice(cons)
    value = rng.choice(["1e300", "-1e300", "1e10", "[-1e300, 1e300]", "[0, 1e300]", "999.9", "1000.1", "[1, -1]"])
    path = ("critical_configurations", index, "p", rng.randrange(3))
    return _replace_leaf_text(rng, data, path, value), "critical_configurations"


def huge_angle_range(rng, text):
    data = _structured(rng, text)
    paths = _angle_paths(data)
    if not paths:
        return huge_number(rng, text)
    path = rng.choice(paths)
    value = rng.choice(["[-pi, 1e9]", "[-1e6, 1e6]", "[-1e300, 1e300]", "[0, 1e-300]", "[pi, -pi]", "[-100pi, 100pi]",
                        "[-720deg, 720deg]", "[0, 0]", "[-pi, .nan]", "[-.inf, .inf]", "[-pi, pi, 0]", "[1]"])
    return _replace_leaf_text(rng, data, path, value), _ANGLE_FIELDS


def tiny_angle_grid(rng, text):
    data = _structured(rng, text)
    value = rng.choice(["0.5", "0.1", "0.01", "1e-300", "0", "-15", ".nan", ".inf", "1e9", "1", "2", "3", "abc",
                        "[15]", "15deg", "5e-324"])
    if rng.random() < 0.6:  # with free angles, so the grid matters
        for path in rng.sample(_angle_paths(data), k=min(len(_angle_paths(data)), rng.randint(1, 4))):
            _set(data, path, "FUZZFREE")
    data["angle_grid_deg"] = "FUZZGRID"
    text = _dump(data).replace("FUZZGRID", value, 1).replace("FUZZFREE", "[-pi, pi]")
    return text, _ANGLE_FIELDS


def many_free_angles(rng, text):
    data = _structured(rng, text)
    paths = _angle_paths(data)
    if not paths:
        return huge_number(rng, text)
    chosen = rng.sample(paths, k=rng.randint(1, len(paths)))
    bound = rng.choice(["[-pi, pi]", "[-pi/2, pi/2]", "[0, 2*pi]", "[-3*pi, 3*pi]"])
    for path in chosen:
        _set(data, path, "FUZZFREE")
    if rng.random() < 0.5:
        data["angle_grid_deg"] = rng.choice([1, 2, 5, 10, 15, 30])
    return _dump(data).replace("'FUZZFREE'", bound).replace("FUZZFREE", bound), _ANGLE_FIELDS


def many_configurations(rng, text):
    data = _structured(rng, text)
    cons = [con for con in (data.get("critical_configurations") or []) if isinstance(con, dict)]
    if not cons:
        return huge_number(rng, text)
    count = rng.choice([1, 2, 30, 200, 3000])
    data["critical_configurations"] = "FUZZCONS"
    lines = [_dump([rng.choice(cons)]).strip() for _ in range(min(count, 8))]
    items = "\n".join(rng.choice(lines) for _ in range(count))
    return _dump(data).replace("FUZZCONS", "\n" + items, 1), None  # other fields may now be wrong


def undefined_variable(rng, text):
    data = _structured(rng, text)
    cons = [i for i, con in enumerate(data.get("critical_configurations") or []) if isinstance(con, dict) and "p" in con]
    if not cons:
        return huge_number(rng, text)
    path = ("critical_configurations", rng.choice(cons), "p", rng.randrange(3))
    value = rng.choice(["w", "x", "pi", "z2", "_x", "Ω", "nan", "-x", "x*2"])
    if rng.random() < 0.3:
        data["variables"] = {value: rng.choice([[0, 1], [1, 0], [0, "1e300"], 5, "abc"])}
    return _replace_leaf_text(rng, data, path, value), None


def unicode_digits(rng, text):
    digits = rng.choice(_UNICODE_DIGITS)
    positions = [i for i, ch in enumerate(text) if ch.isdigit()]
    if not positions:
        return text + "\nangle_grid_deg: " + digits[1] + digits[5] + "\n", "angle_grid_deg"
    chars = list(text)
    for i in rng.sample(positions, k=min(len(positions), rng.randint(1, 3))):
        chars[i] = digits[int(chars[i])] if chars[i] in "0123456789" else chars[i]
    if rng.random() < 0.3:  # a Unicode space too
        spaces = [i for i, ch in enumerate(chars) if ch == " "]
        if spaces:
            chars[rng.choice(spaces)] = rng.choice(["\u00a0", "\u2003", "\u3000"])
    return "".join(chars), None


def underscore_numbers(rng, text):
    data = _structured(rng, text)
    numbers = [path for path in _leaf_paths(data) if isinstance(_get(data, path), (int, float))]
    if not numbers:
        return unicode_digits(rng, text)
    path = rng.choice(numbers)
    return _replace_leaf_text(rng, data, path, rng.choice(["0_5", "1_000", "0_1", "-0_2", "0b1", "0o7", "0x1F",
                                                            "+.5", "1.", "1_0pi", "9_0deg"])), _top(path)


def duplicate_key(rng, text):
    lines = text.splitlines(keepends=True)
    keyed = [i for i, line in enumerate(lines) if ":" in line and not line.lstrip().startswith("#")]
    if not keyed:
        return text + "\nname: a\nname: b\n", "name"
    index = rng.choice(keyed)
    if rng.random() < 0.5:
        lines.insert(index + 1, lines[index] if lines[index].endswith("\n") else lines[index] + "\n")
        return "".join(lines), None
    data = _structured(rng, text)  # a flow mapping with a key twice
    dicts = [path for path, value in _paths(data) if path and isinstance(value, dict) and value]
    if not dicts:
        return "".join(lines), None
    path = rng.choice(dicts)
    mapping = _get(data, path)
    key = rng.choice(list(mapping))
    flow = "{" + ", ".join(f"{k}: {json.dumps(v)}" for k, v in mapping.items()) + f", {key}: 0" + "}"
    return _replace_leaf_text(rng, data, path, flow), None  # a YAML error names the line


def empty_file(rng, text):
    return rng.choice(["", " ", "\n\n", "---\n", "~\n", "null\n", "# only a comment\n", "[]\n", "{}\n", "...\n",
                       "--- \n---\n", "0\n", "'just a string'\n", "- a\n- b\n", "name:\n", "critical_configurations:\n",
                       "critical_configurations: []\nname: x\n"]), None


def binary_garbage(rng, text):
    size = rng.choice([1, 16, 300, 4000])
    kind = rng.random()
    if kind < 0.3:
        return bytes(rng.randrange(256) for _ in range(size)), None
    if kind < 0.5:
        return b"\xef\xbb\xbf" + text.encode(), None  # a byte-order mark
    if kind < 0.6:
        return text.encode("utf-16"), None
    if kind < 0.8:
        data = bytearray(text.encode())
        for _ in range(rng.randint(1, 8)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        return bytes(data), None
    return text.encode()[: len(text) // 2] + b"\x00\x00\xff\xfe" + text.encode()[len(text) // 2:], None


def byte_flip(rng, text):
    chars = list(text)
    for _ in range(rng.randint(1, 5)):
        i = rng.randrange(len(chars))
        chars[i] = rng.choice(list("[]{}:,-&*!|>'\"#%@`\t \n0.9e+") + [chr(rng.randrange(32, 127))])
    return "".join(chars), None


def path_constraint_damage(rng, text):
    data = _structured(rng, text)
    constraint = {"kind": rng.choice(["orientation", "position", "", 1]),
                  "between": rng.choice([[1, 4], [4, 1], [0, 2], [1, 1], [1, 99], [1.5, 2], [-1, 2], [1]]),
                  "euler_zyx": rng.choice([[0, "-pi/2", 0], [0, 0], "x", [0, 0, "1e300"]]),
                  "tolerance_deg": rng.choice([10, 0, -5, 1e300, "nan", 360, 1e-9])}
    data["path_constraints"] = [constraint]
    return _dump(data), "path_constraints"


def box_damage(rng, text):
    data = _structured(rng, text)
    key = rng.choice(["obstacles", "safety_shells", "tool"])
    if key == "tool":
        data[key] = [rng.choice([{"name": "t", "cylinder": {"radius": -1, "length": 0.1}},
                                 {"name": "t", "box": [0, 0, 0]}, {"name": "t", "sphere": 0.1},
                                 {"name": "t", "box": [1e300, 1, 1]}, {"name": "", "box": [0.1, 0.1, 0.1]},
                                 {"box": [0.1, 0.1, 0.1], "cylinder": {"radius": 0.1, "length": 0.1}}])]
    else:
        data[key] = [rng.choice([{"name": "b", "centre": [0, 0, 0], "size": [-1, 1, 1]},
                                 {"name": "b", "centre": [0, 0], "size": [1, 1, 1]},
                                 {"name": "b", "centre": [1e300, 0, 0], "size": [1, 1, 1]},
                                 {"name": "b", "centre": [0, 0, 0], "size": [1e6, 1e6, 1e6]},
                                 {"name": "b", "centre": [0, 0, 0], "size": [0, 0, 0]},
                                 {"name": "a", "centre": [0, 0, 0], "size": [0.1, 0.1, 0.1]}] * 2)]
    return _dump(data), key


TaskMutation = Callable[[random.Random, str], "tuple[str | bytes, str | None]"]

#: Mutation class name -> function(rng, text) -> (damaged text or bytes, field or None).
TASK_MUTATIONS: dict[str, TaskMutation] = {
    "truncate_text": truncate_text,
    "truncate_line": truncate_line,
    "missing_field": missing_field,
    "missing_list_item": missing_list_item,
    "extra_field": extra_field,
    "extra_list_item": extra_list_item,
    "wrong_type": wrong_type,
    "yaml_tag": yaml_tag,
    "deep_nesting": deep_nesting,
    "block_nesting": block_nesting,
    "alias_bomb": alias_bomb,
    "huge_number": huge_number,
    "huge_position": huge_position,
    "huge_angle_range": huge_angle_range,
    "tiny_angle_grid": tiny_angle_grid,
    "many_free_angles": many_free_angles,
    "many_configurations": many_configurations,
    "undefined_variable": undefined_variable,
    "unicode_digits": unicode_digits,
    "underscore_numbers": underscore_numbers,
    "duplicate_key": duplicate_key,
    "empty_file": empty_file,
    "binary_garbage": binary_garbage,
    "byte_flip": byte_flip,
    "path_constraint_damage": path_constraint_damage,
    "box_damage": box_damage,
}

# Mutations that only work on text (a later one cannot parse their output).
_TEXT_ONLY = {"many_configurations", "truncate_text", "truncate_line", "empty_file", "binary_garbage", "byte_flip", "unicode_digits",
              "duplicate_key", "alias_bomb", "block_nesting", "deep_nesting", "yaml_tag"}


def task_cases(count: int, seed: int = 0, bases: dict[str, str] | None = None) -> Iterator[FuzzCase]:
    """``count`` fuzzed task files, the same for the same ``seed`` and bases.

    Every mutation class comes in turn (so a small sample covers them all); about one
    case in five combines a structural mutation with one or two others.
    """
    bases = bases or default_task_bases()
    base_names = sorted(bases)
    names = sorted(TASK_MUTATIONS)
    for index in range(count):
        rng = random.Random(f"task:{seed}:{index}")
        text = bases[rng.choice(base_names)]
        first = names[index % len(names)]
        chain = [first]
        if rng.random() < 0.2 and first not in _TEXT_ONLY:
            chain += rng.sample(names, k=rng.randint(1, 2))
        data: str | bytes = text
        field = None
        applied = []
        for name in chain:
            if isinstance(data, bytes):
                break
            try:
                data, this_field = TASK_MUTATIONS[name](rng, data)
            except (yaml.YAMLError, ValueError, TypeError, KeyError, IndexError, AttributeError):
                continue  # the text is past parsing after an earlier mutation: stop there
            applied.append(name)
            field = this_field if field is None else field
            if name in _TEXT_ONLY:
                break
        payload = data if isinstance(data, bytes) else data.encode("utf-8", "surrogatepass")
        yield FuzzCase(index=index, kind="task", mutation="+".join(applied) or "none", data=payload,
                       field=field if len(applied) == 1 else None)


# ----------------------------------------------------------------------------- joint logs


def default_log_bases(every: int = 4) -> dict[str, list[list[str]]]:
    """The bundled demonstrations' joint logs (``sims/demos/*.csv``), every ``every``-th
    row (so cases stay small; the motion is unchanged): name -> rows of cells, header first."""
    directory = scenarios_directory() / "demos"
    bases = {}
    for path in sorted(directory.glob("*.csv")):
        lines = path.read_text(encoding="utf-8").splitlines()
        rows = [line.split(",") for line in lines]
        bases[path.stem] = [rows[0]] + rows[1::every]
    return bases


def _csv(rows, separator=",", newline="\n", final_newline=True):
    text = newline.join(separator.join(row) for row in rows)
    return text + (newline if final_newline else "")


def _data_rows(rows):
    return rows[1:]


def _column(rows, name):
    return rows[0].index(name) if name in rows[0] else None


def log_truncate_last_value(rng, rows):
    text = _csv(rows)[:-1]  # no final newline
    last = re.split(r"[, ]", text)[-1]
    return text[: len(text) - rng.randrange(1, max(2, len(last)))].encode()


def log_truncate_anywhere(rng, rows):
    text = _csv(rows)
    return text[: rng.randrange(len(text) + 1)].encode()


def log_truncate_line(rng, rows):
    lines = _csv(rows).splitlines(keepends=True)
    index = rng.randrange(1, len(lines))
    lines[index] = lines[index][: rng.randrange(len(lines[index]))] + "\n"
    return "".join(lines).encode()


def log_joint_jump(rng, rows):
    rows = [list(row) for row in rows]
    start = rng.randrange(1, len(rows))
    length = rng.choice([1, 1, 3, len(rows)])
    joint = rng.randrange(6)
    jump = rng.choice([0.5, 1.0, 3.0, -2.0, 6.0, 0.05])
    for row in rows[start: start + length]:
        row[1 + joint] = repr(float(row[1 + joint]) + jump)
    return _csv(rows).encode()


def log_time_units(rng, rows):
    rows = [list(row) for row in rows]
    factor = rng.choice([1e3, 1e6, 1e9, 1e-3, 60.0])
    offset = rng.choice([0.0, 0.0, 1.7e9, 1.7e12])
    for row in rows[1:]:
        row[0] = repr(float(row[0]) * factor + offset)
    return _csv(rows).encode()


def log_time_order(rng, rows):
    rows = [list(row) for row in rows]
    kind = rng.random()
    if kind < 0.3:
        rows = [rows[0]] + rows[:0:-1]  # reversed
    elif kind < 0.6:
        i = rng.randrange(2, len(rows))
        rows[i][0] = rows[i - 1][0]  # a repeated timestamp
    elif kind < 0.8:
        i = rng.randrange(1, len(rows) - 1)
        rows[i], rows[i + 1] = rows[i + 1], rows[i]
    else:
        for row in rows[1:]:
            row[0] = "0.0"
    return _csv(rows).encode()


def log_reorder_columns(rng, rows):
    order = list(range(len(rows[0])))
    rng.shuffle(order)
    if rng.random() < 0.7:  # header and values together: the same log
        shuffled = [[row[i] for i in order] for row in rows]
    else:  # the header alone: other joints
        shuffled = [[rows[0][i] for i in order]] + [list(row) for row in rows[1:]]
    return _csv(shuffled).encode()


def log_duplicate_column(rng, rows):
    column = rng.randrange(len(rows[0]))
    position = rng.randrange(len(rows[0]) + 1)
    duplicated = [row[:position] + [row[column]] + row[position:] for row in rows]
    return _csv(duplicated).encode()


def log_missing_column(rng, rows):
    column = rng.randrange(len(rows[0]))
    if rng.random() < 0.3:  # the cells only, the header keeps the name
        kept = [rows[0]] + [row[:column] + row[column + 1:] for row in rows[1:]]
    else:
        kept = [row[:column] + row[column + 1:] for row in rows]
    return _csv(kept).encode()


def log_extra_columns(rng, rows):
    names = rng.sample(["runtime_state", "target_q_0", "actual_TCP_pose_0", "robot_mode", "safety_mode", "actual_q_6",
                        "actual_qd_0", "", "timestamp2", "Actual_Q_0"], k=rng.randint(1, 3))
    values = {"runtime_state": lambda i: rng.choice(["2", "2", "2", "1", "0", "2.0", "x"]),
              "robot_mode": lambda i: "7"}
    extended = [rows[0] + names]
    for i, row in enumerate(rows[1:]):
        extended.append(row + [values.get(name, lambda i: repr(rng.uniform(-1, 1)))(i) for name in names])
    return _csv(extended).encode()


def log_bad_cell(rng, rows):
    rows = [list(row) for row in rows]
    for _ in range(rng.randint(1, 3)):
        i = rng.randrange(1, len(rows))
        j = rng.randrange(len(rows[i]))
        rows[i][j] = rng.choice(["", "abc", "nan", "NaN", "inf", "-inf", "1e400", "-1e400", "0x10", "1,5", "--1",
                                 "1e", ".", "+", "None", "null", "True", "１", "\u0661", "0_5", "1_000", " 1 ",
                                 "\u00a01", "1e-400", "1.5.5", "\"1\"", "'1'"])
    return _csv(rows).encode()


def log_stationary(rng, rows):
    first = rows[1]
    stationary = [rows[0]] + [[row[0]] + first[1:] for row in rows[1:]]
    if rng.random() < 0.3:  # a tiny drift only
        stationary = [rows[0]] + [[row[0]] + [repr(float(v) + 1e-12 * k) for v in first[1:]]
                                  for k, row in enumerate(rows[1:])]
    return _csv(stationary).encode()


def log_degrees(rng, rows):
    converted = [rows[0]] + [[row[0]] + [repr(math.degrees(float(v))) for v in row[1:]] for row in rows[1:]]
    return _csv(converted).encode()


def log_separators(rng, rows):
    kind = rng.choice(["space", "spaces", "tab", "semicolon", "mixed", "trailing", "crlf", "cr", "bom", "quoted"])
    if kind == "space":
        return _csv(rows, " ").encode()
    if kind == "spaces":
        return "\n".join("   ".join(row) + "  " for row in rows).encode() + b"\n"
    if kind == "tab":
        return _csv(rows, "\t").encode()
    if kind == "semicolon":
        return _csv(rows, ";").encode()
    if kind == "mixed":
        return "\n".join(",".join(row) if rng.random() < 0.9 else " ".join(row) for row in rows).encode() + b"\n"
    if kind == "trailing":
        return "\n".join(",".join(row) + "," for row in rows).encode() + b"\n"
    if kind == "crlf":
        return _csv(rows, ",", "\r\n").encode()
    if kind == "cr":
        return _csv(rows, ",", "\r").encode()
    if kind == "bom":
        return b"\xef\xbb\xbf" + _csv(rows).encode()
    return "\n".join(",".join(f'"{cell}"' for cell in row) for row in rows).encode() + b"\n"


def log_unicode_digits(rng, rows):
    text = _csv(rows)
    digits = rng.choice(_UNICODE_DIGITS + ("0_",))
    chars = list(text)
    positions = [i for i, ch in enumerate(chars) if ch in "0123456789" and i > len(",".join(rows[0]))]
    for i in rng.sample(positions, k=min(len(positions), rng.randint(1, 3))):
        chars[i] = digits[int(chars[i])] if digits != "0_" else chars[i] + "_"
    return "".join(chars).encode()


def log_short(rng, rows):
    kind = rng.choice(["empty", "header", "one", "two", "blank_lines", "comment", "no_header", "whitespace"])
    if kind == "empty":
        return b""
    if kind == "header":
        return _csv(rows[:1]).encode()
    if kind == "one":
        return _csv(rows[:2]).encode()
    if kind == "two":
        return _csv(rows[:3]).encode()
    if kind == "blank_lines":
        return ("\n\n" + _csv(rows).replace("\n", "\n\n")).encode()
    if kind == "comment":
        return ("# recorded by ur_rtde\n" + _csv(rows)).encode()
    if kind == "no_header":
        return _csv(rows[1:]).encode()
    return b"   \n\t\n"


def log_binary(rng, rows):
    kind = rng.random()
    if kind < 0.4:
        return bytes(rng.randrange(256) for _ in range(rng.choice([1, 64, 5000])))
    if kind < 0.6:
        return _csv(rows).encode("utf-16")
    data = bytearray(_csv(rows).encode())
    for _ in range(rng.randint(1, 6)):
        data[rng.randrange(len(data))] = rng.choice([0, 0xff, 0xc3, 0x80, ord(","), ord("\n")])
    return bytes(data)


def log_huge_values(rng, rows):
    rows = [list(row) for row in rows]
    i = rng.randrange(1, len(rows))
    j = rng.randrange(1, len(rows[i]))
    rows[i][j] = rng.choice(["1e300", "-1e300", "1e308", "7", "-7", "6.3", "100", "1e-300"])
    return _csv(rows).encode()


def log_long_line(rng, rows):
    rows = [list(row) for row in rows]
    i = rng.randrange(1, len(rows))
    rows[i][rng.randrange(len(rows[i]))] = "1" * rng.choice([400, 100_000])
    return _csv(rows).encode()


LogMutation = Callable[[random.Random, list], bytes]

#: Mutation class name -> function(rng, rows) -> the damaged log's bytes.
LOG_MUTATIONS: dict[str, LogMutation] = {
    "truncate_last_value": log_truncate_last_value,
    "truncate_anywhere": log_truncate_anywhere,
    "truncate_line": log_truncate_line,
    "joint_jump": log_joint_jump,
    "time_units": log_time_units,
    "time_order": log_time_order,
    "reorder_columns": log_reorder_columns,
    "duplicate_column": log_duplicate_column,
    "missing_column": log_missing_column,
    "extra_columns": log_extra_columns,
    "bad_cell": log_bad_cell,
    "stationary": log_stationary,
    "degrees": log_degrees,
    "separators": log_separators,
    "unicode_digits": log_unicode_digits,
    "short": log_short,
    "binary": log_binary,
    "huge_values": log_huge_values,
    "long_line": log_long_line,
}

_FUZZED_NAMES = ("a" * 240, "a" * 300, "b" * 120, "demo.csv", "../escape", "", "naïve", "with space", "-", "x" * 60,
                 "CON", "nul\x00", "screw_cw", "SCREW_CW", "a/b", ".hidden")


def log_cases(count: int, seed: int = 0, bases: dict[str, list[list[str]]] | None = None) -> Iterator[FuzzCase]:
    """``count`` fuzzed joint logs, the same for the same ``seed`` and bases.

    Every mutation class comes in turn; about one case in ten has a fuzzed ``--name``
    (too long for a file name, not ASCII, a path, a name the library holds), one in
    five goes to a new library directory.
    """
    bases = bases or default_log_bases()
    base_names = sorted(bases)
    names = sorted(LOG_MUTATIONS)
    for index in range(count):
        rng = random.Random(f"log:{seed}:{index}")
        rows = [list(row) for row in bases[rng.choice(base_names)]]
        if rng.random() < 0.3:  # a shorter stretch of the motion
            start = rng.randrange(1, len(rows) // 2)
            rows = [rows[0]] + rows[start: start + rng.randint(3, len(rows) - start)]
        mutation = names[index % len(names)]
        data = LOG_MUTATIONS[mutation](rng, rows)
        name = f"fuzz_{index}"
        if rng.random() < 0.1:
            name = rng.choice(_FUZZED_NAMES)
            mutation += "+name"
        yield FuzzCase(index=index, kind="log", mutation=mutation, data=data, name=name,
                       new_library=rng.random() < 0.2)


# ----------------------------------------------------------------------------------- JSON


def non_finite_json_tokens(text: str) -> int:
    """How many ``NaN``, ``Infinity`` and ``-Infinity`` tokens a JSON text holds (outside
    strings); -1 if the text is not JSON at all."""
    found = []
    try:
        json.loads(text, parse_constant=lambda token: found.append(token) or 0.0)
    except ValueError:
        return -1
    return len(found)
