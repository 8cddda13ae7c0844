"""A standalone Meshcat HTML animation of the UR5e moving through joint configurations.

Used by ``drake-lfd show-model`` to let a person check the model by eye (and by the
tests, through a headless-browser screenshot). It poses a kinematic plant; it does not
simulate dynamics (the closed-loop modules do that).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams, Role
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder

from drake_lfd.io.atomic_files import atomic_write_bytes
from drake_lfd.robot.kinematics import add_ur5e
from drake_lfd.diagrams.recording_meshcat import recording_meshcat

__all__ = ['SHOWCASE_CONFIGURATIONS', 'write_configurations_html']

# Configurations a UR5e user recognises: zero (stretched along -x), the "home" pose UR
# ships (upright), and an elbow-up working pose above the table.
SHOWCASE_CONFIGURATIONS = np.array(
    [
        [0.0, -np.pi / 2, 0.0, -np.pi / 2, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, -1.2, 1.6, -1.97, -np.pi / 2, 0.0],
        [np.pi / 2, -1.0, 1.2, -1.77, -np.pi / 2, 0.6],
    ]
)


def write_configurations_html(
    path: str | Path,
    q_keyframes: np.ndarray = SHOWCASE_CONFIGURATIONS,
    *,
    seconds_per_move: float = 1.5,
    X_WB: RigidTransform | None = None,
    meshcat: Meshcat | None = None,
) -> Path:
    """Writes a self-contained HTML animation moving the UR5e through ``q_keyframes``.

    Parameters
    ----------
    path : output ``.html`` file.
    q_keyframes : array, shape (k, 6), joint angles in radians, UR joint order.
    seconds_per_move : duration of each linear joint-space move between keyframes.

    Returns the path written.
    """
    q_keyframes = np.atleast_2d(np.asarray(q_keyframes, dtype=float))
    if q_keyframes.shape[1] != 6:
        raise ValueError(f"q_keyframes must have shape (k, 6), got {q_keyframes.shape}")
    meshcat = meshcat or recording_meshcat()  # a standalone file: no viewer waits
    meshcat.SetCameraPose(camera_in_world=[1.3, -1.5, 1.0], target_in_world=[0.0, 0.0, 0.35])
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
    model = add_ur5e(plant, X_WB=X_WB)
    plant.Finalize()
    params = MeshcatVisualizerParams(role=Role.kIllustration, publish_period=1 / 30)
    visualizer = MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant_context = plant.GetMyMutableContextFromRoot(context)

    visualizer.StartRecording(set_transforms_while_recording=False)
    frame_period = params.publish_period
    segments = max(len(q_keyframes) - 1, 1)
    times = np.arange(0.0, segments * seconds_per_move + 1e-9, frame_period)
    keyframe_times = np.linspace(0.0, segments * seconds_per_move, len(q_keyframes))
    for t in times:
        q = np.array([np.interp(t, keyframe_times, q_keyframes[:, j]) for j in range(6)])
        context.SetTime(t)
        plant.SetPositions(plant_context, model, q)
        diagram.ForcedPublish(context)
    visualizer.StopRecording()
    visualizer.PublishRecording()
    path = Path(path)
    atomic_write_bytes(path, meshcat.StaticHtml().encode())
    return path
