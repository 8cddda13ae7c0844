"""Robot shapes whose place depends on shoulder_pan alone, and the one way they are measured.

The base, the shoulder link and the upper arm's shoulder_lift housing (a cylinder about
the shoulder_lift axis) occupy the same points of space whatever the joints after
shoulder_pan do: turning shoulder_lift maps the housing onto itself. Their clearance to
a fixed box is therefore a function of shoulder_pan alone, which the refusals use to
rule out a whole sweep of shoulder_pan at once (``planning/refusals.py``).

Mathematically, that is. Drake's distance between a cylinder and a box comes from an
iterative (GJK) query whose answer depends on how the cylinder is posed: two
configurations placing the housing identically (shoulder_lift turned) give distances
some 1e-5 m, at times 2e-4 m, apart. A pan sweep measured at one configuration and a
joint path's check at another could then decide a clearance within that of the margin
differently. So every clearance of these shapes is measured at
:func:`pan_only_configuration` (the configuration's shoulder_pan, every other joint at
zero): the scene's signed distances (:class:`~drake_lfd.robot.scene.KinematicScene`),
the joint-path check (:class:`~drake_lfd.robot.joint_path.JointPathChecker`) and the
refusals' pan sweep give the same number for the same pan, to the bit.

Not for: the sweep itself (``planning/refusals.py``), measuring other shapes
(``scene.py``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydrake.geometry import Capsule, Cylinder, Sphere

from drake_lfd.robot.kinematics import UR5E_JOINT_NAMES

__all__ = ["pan_only_geometry_ids", "pan_only_configuration"]

# How far a shape's axis may be from the shoulder_lift axis (m, rad) for the shape to
# count as turning onto itself (the model's numbers are exact; this absorbs rounding).
_ON_AXIS_TOLERANCE = 1e-12


def pan_only_geometry_ids(plant, model, inspector, robot_geometry_ids: Sequence) -> tuple:
    """The ids among ``robot_geometry_ids`` whose distances to a fixed box depend on
    shoulder_pan alone, read from the model: shapes no joint moves or only shoulder_pan
    moves, and shapes on the shoulder_lift joint's child body that turning it maps onto
    themselves (a sphere centred on its axis; a cylinder or capsule whose axis is
    its axis)."""
    lift = plant.GetJointByName(UR5E_JOINT_NAMES[1], model)
    moved_by_lift = set(plant.GetBodiesKinematicallyAffectedBy([lift.index()]))
    X_CJ = lift.frame_on_child().GetFixedPoseInBodyFrame()  # the joint frame in the child's
    axis = X_CJ.rotation().multiply(np.asarray(lift.revolute_axis(), dtype=float))
    axis /= np.linalg.norm(axis)
    origin = X_CJ.translation()
    found = []
    for geometry_id in robot_geometry_ids:
        body = plant.GetBodyFromFrameId(inspector.GetFrameId(geometry_id))
        if body.index() not in moved_by_lift:  # fixed, or turned by shoulder_pan alone
            found.append(geometry_id)
            continue
        if body.index() != lift.child_body().index():
            continue
        shape, X_CG = inspector.GetShape(geometry_id), inspector.GetPoseInFrame(geometry_id)
        offset = X_CG.translation() - origin
        on_axis = float(np.linalg.norm(offset - axis * float(offset @ axis))) < _ON_AXIS_TOLERANCE
        along_axis = abs(abs(float(X_CG.rotation().matrix()[:, 2] @ axis)) - 1.0) < _ON_AXIS_TOLERANCE
        if on_axis and (isinstance(shape, Sphere) or (isinstance(shape, (Cylinder, Capsule)) and along_axis)):
            found.append(geometry_id)
    return tuple(found)


def pan_only_configuration(q) -> np.ndarray:
    """The configuration the pan-only shapes are measured at: ``q``'s shoulder_pan, every
    other joint at zero (module docstring)."""
    canonical = np.zeros(len(q))
    canonical[0] = q[0]
    return canonical
