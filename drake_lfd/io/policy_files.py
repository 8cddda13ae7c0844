"""Q-policy files: a trained ``QPolicy`` as JSON (format_version 1), saved atomically.

The document (see docs/cli.rst for the commands that read and write it)::

    {"format_version": 1, "kind": "drake-lfd afterstate Q-table",
     "parameters": {...QLearningParameters...}, "library_demos": [...],
     "training_episodes": N, "values": {key: W}, "illegal_action_values": {key: Q}}

Files written before ``QLearningParameters.epsilon`` was renamed
``greedy_probability`` (same meaning: the probability of the greedy action) are read
as if they had the new name.

Not for: learning or planning (``planning/q_learning.py``); other JSON documents
(``plan_json.py``).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from drake_lfd.core.errors import InputError
from drake_lfd.io.atomic_files import atomic_write_bytes
from drake_lfd.planning.q_learning import QLearningParameters, QPolicy

__all__ = [
    "POLICY_FORMAT_VERSION",
    "POLICY_KIND",
    "policy_document",
    "policy_from_document",
    "save_policy",
    "load_policy",
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
    return QPolicy(values, parameters, demos, episodes, illegal)


def save_policy(policy: QPolicy, path: str | Path) -> None:
    """Writes ``policy`` to ``path`` atomically (temporary file, fsync, rename)."""
    atomic_write_bytes(Path(path), (json.dumps(policy_document(policy), indent=1) + "\n").encode())


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
