"""Shapes placed by shoulder_pan alone (robot/pan_only.py): which they are, and that the
scene, the joint-path check and the refusals' pan sweep measure them alike, to the bit."""

from __future__ import annotations

import numpy as np
import pytest

from drake_lfd.core.pose_conversions import dual_quaternion_from_matrices
from drake_lfd.core.tasks import draw_trial
from drake_lfd.core.timing import time_plan
from drake_lfd.diagrams.pipeline import joint_path_checker
from drake_lfd.experiments.pick_and_place import pick_and_place_yaml
from drake_lfd.io.task_files import task_from_spec, task_spec_from_text
from drake_lfd.planning import refusals
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.pan_only import pan_only_configuration
from drake_lfd.robot.scene import KinematicScene
from drake_lfd.robot.workcell import Workcell


def _names(scene, rows):
    return {scene.geometry.names[scene.geometry.robot_geometry_ids[r]] for r in rows}


def test_the_base_the_shoulder_and_the_shoulder_lift_housing_are_placed_by_the_pan_alone():
    """Read from the model: the base (fixed), the shoulder link's housing (turned by the
    pan alone) and the upper arm's housing, a cylinder about the shoulder_lift axis; not
    the upper arm's tube (off the axis) nor anything after the elbow, nor the tool."""
    scene = KinematicScene()
    assert _names(scene, scene.pan_only_rows) == {
        "base_link/base", "shoulder_link/shoulder_housing", "upper_arm_link/shoulder_lift_housing"}


@pytest.fixture(scope="module")
def near_base():
    """The checker of a random pick-and-place work cell with a safety shell beside the
    robot's base (bench_refusals' near-base task 1085, whose shoulder_lift housing passes
    9.3 mm from it)."""
    task = task_from_spec(task_spec_from_text(pick_and_place_yaml(1085, shell_near_base=True)), file="near_base")
    trial = draw_trial(task, 0)
    return joint_path_checker(Workcell.of(trial), task.simulation)


def test_the_scene_measures_them_the_same_whatever_the_other_joints(near_base):
    """Drake's cylinder-box distance depends on how the cylinder is posed (to some 1e-4
    m); the scene measures the pan-only shapes at the pan's configuration, so the same
    pan gives the same numbers to the bit, and every other shape is measured where it
    is."""
    scene = near_base.scene
    rows = scene.pan_only_rows
    others = np.setdiff1d(np.arange(len(scene.geometry.robot_geometry_ids)), rows)
    rng = np.random.default_rng(0)
    for pan in np.linspace(0.0, 2 * np.pi, 7):
        at_pan = scene.signed_distances(pan_only_configuration(np.array([pan, 0, 0, 0, 0, 0.0])))
        for _ in range(8):
            q = rng.uniform(-np.pi, np.pi, 6)
            q[0] = pan
            distances = scene.signed_distances(q)
            assert np.array_equal(distances[rows], at_pan[rows])
            assert not np.array_equal(distances[others], at_pan[others])


def test_the_follow_and_the_pan_sweep_measure_the_housing_as_the_scene_does(near_base):
    """A start where the shoulder_lift housing is the shape nearest a box, within the
    clearance: the follow is blocked at once naming it, with the least clearance the
    scene measures there, and the refusals' pan sweep has the same value at that pan."""
    checker, scene = near_base, near_base.scene
    housing = [r for r in scene.pan_only_rows
               if scene.geometry.names[scene.geometry.robot_geometry_ids[r]].endswith("shoulder_lift_housing")][0]
    sweep = refusals._pan_sweeps(checker)
    pans = sweep.pans[sweep.least < checker.limits.clearance_m]
    assert len(pans), "the shell comes within the clearance of the pan-only shapes"
    rng = np.random.default_rng(1)
    kinematics = UR5eKinematics(X_WB=scene.workcell.X_WB, X_tool0_E=scene.workcell.X_tool0_E)
    found = None
    for _ in range(400):
        q = rng.uniform(-np.pi, np.pi, 6)
        q[0] = float(rng.choice(pans))
        distances = scene.signed_distances(q)
        row, _box = np.unravel_index(np.argmin(distances), distances.shape)
        if row == housing and 0.0 < distances.min() < checker.limits.clearance_m and q[1] != 0.0:
            found = q
            break
    assert found is not None
    X_WE = kinematics.X_WE(found)
    plan = time_plan(dual_quaternion_from_matrices(np.array([X_WE.GetAsMatrix4()] * 2)), [0, 1])
    path = checker.follow(plan, found)
    assert path.blocker is not None and path.blocker.time_s == 0.0
    assert "shoulder_lift_housing" in path.blocker.detail
    assert path.min_clearance_m == scene.signed_distances(found).min()
    assert sweep.f(float(found[0])) == scene.signed_distances(found)[scene.pan_only_rows].min()
