"""The refinement's settings (:class:`RefinementOptions`): the tube's default width and
samples, the program's tolerances and samples, the checks' slack, SNOPT's budget, the
starts and the choice among them; docs/method.rst, Refinement by trajectory
optimization, justifies the defaults.

Not for: the task file's own bounds on the refinement (``refinement_bounds.py``) or
running it (``refinement.py``).
"""

from __future__ import annotations

import dataclasses
import math

from drake_lfd.core.tasks import DEFAULT_REFINEMENT_POSITION_M, DEFAULT_REFINEMENT_ROTATION_RAD
from drake_lfd.robot.optimization_records import SolverBudget, TrajectoryLimits

__all__ = ["RefinementOptions"]


@dataclasses.dataclass(frozen=True)
class RefinementOptions:
    """The refinement's settings (docs/method.rst, Refinement by trajectory
    optimization, justifies the defaults).

    Attributes
    ----------
    tube_position_m, tube_rotation_rad : float
        The tube: E within this distance and angle of the composed path at the matching
        path fraction (0.15 m, 30 deg), checked on the followed joint path, where the
        task file does not bound it (its ``refinement:`` block and path constraints,
        :func:`~drake_lfd.planning.refinement_bounds.allowed_deviations`).
    tube_margin : float
        The program bounds the tube at this fraction of it (0.8): its samples leave
        room for the path between them and for the controller.
    tube_samples : int
        The tube is constrained at this many path fractions evenly spread in ``s`` and
        as many evenly spread along the composed path's arc length (15 + 15). Evenly in
        ``s`` alone (20), 7 of 20 filling-and-pouring plans strayed 151-173 mm from the
        composed path between samples where a span is passed quickly for its length;
        over 36 paper-task plans (3 tasks, 6 seeds, both costs) 20 in ``s`` refined 27,
        20 or 30 along the arc 20 and 26, 15 + 15 refined 30.
    con_position_tolerance_m, con_rotation_tolerance_rad : float
        Each critical configuration, in the program: position within this along each
        axis (0.7 mm; at most 1.2 mm away), rotation within this (0.3 deg).
    target_check_slack : float
        The motion itself (before it is followed) must meet each critical configuration
        within this multiple of the program's tolerances (1.5: 1.8 mm, 0.45 deg): SNOPT
        meets its constraints only to its feasibility tolerance, and its iterate at an
        iteration limit not at all.
    check_fraction : float
        The followed joint path must meet each critical configuration within this
        fraction of the success tolerances (0.5: 2.5 mm, 1 deg), the rest being the
        closed loop's: its servos lag the command, and the motion passes the
        intermediate critical configurations at speed.
    pass_speed_m_s : float, optional
        E passes each intermediate critical configuration at most this fast (0.4 m/s;
        the motion is slowed along its path around it). The closed loop's servos lag
        the command by about 5 ms, so at 0.6 m/s E is 3 mm behind when the
        configuration is due; at 0.4 m/s, 2 mm. None: as optimized.
    pass_acceleration_m_s2 : float, optional
        And with at most this acceleration (1.5 m/s^2): accelerating through one at
        5 m/s^2 and 0.4 m/s, a trial missed it by 4.6 mm; the lag grows with both.
        None: not limited.
    program_pass_speed_m_s : float, optional
        The program's own bound on E's speed at each inner critical configuration,
        along each world axis (0.4 m/s: the optimizer plans a slow passage, and the
        retiming above brings the magnitude, up to sqrt(3) times that, within
        ``pass_speed_m_s``; 0.4 / sqrt(3) per axis, which keeps the magnitude within
        it in the program already, makes the refined motions markedly slower). None, or
        ``pass_speed_m_s`` None: no such bound.
    path_constraint_margin_rad : float
        The program holds each path constraint to what the check allows
        (:func:`~drake_lfd.robot.path_constraints.allowed_deviation`, the measure the
        search uses: its tolerance less the closed loop's tracking margin) less this
        (1.5 deg), but at least half of that: the constraint holds only at the program's
        samples, and the motion between them must keep it too.
    path_constraint_samples : int
        Path fractions each path constraint is constrained at, per span it covers (9;
        with 6, 2 of 10 transferring plans tilted 9.0-9.4 deg between samples); also the
        tube's extra samples in each span the task bounds more tightly than the whole.
    num_control_points : int, optional
        B-spline control points (cubic; None: 6 plus 3 per span, so that after the ends'
        zero velocity and acceleration each span keeps about 3 free ones; when SNOPT
        finds that program infeasible or its motion fails a check, once more with 1.5
        times as many).
    clearance_samples : int
        Path fractions the clearance is constrained at (15).
    budget : SolverBudget
        SNOPT's work per attempt, in iterations (never seconds: the same plan on any
        machine under any load). When SNOPT stops at an iteration limit, its last
        iterate is sampled and checked like a solution, and refines the plan when it
        passes every check.
    limits : TrajectoryLimits, optional
        The program's bounds (None: the task's ``timing:`` block at its
        ``limit_fraction``, :meth:`TrajectoryLimits.of_timing`, so the refined motion
        uses the same share of the limits as the composed plan's timing, with
        ``clearance_m``).
    clearance_m : float
        The program's clearance when ``limits`` is None (3 cm; the check demands 1 cm on
        the followed path, which lags the motion where it is fast and passes between the
        program's samples, so the program keeps more).
    repair_clearance_m : float
        A tube program's motion that fails the check for a collision is solved once more
        from itself with this much more clearance (2 cm; 0: never): otherwise whether a
        start passes a shell a hair inside or outside the clearance decides, with the
        plan's last bits, which start the plan takes.
    starts, fallback_starts : tuple of str
        The tube program's starts, in order, and those tried only when none of them gives
        a motion that passes (``refinement_starts.start_guesses``).
    energy_weight : float
        Weight of the path-energy cost beside the duration's in the tube program and
        the plain program that starts it (1e-3, in seconds per rad^2 of the control
        points' steps: a tie-breaker, not a trade). Without it the minimum-time program
        leaves the shape free where the duration does not bind it, so starts reached
        equal durations along shapes the slow passage of the critical configurations
        retimes differently.
    equal_duration : float
        Program durations within this fraction of the shortest are equal for the choice
        among starts (``refinement_starts.best_start``; 0.005).
    """

    tube_position_m: float = DEFAULT_REFINEMENT_POSITION_M
    tube_rotation_rad: float = DEFAULT_REFINEMENT_ROTATION_RAD
    tube_margin: float = 0.8
    tube_samples: int = 15
    con_position_tolerance_m: float = 0.0007
    con_rotation_tolerance_rad: float = math.radians(0.3)
    check_fraction: float = 0.5
    target_check_slack: float = 1.5
    pass_speed_m_s: float | None = 0.4
    pass_acceleration_m_s2: float | None = 1.5
    program_pass_speed_m_s: float | None = 0.4
    path_constraint_margin_rad: float = math.radians(1.5)
    path_constraint_samples: int = 9
    num_control_points: int | None = None
    clearance_samples: int = 15
    budget: SolverBudget = SolverBudget()
    limits: TrajectoryLimits | None = None
    clearance_m: float = 0.03
    repair_clearance_m: float = 0.02
    starts: tuple = ("plain motion", "lines")
    fallback_starts: tuple = ("composed",)
    energy_weight: float = 1e-3
    equal_duration: float = 0.005
