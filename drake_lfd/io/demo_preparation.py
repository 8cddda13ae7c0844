"""A new demonstration made ready for a library: every check that does not depend on
what the library holds, and its feature, computed by forward kinematics.

What ``Library.add`` and a bulk add run on each demonstration before the library is
touched, so a refused demonstration changes nothing. Features are computed with
``X_WB`` = identity (they do not depend on where the robot stands) for the library's
end-effector frame ``X_tool0_E``.

Not for: writing anything (:mod:`drake_lfd.io.library` writes what this prepares),
reading logs (:mod:`drake_lfd.io.log_import`), the feature math
(:mod:`drake_lfd.core.features`).
"""

from __future__ import annotations

import datetime
from typing import NamedTuple

from drake_lfd.core.demonstrations import Demonstration, check_demonstration
from drake_lfd.core.errors import InputError
from drake_lfd.core.features import (
    DEFAULT_NUM_SAMPLES,
    DEFAULT_ROTATION_LENGTH_M,
    Feature,
    arc_lengths_from_poses,
)
from drake_lfd.io.demonstration_logs import check_plausible_motion, rtde_csv_text
from drake_lfd.io.library_manifest import DEMOS_DIRECTORY, DemoEntry, check_demo_name
from drake_lfd.robot.kinematics import UR5eKinematics, dual_quaternions_from_demonstration

__all__ = ["MIN_MOTION_LENGTH", "PreparedDemo", "prepare_demonstration", "DemonstrationPreparer"]

# A demonstration whose tool path is shorter than this (arc length in metres, rotation
# counted as in features.py) does not move and has no feature worth matching.
MIN_MOTION_LENGTH = 1e-6


class PreparedDemo(NamedTuple):
    """A checked demonstration ready to be written: entry, log bytes, feature."""

    entry: DemoEntry
    log_bytes: bytes
    feature: Feature


def prepare_demonstration(demonstration, name, description, *, kinematics, num_samples, rotation_length_m,
                          source, label):
    """Every check of a new demonstration that does not depend on what the library
    holds (name syntax, the demonstration itself, that it moves the tool), and its
    feature: a :class:`PreparedDemo`. Errors name ``source`` (the log), else ``label``."""
    check_demo_name(name)
    if not isinstance(description, str):
        raise InputError(f"expected a string, got {description!r}", field="description")
    file = label if source is None else source
    check_demonstration(demonstration, file=file)
    check_plausible_motion(
        demonstration.timestamps, demonstration.joint_positions, file=file, field_of=lambda i: f"sample {i}"
    )
    stored = Demonstration(
        name=name,
        timestamps=demonstration.timestamps,
        joint_positions=demonstration.joint_positions,
        description=description,
    )
    D = dual_quaternions_from_demonstration(stored, kinematics)
    length = float(arc_lengths_from_poses(D, rotation_length_m)[-1])
    if not length > MIN_MOTION_LENGTH:
        raise InputError(
            f"the demonstration does not move the tool (its path is {length:.3g} m long, counting "
            f"{rotation_length_m:g} m per radian of rotation); it has no feature to learn",
            file=file,
            field="samples",
        )
    feature = Feature.from_poses(D, num_samples=num_samples, rotation_length_m=rotation_length_m)
    entry = DemoEntry(
        name=name,
        file=f"{DEMOS_DIRECTORY}/{name}.csv",
        samples=stored.num_samples,
        duration_s=stored.duration_s,
        description=description,
        added=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    )
    return PreparedDemo(entry, rtde_csv_text(stored).encode("utf-8"), feature)


class DemonstrationPreparer:
    """Checks new demonstrations and computes their features for one end-effector frame,
    before any library is touched: what ``library add`` of many logs runs on each log
    (:meth:`Library.prepare <drake_lfd.io.library.Library.prepare>` uses one too).

    Parameters
    ----------
    X_tool0_E : RigidTransform
    label : str
        How to name the library in errors.
    num_samples, rotation_length_m
        Feature parameters (``features.Feature.from_poses``).
    """

    def __init__(self, X_tool0_E, label, num_samples=DEFAULT_NUM_SAMPLES,
                 rotation_length_m=DEFAULT_ROTATION_LENGTH_M):
        self.kinematics = UR5eKinematics(X_tool0_E=X_tool0_E)
        self.label = str(label)
        self.num_samples = int(num_samples)
        self.rotation_length_m = float(rotation_length_m)

    def prepare(self, demonstration, name, description="", *, source=None):
        """The checked demonstration, ready for :meth:`Library.add_prepared
        <drake_lfd.io.library.Library.add_prepared>`; writes nothing. Raises InputError
        as ``Library.add`` (bad name, invalid demonstration, one that does not move)."""
        return prepare_demonstration(
            demonstration, name, description, kinematics=self.kinematics, num_samples=self.num_samples,
            rotation_length_m=self.rotation_length_m, source=source, label=self.label,
        )
