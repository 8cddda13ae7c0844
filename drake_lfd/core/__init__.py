"""Layer 1, the core: the paper's maths and data types, pure numpy (Drake math types allowed).

No Diagram, no file writes; every equation can be tested without building a system.
In the default pipeline the core supplies the features the library holds, the
similarity test and the mapping the planner uses, and the SE(3) timing law that times
the paper's baseline (``timing``).

The modules:

* ``dual_quaternion``: unit dual quaternions for rigid poses (Eq. 1-9): the
  conventions, input checks, products, translation and rotation parts.
* ``quaternion``: unit quaternions for rotations: products, axis-angle, rotation
  vectors and matrices.
* ``pose_conversions``: dual quaternions to and from Drake's ``RigidTransform``, 4x4
  matrices and Euler angles.
* ``screw_motion``: the logarithm and exponential of dual quaternions and screw
  interpolation (ScLERP).
* ``features``: features of demonstrations and task segments (Eq. 12-18), arc-length
  resampling.
* ``similarity``: the similarity test of a segment and a demonstration (Eq. 19-21), the
  one allocation kernel.
* ``mapping``: a demonstration mapped onto a task segment (Eq. 22-25) and bent through
  its critical configurations.
* ``fidelity``: shape fidelity of a mapped demonstration, the allocation cost beyond
  Eq. 31.
* ``timing``: the UR5e's motion limits (``TimingLimits``) and the SE(3) timing law of a
  plan.
* ``tasks``: the task data model: critical configurations, boxes, path constraints,
  trials (Eq. 10).
* ``demonstrations``: the demonstration data type, a joint-angle time series (Eq. 11).
* ``tool``: the tool and what it holds, solids fixed to the flange frame ``tool0``.
* ``people``: people in the cell (capsule bodies on scripted paths or recorded tracks)
  and ISO/TS 15066's protective separation distance and speed override.
* ``guidance``: the guiding hand's path in a simulated kinesthetic demonstration.
* ``synthetic_library``: hand-built demonstrations with the motions of the paper's
  Fig. 5, as pose sequences.
* ``failures``: why a trial failed, as records of a closed set of kinds (each also its
  line), so summaries never parse text.
* ``errors``: errors users can act on (``InputError``) and the command line's exit
  codes.
* ``option_values``: the closed sets and defaults of user options (planners, costs,
  workers), plain Python for the command line.
* ``task_terms``: the closed sets and bounds a task is made of (path-constraint kinds,
  override policies, the fewest critical configurations), plain Python for the checks
  of a task file before Drake loads.
* ``resources``: where the shipped data lives (the UR5e model, the paper's scenarios).
* ``network_policy``: Drake's network switch, ``DRAKE_ALLOW_NETWORK``, read as Drake
  reads it.
* ``exact_memo``: a bounded, process-local memo keyed by exact inputs.
* ``read_only_arrays``: read-only numpy arrays for the frozen dataclasses passed between
  stages.
* ``_lazy``: the exported names of ``drake_lfd`` and its sub-packages, each loaded on
  first use (``lazy_exports``).

It exports what users hold and compute with (``from drake_lfd.core import Task``): the
task and demonstration data types (``Task``, ``ConcreteTask``, ``draw_trial``,
``Demonstration``, ``Feature``), the dual-quaternion conversions, the similarity test
(``allocate_features``), the timing limits, people in the cell, ``InputError`` and where
the shipped scenarios live. ``__all__`` lists them and docs/api.rst documents them; each
is loaded from its module on first use, so importing the package loads none of the
modules that define them. Its other modules, and the names the exports leave out, are
internal.
"""

from __future__ import annotations

from drake_lfd.core._lazy import lazy_exports

# name -> module that defines it (imported on first access, PEP 562).
_EXPORTS = {
    "Demonstration": "drake_lfd.core.demonstrations",
    "dual_quaternion_multiply": "drake_lfd.core.dual_quaternion",
    "dual_quaternion_conjugate": "drake_lfd.core.dual_quaternion",
    "dual_quaternion_from_translation_rotation": "drake_lfd.core.dual_quaternion",
    "translation_rotation_from_dual_quaternion": "drake_lfd.core.dual_quaternion",
    "dual_quaternion_from_rigid_transform": "drake_lfd.core.pose_conversions",
    "rigid_transform_from_dual_quaternion": "drake_lfd.core.pose_conversions",
    "dual_quaternion_from_euler_zyx": "drake_lfd.core.pose_conversions",
    "quaternion_from_axis_angle": "drake_lfd.core.quaternion",
    "dual_quaternion_sclerp": "drake_lfd.core.screw_motion",
    "Feature": "drake_lfd.core.features",
    "task_feature_from_poses": "drake_lfd.core.features",
    "Tolerances": "drake_lfd.core.similarity",
    "Allocation": "drake_lfd.core.similarity",
    "allocate_features": "drake_lfd.core.similarity",
    "TimingLimits": "drake_lfd.core.timing",
    "TimedPlan": "drake_lfd.core.timing",
    "Task": "drake_lfd.core.tasks",
    "ConcreteTask": "drake_lfd.core.tasks",
    "CriticalConfiguration": "drake_lfd.core.tasks",
    "ConcreteCriticalConfiguration": "drake_lfd.core.tasks",
    "Box": "drake_lfd.core.tasks",
    "PathConstraint": "drake_lfd.core.tasks",
    "draw_trial": "drake_lfd.core.tasks",
    "rigid_transform_from_euler_zyx": "drake_lfd.core.tasks",
    "Person": "drake_lfd.core.people",
    "CollaborationParameters": "drake_lfd.core.people",
    "Failure": "drake_lfd.core.failures",
    "InputError": "drake_lfd.core.errors",
    "scenarios_directory": "drake_lfd.core.resources",
    "bundled_library_names": "drake_lfd.core.resources",
}

__all__ = list(_EXPORTS)
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)
