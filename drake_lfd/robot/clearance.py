"""Clearance geometry of the tool: the points fixed in the end-effector frame to keep
clear (E, the flange, the wrist behind it) and their signed distances to keep-out boxes
and the floor along a path of poses.

What the planner scores twists by (``planning/planner.py``: the mapped path's shortfall
below a clearance goal) and what a test compares with Drake's own signed distances. Plain
numpy on dual quaternions, no plant.

Not for: the robot's collision geometry and Drake's distance queries (``scene.py``),
the joint-space check (``joint_path.py``), the boxes themselves (``core/tasks.py``).
"""

from __future__ import annotations

import numpy as np

from drake_lfd.core.dual_quaternion import translation_from_dual_quaternion
from drake_lfd.core.pose_conversions import matrices_from_dual_quaternion
from drake_lfd.core.tasks import Box
from drake_lfd.robot.analytic_ik import UR5E_DH_D

__all__ = [
    "WRIST_BEHIND_FLANGE_M",
    "LINK_RADIUS_M",
    "tool_clearance_points",
    "box_signed_distance",
    "clearances",
    "path_clearance",
]

# The flange and the wrist behind it (UR5e: wrist_2's axis is d6 of the DH table behind
# the flange along tool0's -z), plus the room the links take (wrist housing radius 0.045 m).
WRIST_BEHIND_FLANGE_M = UR5E_DH_D[5]
LINK_RADIUS_M = 0.05


def tool_clearance_points(X_tool0_E) -> np.ndarray:
    """Points fixed in E to keep clear: E itself, the flange, the wrist behind it,
    shape (3, 3), expressed in E."""
    X_E_tool0 = X_tool0_E.inverse()
    return np.array([
        [0.0, 0.0, 0.0],
        X_E_tool0.translation(),
        X_E_tool0.multiply(np.array([0.0, 0.0, -WRIST_BEHIND_FLANGE_M])),
    ])


def box_signed_distance(points: np.ndarray, centre: np.ndarray, size: np.ndarray,
                        rotation: np.ndarray | None = None) -> np.ndarray:
    """Signed distance of points (n, 3) to a box (negative inside), (n,): its centre,
    full edges and axes in W (``rotation`` (3, 3), default axis-aligned); the same as
    :meth:`drake_lfd.core.tasks.Box.signed_distance`."""
    box = Box(name="", centre=centre, size=size, rotation=np.eye(3) if rotation is None else rotation)
    return box.signed_distance(points)


def clearances(poses: np.ndarray, keep_out=(), floor_z=None,
               points_E: np.ndarray | None = None) -> np.ndarray:
    """Distance of every tracked point along the path to the nearest keep-out box
    (:meth:`Box.signed_distance <drake_lfd.core.tasks.Box.signed_distance>`, boxes
    of any orientation) or the floor, shape (n * k,): of the origins of ``poses``
    (n, 8), or of ``points_E`` (k, 3), points fixed in E such as the flange and the
    wrist behind it. The floor is a level table top's height, or a tilted table (a
    Box: the plane of its top face, :meth:`~drake_lfd.core.tasks.Box.height_above_top`);
    ``Workcell.planner_floor`` gives either."""
    if points_E is None:
        p = translation_from_dual_quaternion(poses)
    else:
        T = matrices_from_dual_quaternion(poses)
        p = (np.einsum("nij,kj->nki", T[:, :3, :3], np.asarray(points_E)) + T[:, None, :3, 3]).reshape(-1, 3)
    distance = np.full(len(p), np.inf)
    for box in keep_out:
        distance = np.minimum(distance, box.signed_distance(p))
    if isinstance(floor_z, Box):
        distance = np.minimum(distance, floor_z.height_above_top(p))
    elif floor_z is not None:
        distance = np.minimum(distance, p[:, 2] - floor_z)
    return distance


def path_clearance(poses: np.ndarray, keep_out=(), floor_z: float | None = None,
                   points_E: np.ndarray | None = None) -> float:
    """Least distance of the tool path to the keep-out boxes and the floor (inf with
    neither); see :func:`clearances`."""
    return float(np.min(clearances(poses, keep_out, floor_z, points_E), initial=np.inf))
