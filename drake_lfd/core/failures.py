"""Why a trial failed, as records: a kind from a closed set, the configuration concerned,
and the line a person reads.

A :class:`Failure` is its line (a ``str``: printed, joined, written to JSON as before)
that also carries ``kind`` (one of :data:`FAILURE_KINDS`), ``configuration`` (the 1-based
critical configuration concerned, when one is) and ``cause`` (for ``no_executable_plan``,
the blocking reason: ``reach``, ``joint_limit``, ``singularity``, ``collision`` or
``path_constraint``). Sweeps, summaries and exit codes group failures by ``kind`` (and
``label``), never by parsing the line, so rewording a line moves no figure.

Not for: deciding success (``diagrams/judging.py``), or what a plan-time refusal says
(``planning/executable.py``).
"""

from __future__ import annotations

__all__ = ["FAILURE_KINDS", "Failure", "failure_labels"]

# kind -> the label sweeps and figures group by.
FAILURE_KINDS = {
    "not_reached": "critical configuration not reached",
    "position_error": "critical configuration position error",
    "rotation_error": "critical configuration rotation error",
    "path_constraint": "path constraint",
    "penetration": "penetration",
    "joint_position_limit": "joint position limit",
    "joint_speed_limit": "joint speed limit",
    "singularity": "singularity",
    "separation": "separation",
    "no_executable_plan": "no executable plan",
    "demonstration_requested": "demonstration requested",
    "unreachable": "unreachable",
    "nothing_planned": "nothing planned",
}


class Failure(str):
    """One failed criterion: the line, with ``kind``, ``configuration`` and ``cause`` (see
    the module docstring). Equal to its line as a string."""

    kind: str
    configuration: int | None
    cause: str | None

    def __new__(cls, kind: str, detail: str, *, configuration: int | None = None, cause: str | None = None):
        if kind not in FAILURE_KINDS:
            raise ValueError(f"unknown failure kind {kind!r} (one of {', '.join(FAILURE_KINDS)})")
        failure = super().__new__(cls, detail)
        failure.kind, failure.configuration, failure.cause = kind, configuration, cause
        return failure

    @property
    def detail(self) -> str:
        return str.__str__(self)

    @property
    def label(self) -> str:
        """The kind's label, with the cause of a refusal: ``no executable plan (reach)``."""
        label = FAILURE_KINDS[self.kind]
        return f"{label} ({self.cause})" if self.cause else label

    def __reduce__(self):  # pickled to and from worker processes whole
        return _failure, (self.kind, self.detail, self.configuration, self.cause)

    def __repr__(self) -> str:
        return f"Failure({self.kind!r}, {self.detail!r})"


def _failure(kind, detail, configuration, cause):
    return Failure(kind, detail, configuration=configuration, cause=cause)


def failure_labels(failures) -> list[str]:
    """The labels of ``failures`` (records; a plain string, as an old record holds, is
    ``other``)."""
    return [failure.label if isinstance(failure, Failure) else "other" for failure in failures]
