"""Layer 4, files: everything read from or written to disk.

In the default pipeline a task file and a library are read here, the library's features
come from its cache (``library_source.resolve_features`` takes a library in any form),
and the closed loop's gains and periods come from ``simulation_config``.

The modules:

* ``task_files``: task files, the YAML form of a task, read and checked.
* ``task_schema``: a task file's keys and the check of its structure, without Drake.
* ``task_checks``: a task file's values checked without Drake, and the command line's
  check of a task or people file before Drake loads.
* ``simulation_config``: the typed ``simulation:`` block: station, controller (the
  default ``compiled`` one or the baseline's ``drake`` / ``pseudo_inverse``), monitor,
  logger, planner system.
* ``simulation_schema``: the ``simulation:`` block's own keys and its range checks,
  without Drake.
* ``guidance_scripts``: the YAML scripts of ``drake-lfd record``.
* ``yaml_checks``: reading the YAML files: syntax, nesting, duplicated keys, the
  structure against the Spec dataclasses, loading.
* ``yaml_values``: a YAML file's values converted and checked one by one (numbers,
  coordinates, angles, poses).
* ``people_files``: people in the cell and speed and separation monitoring (``people:``,
  ``collaboration:``; ``simulate --people``), read and checked.
* ``people_schema``: the keys of people, ``collaboration:`` and people files, without
  Drake.
* ``people_checks``: people's and ``collaboration:`` values checked without Drake.
* ``demonstration_logs``: UR5e joint logs as RTDE CSV, read, checked and written.
* ``rtde_logs``: full RTDE recordings, the TCP-offset check against ``actual_TCP_pose``.
* ``rosbag_logs``: joint logs from ROS 1 and ROS 2 bags (``sensor_msgs/JointState``).
* ``log_import``: a demonstration from whatever log a user has (RTDE CSV or ROS bag).
* ``library``: the demonstration library (Eq. 14): ``Library``, its read and edit API.
* ``library_store``: a library directory on disk: layout, lock, temporaries, the check
  of the manifest against the logs, an atomic copy.
* ``library_feature_reads``: a library's features, from its cache or its logs.
* ``demo_preparation``: a new demonstration checked and its feature computed, before a
  library is touched.
* ``bulk_add``: many logs added at once (``Library.add_many``), with a typed report.
* ``library_manifest``: a library's manifest, ``library.json``.
* ``feature_cache``: a library's feature cache, ``cache/features.sqlite``.
* ``library_source``: a library given in any form, as its features.
* ``file_lock``: advisory file locks, so writers of one directory take turns.
* ``policy_files``: Q-policy files (JSON).
* ``plan_json``: the JSON form of a plan or a demonstration request (``plan --json``).
* ``pose_records``: poses in JSON files.
* ``json_lines``: results written as they come, one JSON record per line.
* ``strict_json``: strict JSON, never ``NaN`` or ``Infinity``.
* ``atomic_files``: atomic file writes.
* ``trajectory_export``: a planned joint trajectory resampled, checked and written for a
  real UR5e (``drake-lfd export``).
* ``urscript``: the URScript program that runs an exported trajectory.

It exports the files users read and write (``from drake_lfd.io import load_task``): task
files, the demonstration library, joint logs, guidance scripts, people files, the
simulation configuration, a demonstration request in words, policy files and exported
trajectories. ``__all__`` lists them and docs/api.rst documents them; each is loaded
from its module on first use, so importing the package loads none of the modules that
define them. Its other modules, and the names the exports leave out, are internal.
"""

from __future__ import annotations

from drake_lfd.core._lazy import lazy_exports

# name -> module that defines it (imported on first access, PEP 562).
_EXPORTS = {
    "load_task": "drake_lfd.io.task_files",
    "Library": "drake_lfd.io.library",
    "library_features": "drake_lfd.io.library",
    "copy_library": "drake_lfd.io.library",
    "check_end_effector_frame": "drake_lfd.io.library",
    "resolve_features": "drake_lfd.io.library_source",
    "read_rtde_csv": "drake_lfd.io.demonstration_logs",
    "write_rtde_csv": "drake_lfd.io.demonstration_logs",
    "read_demonstration_log": "drake_lfd.io.log_import",
    "load_guidance_script": "drake_lfd.io.guidance_scripts",
    "load_people_file": "drake_lfd.io.people_files",
    "task_with_people": "drake_lfd.io.people_files",
    "PipelineConfig": "drake_lfd.io.simulation_config",
    "StationConfig": "drake_lfd.io.simulation_config",
    "ControllerConfig": "drake_lfd.io.simulation_config",
    "describe_uncovered": "drake_lfd.io.plan_json",
    "save_policy": "drake_lfd.io.policy_files",
    "load_policy": "drake_lfd.io.policy_files",
    "load_plan_trajectory": "drake_lfd.io.trajectory_export",
    "least_slow_down": "drake_lfd.io.trajectory_export",
}

__all__ = list(_EXPORTS)
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)
