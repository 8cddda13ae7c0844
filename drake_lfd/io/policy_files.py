"""Q-policy files: a trained ``QPolicy`` as JSON (format_version 1), saved atomically.

The document (see docs/cli.rst for the commands that read and write it)::

    {"format_version": 1, "kind": "drake-lfd afterstate Q-table",
     "parameters": {...QLearningParameters...}, "library_demos": [...],
     "library_feature_sha256": {name: hex}, "training_episodes": N,
     "values": {key: W}, "illegal_action_values": {key: Q}}

Files written before ``QLearningParameters.epsilon`` was renamed
``greedy_probability`` (same meaning: the probability of the greedy action) are read
as if they had the new name. ``library_feature_sha256`` (the hash of each training
demonstration's feature, ``planning.training.feature_hash``) is optional: files written
before it was kept load without it.

:func:`check_policy_library` compares what a policy was trained with against the library
it is about to plan with (``plan`` and ``simulate`` call it; ``train --warm-start`` does
not: retraining with a new demonstration is what warm start is for).

Not for: learning or planning (``planning/q_learning.py``); other JSON documents
(``plan_json.py``).
"""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np

from drake_lfd.core.errors import HINT, Hint, InputError
from drake_lfd.io.atomic_files import atomic_write_bytes
from drake_lfd.planning.q_learning import QLearningParameters, QPolicy
from drake_lfd.planning.training import feature_hashes

__all__ = [
    "POLICY_FORMAT_VERSION",
    "POLICY_KIND",
    "policy_document",
    "policy_from_document",
    "save_policy",
    "load_policy",
    "policy_library_mismatch",
    "check_policy_library",
]

POLICY_FORMAT_VERSION = 1
POLICY_KIND = "drake-lfd afterstate Q-table"

# Parameter names of older files -> current names.
_RENAMED_PARAMETERS = {"epsilon": "greedy_probability"}


def policy_document(policy: QPolicy) -> dict:
    """The JSON document of ``policy`` (keys sorted, so equal tables give equal files)."""
    return {
        "format_version": POLICY_FORMAT_VERSION,
        "kind": POLICY_KIND,
        "parameters": dataclasses.asdict(policy.parameters),
        "library_demos": list(policy.library_demos),
        **({} if policy.library_feature_hashes is None
           else {"library_feature_sha256": dict(policy.library_feature_hashes)}),
        "training_episodes": policy.training_episodes,
        "values": dict(sorted(policy.values.items())),
        "illegal_action_values": dict(sorted(policy.illegal_values.items())),
    }


def _parameters(raw: dict) -> QLearningParameters:
    renamed = {}
    for name, value in raw.items():
        new = _RENAMED_PARAMETERS.get(name, name)
        if new != name and new in raw:
            continue  # both spellings: the current one wins
        renamed[new] = value
    return QLearningParameters(**renamed)


def policy_from_document(document, file: str | None = None) -> QPolicy:
    """A QPolicy from a parsed policy document; InputError naming ``file`` if malformed."""
    if not isinstance(document, dict) or document.get("format_version") != POLICY_FORMAT_VERSION:
        raise InputError(
            f"unsupported policy format (expected format_version {POLICY_FORMAT_VERSION})",
            file=file, field="format_version",
        )
    try:
        values = {str(k): float(v) for k, v in document["values"].items()}
        illegal = {str(k): float(v) for k, v in document.get("illegal_action_values", {}).items()}
        parameters = _parameters(document["parameters"])
        demos = [str(name) for name in document["library_demos"]]
        episodes = int(document.get("training_episodes", 0))
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise InputError(f"malformed policy ({error})", file=file) from None
    if not all(np.isfinite(v) for v in [*values.values(), *illegal.values()]):
        raise InputError("non-finite value in the table", file=file, field="values")
    hashes = document.get("library_feature_sha256")
    if hashes is not None:
        if not isinstance(hashes, dict) or not all(
            isinstance(k, str) and isinstance(v, str) and re.fullmatch(r"[0-9a-f]{64}", v) for k, v in hashes.items()
        ):
            raise InputError("expected demonstration names mapped to sha256 hex digests",
                             file=file, field="library_feature_sha256")
        hashes = dict(hashes)
    return QPolicy(values, parameters, demos, episodes, illegal, library_feature_hashes=hashes)


