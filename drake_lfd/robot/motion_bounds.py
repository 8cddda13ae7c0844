"""How far a robot geometry can move when the joints turn: bounds for pruning distance queries.

A revolute joint turning by ``dq`` moves every point at most ``r |dq|``, ``r`` the point's
distance from the joint axis; over all configurations of a serial chain that distance is
at most the sum of the joint-to-joint distances down the chain plus the distance to the
geometry and its bounding radius. A signed distance to a fixed box changes no more than
the geometry's points move, so a pair measured at ``d`` stays at least
``d - sum_k bound_k |dq_k|`` away. The shell monitor and the plan-time joint-space check
use this to skip the pairs that provably cannot come close.

Not for: the distance queries themselves (``scene.py``).
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.geometry import Box as BoxShape, Capsule, Cylinder, Ellipsoid, GeometryId, Sphere
from pydrake.multibody.plant import MultibodyPlant

__all__ = ["bounding_radius", "motion_bounds"]


def bounding_radius(shape) -> float:
    """Radius of a sphere about the shape's origin that contains it (inf for shapes
    without a closed form here, such as meshes)."""
    if isinstance(shape, Sphere):
        return shape.radius()
    if isinstance(shape, Cylinder):
        return math.hypot(shape.radius(), shape.length() / 2)
    if isinstance(shape, Capsule):
        return shape.radius() + shape.length() / 2
    if isinstance(shape, BoxShape):
        return 0.5 * math.sqrt(shape.width() ** 2 + shape.depth() ** 2 + shape.height() ** 2)
    if isinstance(shape, Ellipsoid):
        return max(shape.a(), shape.b(), shape.c())
    return math.inf


def motion_bounds(plant: MultibodyPlant, inspector, geometry_id: GeometryId) -> np.ndarray:
    """How far each position coordinate can move a robot geometry, shape (num_positions,).

    Entry ``k`` bounds, over all configurations, the distance of any point of the
    geometry from the axis of the revolute joint of coordinate ``k`` (0 for joints that
    do not move it): the distance from the joint's origin to the next moving joint's
    origin down the chain, and so on, plus the distance from the last one to the
    geometry's origin and its bounding radius. Those joint-to-joint distances are fixed
    on each body, so they are measured at the default configuration. A point then moves
    at most ``sum_k bound_k |dq_k|`` when the coordinates change by ``dq``. ``inf`` in
    every moving entry when the chain has a joint other than revolute or weld, or the
    shape has no bounding radius.
    """
    context = plant.CreateDefaultContext()
    radius = bounding_radius(inspector.GetShape(geometry_id))
    body = plant.GetBodyFromFrameId(inspector.GetFrameId(geometry_id))
    X_WG = body.EvalPoseInWorld(context).multiply(inspector.GetPoseInFrame(geometry_id))
    parent_joint = {}
    for joint_index in plant.GetJointIndices():
        joint = plant.get_joint(joint_index)
        parent_joint[joint.child_body().index()] = joint
    bounds = np.zeros(plant.num_positions())
    moving, reach, previous_origin = [], radius, X_WG.translation()
    unbounded = not math.isfinite(radius)
    world = plant.world_body().index()
    while body.index() != world and body.index() in parent_joint:
        joint = parent_joint[body.index()]
        if joint.num_positions() > 0:
            if joint.type_name() != "revolute":
                unbounded = True
            origin = joint.frame_on_child().CalcPoseInWorld(context).translation()
            reach += float(np.linalg.norm(previous_origin - origin))
            previous_origin = origin
            bounds[joint.position_start()] = reach
            moving.append(joint.position_start())
        body = joint.parent_body()
    if unbounded:
        bounds[moving] = math.inf
    return bounds
