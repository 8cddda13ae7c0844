"""A URScript program that runs an exported joint trajectory on a UR e-Series arm.

The program (docs/cli.rst, ``drake-lfd export``)::

    def drake_lfd_TASK():
      movej([q0], a=MOVEJ_A, v=MOVEJ_V)        # to the start, slowly
      servoj([q], a=0, v=0, t=0.002, lookahead_time=L, gain=G)   # one line per 2 ms
      ...
      stopj(STOPJ_A)
    end

``servoj`` blocks for ``t``, so consecutive lines stream the targets at the controller
rate (500 Hz). Its ``a`` and ``v`` are unused by the controller (URScript manual) and
written as 0. The parameters (:data:`MOVEJ_ACCELERATION_RAD_S2`, ...) are explained in
docs/cli.rst.

Not for: resampling or checking the trajectory (:mod:`drake_lfd.io.trajectory_export`).
"""

from __future__ import annotations

import re

from drake_lfd.core.errors import InputError

__all__ = [
    "MOVEJ_ACCELERATION_RAD_S2",
    "MOVEJ_SPEED_RAD_S",
    "STOPJ_DECELERATION_RAD_S2",
    "DEFAULT_LOOKAHEAD_TIME_S",
    "DEFAULT_GAIN",
    "LOOKAHEAD_RANGE_S",
    "GAIN_RANGE",
    "check_servoj_parameters",
    "urscript_program",
]

#: movej to the start: 0.5 rad/s^2 and 0.35 rad/s (20 deg/s), a third of URScript's
#: defaults (1.4, 1.05), so the unchecked move to the start is slow enough to stop by hand.
MOVEJ_ACCELERATION_RAD_S2 = 0.5
MOVEJ_SPEED_RAD_S = 0.35
#: stopj's deceleration at the end (the trajectory already ends at rest).
STOPJ_DECELERATION_RAD_S2 = 2.0
#: servoj lookahead_time (s): URScript's default 0.1; range 0.03-0.2. Longer smooths the
#: targets more (the plan's 10 ms knots) at the cost of lag; shorter tracks tighter.
DEFAULT_LOOKAHEAD_TIME_S = 0.1
#: servoj gain: URScript's default 300; range 100-2000. Higher is stiffer tracking and
#: jerkier motion, more likely to end in a protective stop.
DEFAULT_GAIN = 300.0
LOOKAHEAD_RANGE_S = (0.03, 0.2)
GAIN_RANGE = (100.0, 2000.0)


def check_servoj_parameters(lookahead_time_s: float, gain: float) -> None:
    """Refuses servoj parameters the controller does not accept (one line)."""
    low, high = LOOKAHEAD_RANGE_S
    if not (low <= lookahead_time_s <= high):
        raise InputError(f"{lookahead_time_s} s is outside servoj's range {low}-{high} s", field="--lookahead-time")
    low, high = GAIN_RANGE
    if not (low <= gain <= high):
        raise InputError(f"{gain} is outside servoj's range {low:g}-{high:g}", field="--gain")


def _vector(q) -> str:
    return "[" + ", ".join(f"{float(v):.9f}" for v in q) + "]"


def urscript_program(trajectory, *, lookahead_time_s: float = DEFAULT_LOOKAHEAD_TIME_S,
                     gain: float = DEFAULT_GAIN, period_s: float = 0.002) -> str:
    """The program for an :class:`~drake_lfd.io.trajectory_export.ExportTrajectory`.

    Joint values are written with 9 decimals (1e-9 rad: far below the arm's resolution)."""
    check_servoj_parameters(lookahead_time_s, gain)
    name = "drake_lfd_" + (re.sub(r"[^A-Za-z0-9_]", "_", trajectory.task) or "plan")
    servo = f"a=0, v=0, t={period_s:g}, lookahead_time={lookahead_time_s:g}, gain={gain:g}"
    lines = [
        f"def {name}():",
        f"  # drake-lfd export: {len(trajectory.t)} servoj targets every {period_s * 1e3:g} ms over "
        f"{trajectory.duration_s:.3f} s (plan time x {trajectory.slow_down:g}).",
        "  # Run it in URSim first, then on the arm with the speed slider reduced (docs/cli.rst).",
        f'  textmsg("drake-lfd: moving to the start of {name}")',
        f"  movej({_vector(trajectory.q[0])}, a={MOVEJ_ACCELERATION_RAD_S2:g}, v={MOVEJ_SPEED_RAD_S:g})",
        '  textmsg("drake-lfd: streaming the trajectory")',
    ]
    lines.extend(f"  servoj({_vector(q)}, {servo})" for q in trajectory.q)
    lines.append(f"  stopj({STOPJ_DECELERATION_RAD_S2:g})")
    lines.append('  textmsg("drake-lfd: done")')
    lines.append("end")
    return "\n".join(lines) + "\n"
