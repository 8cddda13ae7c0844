"""The JSON form of a plan or demonstration request (``plan --json``, documented in docs/cli.rst).

Not for: computing plans (``planning.py``).
"""

from __future__ import annotations

from drake_lfd.core.dual_quaternion import translation_rotation_from_dual_quaternion
from drake_lfd.planning.planner import PlanResult
from drake_lfd.io.pose_records import pose_json_from_rigid_transform

__all__ = [
    'critical_configurations_json',
    'composition_json',
    'uncovered_json',
    'joint_trajectory_json',
    'infeasible_json',
    'plan_json',
    'describe_infeasible',
    'describe_uncovered',
]


def _floats(values) -> list[float]:
    return [float(v) for v in values]


def critical_configurations_json(result: PlanResult) -> list[dict]:
    return [
        {"con": i + 1, "p": _floats(con.p), "euler_zyx": _floats(result.euler_zyx[i])}
        for i, con in enumerate(result.task.critical_configurations)
    ]


def composition_json(result: PlanResult) -> list[dict]:
    return [
        {"demo": s.demo, "from": s.con_from, "to": s.con_to, "cost": float(s.cost),
         "max_correction": {"position_m": float(s.max_correction_position_m),
                            "rotation_rad": float(s.max_correction_rotation_rad)}}
        for s in result.composition
    ]


def uncovered_json(result: PlanResult, script_paths=None) -> list[dict]:
    """The segments to demonstrate, each with ``guidance_script``: a guidance script
    (YAML text) for ``drake-lfd record`` showing the motion, ready to edit; written for
    the path ``script_paths[i]`` of segment i when given (``plan --request-script``)."""
    from drake_lfd.io.guidance_scripts import request_guidance_yaml

    paths = list(script_paths) if script_paths is not None else [None] * len(result.uncovered)

    return [
        {
            "from": u.con_from,
            "to": u.con_to,
            "axis": _floats(u.axis),
            "angle_rad": float(u.angle_rad),
            "translation_m": _floats(u.translation_m),
            **({"guidance_script": request_guidance_yaml(result.task, u, path=path)}
               if u.pose_from is not None else {}),
        }
        for u, path in zip(result.uncovered, paths)
    ]


def plan_json(result: PlanResult, cost: str = "paper", script_paths=None) -> dict:
    """The ``plan --json`` document; ``cost`` is the action cost it was planned with
    (``plan_task``'s ``cost``, the ``"cost"`` field). Extra optional fields: ``q_planner``
    (Q runs only) and ``refinement`` (``plan --refine`` only: the trajectory
    optimization's report, ``planning/refinement.py``). ``script_paths``: where
    ``--request-script`` writes each uncovered segment's guidance script (its comment
    names that file)."""
    poses = []
    critical_indices = []
    if result.timed is not None:
        p, q = translation_rotation_from_dual_quaternion(result.timed.poses)
        poses = [
            {"t": float(t), "p": _floats(pi), "q_wxyz": _floats(qi if qi[0] >= 0 else -qi)}
            for t, pi, qi in zip(result.timed.times, p, q)
        ]
        critical_indices = [int(i) for i in result.timed.critical_indices]
    document = {
        "status": result.status,
        "task": result.task.name,
        "X_WB": pose_json_from_rigid_transform(result.task.X_WB),
        "X_tool0_E": pose_json_from_rigid_transform(result.task.X_tool0_E),
        "planner": result.planner,
        "cost": cost,
        "critical_configurations": critical_configurations_json(result),
        "composition": composition_json(result),
        "total_cost": float(result.total_cost) if result.planned else None,
        "poses": poses,
        "critical_indices": critical_indices,
        "max_correction": {
            "position_m": float(result.max_correction_position_m),
            "rotation_rad": float(result.max_correction_rotation_rad),
        },
        "joint_trajectory": joint_trajectory_json(result),
        "timing": result.timing if result.planned else None,
        "infeasible": infeasible_json(result),
        "uncovered": uncovered_json(result, script_paths),
    }
    if result.planner == "q":
        document["q_planner"] = {
            "greedy_completed": result.greedy_completed,
            "fallback": result.fallback,
            "refine_episodes": result.refine_episodes,
        }
    if result.refinement is not None:
        document["refinement"] = result.refinement.to_json(wall_times=False)
    return document


def joint_trajectory_json(result: PlanResult) -> dict:
    """``{"t": [...], "q": [[q1..q6], ...]}``: the joint path the plan-time check
    produced, with the plan's executed timing, at the controller's period from plan time
    0: the motion ``simulate`` commands; empty lists without one."""
    path = result.joint_path if result.planned else None
    if path is None:
        return {"t": [], "q": []}
    return {"t": [float(t) for t in path.t], "q": [_floats(q) for q in path.q]}


def infeasible_json(result: PlanResult) -> list[dict]:
    """The segments found blocked for the robot: for ``no_executable_plan`` every
    composition's; for a plan, those the search set aside on the way."""
    return [{"from": s.con_from, "to": s.con_to, "reason": s.reason, "detail": s.detail, "demo": s.demo,
             "blocked_alternatives": int(s.blocked_alternatives)}
            for s in result.infeasible]


def describe_infeasible(result: PlanResult) -> list[str]:
    """One line per blocking segment (``con_2 -> con_4 (stacking): singularity: ...``)."""
    return [segment.describe() for segment in result.infeasible]


def describe_uncovered(result: PlanResult) -> list[str]:
    """One human line per uncovered segment: what the new demonstration must show."""
    import numpy as np

    lines = []
    for u in result.uncovered:
        lines.append(
            f"con_{u.con_from} -> con_{u.con_to}: rotate {np.degrees(u.angle_rad):.0f} deg about "
            f"body axis [{', '.join(f'{a:.2f}' for a in u.axis)}] while translating "
            f"[{', '.join(f'{t:.3f}' for t in u.translation_m)}] m (in con_{u.con_from}'s frame)"
        )
    return lines
