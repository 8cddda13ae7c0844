"""The feature library as a Drake system: the library's features on an output port.

:class:`FeatureLibrarySystem` holds the features (Eq. 12-13) of a library's
demonstrations in its abstract state and puts them out as a :class:`LibraryFeatures`
record. An optional input takes a newly recorded demonstration (for example from a
:class:`~drake_lfd.systems.demo_recorder.DemoRecorder`): when a demonstration with a new
name arrives, its feature is computed (UR5e forward kinematics with the library's tool
frame, arc-length resampling) and added, and the record's ``revision`` goes up, so a
planner downstream can plan again. The demonstrations added during a run live in the
system's abstract state too (every Context has its own); no event writes a file:
after the simulation, :meth:`FeatureLibrarySystem.write_added_demonstrations` adds them
to a library directory (atomically, as ``drake-lfd library add`` does).

Not for: reading or writing library files (``io/library.py``) or the feature math
(``core/features.py``).
"""

from __future__ import annotations

import dataclasses
import hashlib
import types
from typing import Mapping

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context, DiagramBuilder, EventStatus, LeafSystem, OutputPort

from drake_lfd.core.demonstrations import Demonstration
from drake_lfd.core.features import DEFAULT_NUM_SAMPLES, DEFAULT_ROTATION_LENGTH_M, Feature
from drake_lfd.io.simulation_config import DEFAULT_CHECK_PERIOD_S
from drake_lfd.robot.kinematics import UR5eKinematics, dual_quaternions_from_demonstration
from drake_lfd.systems.demo_recorder import NO_DEMONSTRATION

__all__ = ["LibraryFeatures", "AddedDemonstrations", "FeatureLibrarySystem"]


@dataclasses.dataclass(frozen=True, eq=False)
class LibraryFeatures:
    """The library's features as they flow between systems.

    Attributes
    ----------
    features : Mapping[str, Feature]
        Read-only, in library order.
    revision : int
        0 for the library as loaded; +1 for every demonstration added since.
    X_tool0_E : RigidTransform
        The tool frame the demonstrations were recorded with.
    """

    features: Mapping[str, Feature]
    revision: int = 0
    X_tool0_E: RigidTransform = dataclasses.field(default_factory=RigidTransform)

    def __post_init__(self):
        digest = hashlib.sha256()
        for name, feature in self.features.items():
            digest.update(name.encode() + b"\0")
            for values in (feature.rotations, feature.translations):
                digest.update(np.ascontiguousarray(values, dtype=float).tobytes())
        object.__setattr__(self, "_digest", digest.digest())

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.features)

    @property
    def digest(self) -> bytes:
        """A digest of the names and features: equal digests, equal libraries."""
        return self._digest

    def __deepcopy__(self, memo):
        return self  # immutable: Drake's copies of a Context share it


@dataclasses.dataclass(frozen=True, eq=False)
class AddedDemonstrations:
    """The demonstrations a :class:`FeatureLibrarySystem` added during a run, in order
    (its abstract state; immutable, so Drake's copies of a Context share it).

    Attributes
    ----------
    demonstrations : tuple[Demonstration, ...]
    """

    demonstrations: tuple = ()

    def __deepcopy__(self, memo):
        return self