def save_policy(policy: QPolicy, path: str | Path) -> None:
    """Writes ``policy`` to ``path`` atomically (temporary file, fsync, rename)."""
    # Strict JSON: the table's values are finite (load_policy refuses anything else).
    atomic_write_bytes(Path(path), (json.dumps(policy_document(policy), indent=1, allow_nan=False) + "\n").encode())


def load_policy(path: str | Path) -> QPolicy:
    """Reads a policy file; InputError when it is missing, not JSON, or malformed."""
    path = Path(path)
    try:
        document = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError("no such policy file", file=str(path)) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise InputError(f"not a JSON policy ({error})", file=str(path)) from None
    return policy_from_document(document, str(path))


def _names(names):
    return ", ".join(names)


def policy_library_mismatch(policy: QPolicy, features) -> tuple[list[str], list[str]]:
    """What in a library a policy was not trained on.

    Parameters
    ----------
    policy : QPolicy
    features : Mapping[str, Feature]
        The library's features, name -> feature (``io.library.library_features``).

    Returns
    -------
    unseen : list of str
        The library's demonstrations that are not in the policy's ``library_demos``.
    changed : list of str
        Those the policy was trained on whose feature hash differs from the one it
        recorded (empty for a policy file without hashes: only names are compared).
    """
    trained = set(policy.library_demos)
    unseen = [name for name in features if name not in trained]
    changed = []
    if policy.library_feature_hashes is not None:
        current = feature_hashes({name: features[name] for name in features if name in trained})
        changed = [name for name, digest in current.items()
                   if policy.library_feature_hashes.get(name) not in (None, digest)]
    return unseen, changed


def check_policy_library(policy: QPolicy, features, *, file=None, library=None, allow_mismatch=False):
    """Refuses a policy trained on another library (docs/cli.rst, plan ``--policy``).

    A policy's table was learned with the demonstrations it names; a library with a
    demonstration it never saw, or one whose feature changed (the same name recorded
    again, or with another tool frame), plans with values learned for something else.
    A library with fewer demonstrations than the policy saw is fine.

    Parameters
    ----------
    policy : QPolicy
    features : Mapping[str, Feature]
        The library's features.
    file : str or Path, optional
        The policy file, named in the message.
    library : str, optional
        How to name the library in the message (``Library.label``).
    allow_mismatch : bool
        Return the message (for a warning) instead of raising.

    Returns
    -------
    message : str or None
        None when the policy was trained on these demonstrations; with
        ``allow_mismatch``, the mismatch as one line.

    Raises
    ------
    InputError
        The mismatch, naming the demonstrations, unless ``allow_mismatch``.
    """
    unseen, changed = policy_library_mismatch(policy, features)
    if not unseen and not changed:
        return None
    parts = []
    if unseen:
        parts.append(f"demonstrations it was not trained on ({_names(unseen)})")
    if changed:
        parts.append(f"demonstrations whose features differ from the ones it was trained on ({_names(changed)})")
    name = f"library {library}" if library else "the library"
    trained = _names(policy.library_demos) or "none"
    problem = (f"the policy does not match the library: it was trained on {trained}, and {name} has "
               + " and ".join(parts))
    if allow_mismatch:
        return problem + "; planning with it anyway (--allow-policy-mismatch)"
    policy_text = "POLICY" if file is None else str(file)
    library_text = library or "LIB"
    raise InputError(
        problem + f"; retrain it for this library ({HINT}), or pass --allow-policy-mismatch to plan with it anyway",
        file=file,
        field="library_demos",
        hints=(Hint("train", ("--library", library_text, "--warm-start", policy_text, "--out", "NEW_POLICY")),),
    )
