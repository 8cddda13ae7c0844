"""What the joint-path check keeps to and reports: its margins, a path's first violation, the path.

:class:`JointPathLimits` holds the check's margins (``joint_path.py``'s module docstring
says what each guards against), :class:`Blocker` why a joint path is not executable
(one of :data:`REASONS`, with a line for a person), :class:`JointPath` the joint path a
plan promises. :func:`describe_clearance_shortfall` and
:func:`describe_shoulder_shortfall` word a shortfall the one way both the check and the
refusals' pre-check (``planning/refusals.py``) state it.

Not for: following a plan (``joint_path.py``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = [
    "REASONS",
    "JointPathLimits",
    "Blocker",
    "JointPath",
    "millimetres_below",
    "describe_clearance_shortfall",
    "describe_shoulder_shortfall",
    "singularity_shortfall",
]

REASONS = ("reach", "joint_limit", "singularity", "collision", "path_constraint")


@dataclasses.dataclass(frozen=True)
class JointPathLimits:
    """What a joint path must keep to (all configurable; the defaults are documented in
    ``joint_path.py``'s module docstring).

    Attributes
    ----------
    elbow_margin, wrist_margin : float
        Least ``|sin q3|`` and ``|sin q5|`` (0.06, about 3.4 deg from straight/aligned:
        a closed-loop run is judged against 0.05, and the servos' lag moves the joints
        by far less than the difference).
    shoulder_margin_m : float
        Least distance of the wrist point from the shoulder axis, m (0.05).
    clearance_m : float
        Least signed distance of any robot or tool geometry to any box, m (0.01).
    position_tolerance_m, rotation_tolerance_rad : float
        At each critical configuration when due (the closed loop's success tolerances).
    path_position_tolerance_m, path_rotation_tolerance_rad : float
        Anywhere along the path (5 cm, 15 deg: a motion slowed by a speed limit may lag
        and catch up by the next critical configuration; the clearance is checked on
        the lagging path itself).
    settle_steps : int
        Controller steps followed after the plan's end (the closed loop keeps tracking).
    """

    elbow_margin: float = 0.06
    wrist_margin: float = 0.06
    shoulder_margin_m: float = 0.05
    clearance_m: float = 0.01
    position_tolerance_m: float = 0.005
    rotation_tolerance_rad: float = math.radians(2.0)
    path_position_tolerance_m: float = 0.05
    path_rotation_tolerance_rad: float = math.radians(15.0)
    settle_steps: int = 10


@dataclasses.dataclass(frozen=True)
class Blocker:
    """Why a joint path is not executable.

    Attributes
    ----------
    reason : str
        One of :data:`REASONS`.
    detail : str
        One line for a person (``forearm_link/forearm enters safety shell 'shell' by
        4.2 mm``).
    time_s : float
        Plan time of the violation.
    span : int
        0-based index of the span (between consecutive critical configurations) it is in.
    con : int or None
        1-based critical configuration concerned (``reach`` at a critical configuration).
    pair : tuple of (GeometryId, GeometryId) or None
        For a ``collision``: the robot geometry and the box (or table) too close.
    """

    reason: str
    detail: str
    time_s: float
    span: int
    con: int | None = None
    pair: tuple | None = None


@dataclasses.dataclass(frozen=True)
class JointPath:
    """The joint path of a plan, as the controller would command it.

    Attributes
    ----------
    t : array (m,)
        Plan times of the samples (the controller's period), s.
    q : array (m, 6)
        Commanded joint positions.
    blocker : Blocker or None
        The first violation (the path then ends there); None when executable.
    critical_errors : tuple of (position_m, rotation_rad)
        At each critical configuration reached before the blocker.
    min_clearance_m : float
        Least clearance measured along the path (inf without boxes).
    min_elbow, min_wrist, min_shoulder_m : float
        Least ``|sin q3|``, ``|sin q5|`` and shoulder distance along the path.
    start_index : int
        Which start configuration candidate it followed from.
    clearances : array (m,)
        The least distance measured at each sample (inf where every pair was proven
        beyond the clearance).
    """

    t: np.ndarray
    q: np.ndarray
    blocker: Blocker | None
    critical_errors: tuple[tuple[float, float], ...]
    min_clearance_m: float
    min_elbow: float
    min_wrist: float
    min_shoulder_m: float
    start_index: int = 0
    clearances: np.ndarray | None = None

    @property
    def executable(self) -> bool:
        return self.blocker is None


def millimetres_below(value_m: float, limit_m: float) -> str:
    """``value_m`` in millimetres with the fewest decimals (1 to 4) that show it below
    ``limit_m`` (9.96 mm under a 10 mm clearance reads ``9.96``, not ``10.0``)."""
    for digits in (1, 2, 3, 4):
        text = f"{1000 * value_m:.{digits}f}"
        if float(text) < 1000 * limit_m:
            return text
    return f"{1000 * value_m:.4f}"


def describe_clearance_shortfall(what: str, distance_m: float, clearance_m: float) -> str:
    """``enters WHAT by D mm`` or ``passes D mm from WHAT (clearance C mm)``, with digits
    enough to show the shortfall."""
    if distance_m < 0:
        return f"enters {what} by {-1000 * distance_m:.1f} mm"
    return f"passes {millimetres_below(distance_m, clearance_m)} mm from {what} (clearance {1000 * clearance_m:g} mm)"


def describe_shoulder_shortfall(distance_m: float, margin_m: float) -> str:
    """The wrist centre's distance from the shoulder axis, below its margin."""
    return (f"wrist centre {millimetres_below(distance_m, margin_m)} mm from the shoulder axis "
            f"(< {1000 * margin_m:g} mm)")


def singularity_shortfall(elbow: float, wrist: float, shoulder_m: float,
                          limits: JointPathLimits) -> tuple[str, str] | None:
    """The first singularity margin of ``limits`` a configuration breaks, in the check's
    order, as ``(kind, detail)`` (kind ``elbow``, ``wrist`` or ``shoulder``, the detail in
    the check's words); None when it keeps them. ``elbow`` is ``|sin q3|``, ``wrist``
    ``|sin q5|``, ``shoulder_m`` the wrist centre's distance from the shoulder axis."""
    if elbow < limits.elbow_margin:
        return "elbow", f"elbow straight (|sin q3| = {elbow:.3f} < {limits.elbow_margin:g})"
    if wrist < limits.wrist_margin:
        return "wrist", f"wrist aligned (|sin q5| = {wrist:.3f} < {limits.wrist_margin:g})"
    if shoulder_m < limits.shoulder_margin_m:
        return "shoulder", describe_shoulder_shortfall(shoulder_m, limits.shoulder_margin_m)
    return None