class FeatureLibrarySystem(LeafSystem):
    """The features of a library, and the demonstrations added during a run.

    .. pydrake_system::

        name: FeatureLibrarySystem
        input_ports:
        - demonstration (optional)
        output_ports:
        - library

    ``library`` is an abstract :class:`LibraryFeatures`. ``demonstration`` (declared when
    ``accept_demonstrations`` is True; may stay unconnected) is an abstract
    :class:`~drake_lfd.core.demonstrations.Demonstration`
    (:data:`~drake_lfd.systems.demo_recorder.NO_DEMONSTRATION`, or any of fewer than 2
    samples, stands for none yet); it is read every ``check_period`` s and a
    demonstration whose name the library does not have yet is added: its feature to the
    ``library`` output, the demonstration itself to the :class:`AddedDemonstrations` in
    the Context (:meth:`added_demonstrations`, written to a library directory after the
    run by :meth:`write_added_demonstrations`).

    Parameters
    ----------
    features : Mapping[str, Feature]
        The library's features (for example ``drake_lfd.io.library.library_features``).
    X_tool0_E : RigidTransform, optional
        The library's tool frame (used for demonstrations added during the run).
    accept_demonstrations : bool
    check_period : float
        s.
    num_samples, rotation_length_m :
        Feature resampling of added demonstrations (the library's settings).
    """

    def __init__(
        self,
        *,
        features: Mapping[str, Feature],
        X_tool0_E: RigidTransform | None = None,
        accept_demonstrations: bool = False,
        check_period: float = DEFAULT_CHECK_PERIOD_S,
        num_samples: int = DEFAULT_NUM_SAMPLES,
        rotation_length_m: float = DEFAULT_ROTATION_LENGTH_M,
    ):
        super().__init__()
        self._X_tool0_E = RigidTransform() if X_tool0_E is None else RigidTransform(X_tool0_E)
        self._num_samples = int(num_samples)
        self._rotation_length_m = float(rotation_length_m)
        self._kinematics = None  # built on the first added demonstration
        initial = LibraryFeatures(types.MappingProxyType(dict(features)), 0, self._X_tool0_E)
        self._state_index = self.DeclareAbstractState(AbstractValue.Make(initial))
        self.library_output_port = self.DeclareStateOutputPort("library", self._state_index)
        self._added_index = self.DeclareAbstractState(AbstractValue.Make(AddedDemonstrations()))
        self.demonstration_input_port = None
        if accept_demonstrations:
            self.demonstration_input_port = self.DeclareAbstractInputPort(
                "demonstration", AbstractValue.Make(NO_DEMONSTRATION))
            self.DeclarePeriodicUnrestrictedUpdateEvent(check_period, 0.0, self._add_new_demonstration)

    @staticmethod
    def AddToBuilder(*, builder: DiagramBuilder, features: Mapping[str, Feature],
                     demonstration_output_port: OutputPort | None = None,
                     name: str = "feature_library", **kwargs) -> "FeatureLibrarySystem":
        """Adds the system named ``name``; connects ``demonstration_output_port`` when given
        (with ``accept_demonstrations=True`` and no port, export or fix its input)."""
        accept = kwargs.pop("accept_demonstrations", False) or demonstration_output_port is not None
        system = builder.AddNamedSystem(name, FeatureLibrarySystem(
            features=features, accept_demonstrations=accept, **kwargs))
        if demonstration_output_port is not None:
            builder.Connect(demonstration_output_port, system.demonstration_input_port)
        return system

    def feature_of(self, demonstration: Demonstration) -> Feature:
        """The feature of a demonstration under this library's tool frame and sampling."""
        if self._kinematics is None:
            self._kinematics = UR5eKinematics(X_tool0_E=self._X_tool0_E)
        poses = dual_quaternions_from_demonstration(demonstration, self._kinematics)
        return Feature.from_poses(poses, num_samples=self._num_samples, rotation_length_m=self._rotation_length_m)

    def _add_new_demonstration(self, context, state):
        port = self.demonstration_input_port
        if not port.HasValue(context):
            return EventStatus.DidNothing()
        demonstration = port.Eval(context)
        if demonstration.num_samples < 2:  # NO_DEMONSTRATION: nothing recorded yet
            return EventStatus.DidNothing()
        current = context.get_abstract_state(self._state_index).get_value()
        if demonstration.name in current.features:
            return EventStatus.DidNothing()
        features = dict(current.features)
        features[demonstration.name] = self.feature_of(demonstration)
        added = context.get_abstract_state(self._added_index).get_value()
        state.get_mutable_abstract_state(self._state_index).set_value(
            LibraryFeatures(types.MappingProxyType(features), current.revision + 1, self._X_tool0_E))
        state.get_mutable_abstract_state(self._added_index).set_value(
            AddedDemonstrations(added.demonstrations + (demonstration,)))
        return EventStatus.Succeeded()

    def added_demonstrations(self, context: Context) -> tuple[Demonstration, ...]:
        """The demonstrations added during the run of ``context`` (this system's Context
        or its Diagram's root Context), in order."""
        try:
            self.ValidateContext(context)
        except RuntimeError:
            context = self.GetMyContextFromRoot(context)
        return context.get_abstract_state(self._added_index).get_value().demonstrations

    def write_added_demonstrations(self, context: Context, library) -> tuple[str, ...]:
        """Adds the demonstrations added during the run of ``context`` to ``library``
        (a :class:`~drake_lfd.io.library.Library`, with :meth:`Library.add
        <drake_lfd.io.library.Library.add>`: atomic files under the library's lock) and
        returns their names; those the library already has are skipped. Call it after
        the simulation.

        Raises
        ------
        InputError
            As ``Library.add`` (read-only library, an implausible demonstration); the
            demonstrations before it are written.
        """
        have = {name.lower() for name in library.names}
        written = []
        for demonstration in self.added_demonstrations(context):
            if demonstration.name.lower() in have:
                continue
            library.add(demonstration, demonstration.name, demonstration.description)
            have.add(demonstration.name.lower())
            written.append(demonstration.name)
        return tuple(written)
