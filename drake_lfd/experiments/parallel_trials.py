"""Closed-loop trials on worker processes or a cluster (dask.distributed), results as they finish.

A trial is named by a small, picklable :class:`TrialSpec`: which runner (a
:class:`RunnerSpec`: task file, library, planner options, an optional robot base
placement) and which trial (1-based index and seed). :func:`run_trial_specs` runs a list
of them on a ``dask.distributed`` Client: by default a LocalCluster of single-threaded
worker *processes* (Drake and the planners hold the GIL, so threads would not run in
parallel), or an existing cluster named by its scheduler address. Each worker process
builds a :class:`~drake_lfd.experiments.simulation.TrialRunner` (one pipeline Diagram)
once per distinct RunnerSpec and reuses it for every trial of that spec it runs. A trial
draws its concrete task from its own seed, so its outcome does not depend on which
process ran it, nor on the trials that ran before it there. With one worker (or one
trial) and no scheduler, the trials run in this process and no cluster is started.

On Linux a LocalCluster's worker processes are forked from this one
(:data:`WORKER_START_METHOD`), so they start with pydrake imported and a cluster starts
in a fraction of the time spawned workers (other systems) take, which import it as they
join. A command with several sets of trials (``paper``: three tasks) starts one
cluster with :func:`trial_cluster` and passes it to each :func:`run_trial_specs` call
(``cluster=``); without ``cluster=``, each call starts and shuts down its own. A process
loads a library's features once for all the runners it builds (a sweep's base
placements share them).

Outcomes reach a callback as they finish (``as_completed``), or, with ``in_order``, in
the order of the specs (a finished trial waits for the ones before it; on an interrupt,
every finished one is still delivered before the interrupt goes on). A cluster is shut
down however its run (or its ``with`` block) ends, Ctrl-C and SIGTERM included. Dask's
own logging is silenced.

Not for: judging trials (:mod:`drake_lfd.experiments.simulation`), sweeps over base
placements (:mod:`drake_lfd.experiments.sweep`), or the command line.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import importlib
import logging
import math
import signal
import sys
import time
import warnings
from pathlib import Path
from typing import Callable, Iterator, Sequence

import numpy as np

from drake_lfd.core.errors import InputError
from drake_lfd.core.exact_memo import ExactMemo
from drake_lfd.core.option_values import default_workers
from drake_lfd.planning.options import PlanningOptions

__all__ = [
    "BasePlacement",
    "RunnerSpec",
    "TrialSpec",
    "runner_spec",
    "trial_specs",
    "run_trial_spec",
    "run_trial_specs",
    "run_trials_on_workers",
    "default_workers",
    "TrialCluster",
    "trial_cluster",
]

#: TrialRunners a worker process keeps (least recently used dropped first): a sweep
#: submits the trials of one base placement together, so a few cover the trials in flight.
RUNNERS_PER_WORKER = 4


#: Libraries' features a process keeps, by library and fingerprint: the runners of a
#: sweep's base placements share one set (loading a library costs several times what
#: building a runner from it does). Features are read-only, so sharing them is safe.
FEATURE_SETS_PER_PROCESS = 2
_FEATURES = ExactMemo(maxsize=FEATURE_SETS_PER_PROCESS)  # by (library, fingerprint)


@dataclasses.dataclass(frozen=True)
class BasePlacement:
    """Where the robot base stands: position (m) and yaw about the world z axis (deg).

    It replaces the position and yaw of the task's ``X_WB``; roll and pitch stay the task's.
    """

    x: float
    y: float
    z: float
    yaw_deg: float

    @classmethod
    def of(cls, X_WB) -> "BasePlacement":
        """The placement of a base pose ``X_WB`` (a RigidTransform)."""
        from pydrake.math import RollPitchYaw

        x, y, z = (float(v) for v in X_WB.translation())
        return cls(x, y, z, math.degrees(RollPitchYaw(X_WB.rotation()).yaw_angle()))

    def X_WB(self, task_X_WB):
        """The base pose: this position and yaw, the roll and pitch of ``task_X_WB``."""
        from pydrake.math import RigidTransform, RollPitchYaw

        rpy = RollPitchYaw(task_X_WB.rotation())
        return RigidTransform(RollPitchYaw(rpy.roll_angle(), rpy.pitch_angle(), math.radians(self.yaw_deg)),
                              np.array([self.x, self.y, self.z]))


@dataclasses.dataclass(frozen=True)
class RunnerSpec:
    """What one TrialRunner (one pipeline Diagram) is built from; hashable, so a worker
    keeps one runner per spec.

    ``task_file``, ``library`` (a bundled name or an absolute path), ``policy_file``,
    ``base`` and ``people_file`` (``simulate --people``) say what to load; ``fingerprint`` (:func:`runner_spec`) changes when those
    files do, so a long-lived worker of a cluster does not reuse a stale runner. Every
    other field is a keyword option of
    :class:`~drake_lfd.experiments.simulation.TrialRunner`, with its default: ``options``
    (the :class:`~drake_lfd.planning.options.PlanningOptions`, hashable) and
    ``controller``.
    """

    task_file: str
    library: str
    policy_file: str | None = None
    base: BasePlacement | None = None
    fingerprint: str = ""
    people_file: str | None = None
    options: PlanningOptions = PlanningOptions()
    controller: str | None = None

    def runner_options(self) -> dict:
        """The TrialRunner keyword options: every field but what says what to load."""
        loading = {"task_file", "library", "policy_file", "base", "fingerprint", "people_file"}
        return {field.name: getattr(self, field.name) for field in dataclasses.fields(self)
                if field.name not in loading}

    def options_json(self) -> dict:
        """The options as a sweep's rows and summary record them (JSON): ``planner``,
        ``cost``, ``refine`` (the command line's planning options) and ``controller``."""
        return {"planner": self.options.planner, "cost": self.options.cost, "refine": self.options.refine,
                "controller": self.controller}

    def task(self):
        """The task file's task, with ``base`` (if any) as its robot base."""
        from drake_lfd.io.task_files import load_task

        task = load_task(self.task_file)
        if self.people_file is not None:
            from drake_lfd.io.people_files import task_with_people

            task = task_with_people(task, self.people_file)
        if self.base is None:
            return task
        return dataclasses.replace(task, X_WB=self.base.X_WB(task.X_WB))

    def build(self):
        """A TrialRunner for this spec (loads the task, the library and the policy)."""
        from drake_lfd.experiments.simulation import TrialRunner
        from drake_lfd.io.library import Library, library_features
        from drake_lfd.io.policy_files import load_policy

        policy = load_policy(self.policy_file) if self.policy_file else None
        features = _FEATURES.get((self.library, self.fingerprint),
                                 lambda: library_features(Library.open(self.library)))
        return TrialRunner(self.task(), features, policy=policy, **self.runner_options())


@dataclasses.dataclass(frozen=True)
class TrialSpec:
    """One trial: its runner, its 1-based index and its seed; ``record_html`` (optional)
    asks for a Meshcat recording of it."""

    runner: RunnerSpec
    trial: int
    seed: int
    record_html: str | None = None


def _fingerprint(*paths: Path | None) -> str:
    digest = hashlib.sha256()
    for path in paths:
        if path is not None and path.is_file():
            digest.update(path.read_bytes())
        digest.update(b"\0")
    return digest.hexdigest()[:16]


def runner_spec(task_file, library, *, policy_file=None, base: BasePlacement | None = None, people_file=None,
                **options) -> RunnerSpec:
    """A RunnerSpec with absolute paths and the fingerprint of the files it names.

    Parameters
    ----------
    task_file : str or Path
    library : Library
        An opened library (its label names it: a bundled name or an absolute path).
    policy_file : str or Path, optional
    base : BasePlacement, optional
    people_file : str or Path, optional
        A people file put on the task (``simulate --people``).
    **options
        TrialRunner options, RunnerSpec fields: ``options`` (a
        :class:`~drake_lfd.planning.options.PlanningOptions`), ``controller``.
    """
    from drake_lfd.io.library_manifest import MANIFEST_NAME

    task_path = Path(task_file).resolve()
    policy_path = Path(policy_file).resolve() if policy_file else None
    people_path = Path(people_file).resolve() if people_file else None
    return RunnerSpec(
        task_file=str(task_path), library=library.label,
        policy_file=None if policy_path is None else str(policy_path), base=base,
        people_file=None if people_path is None else str(people_path),
        fingerprint=_fingerprint(task_path, policy_path, library.path / MANIFEST_NAME,
                                 *(() if people_path is None else (people_path,))), **options,
    )


def trial_specs(runner: RunnerSpec, *, trials: int, seed: int, record_html=None) -> list[TrialSpec]:
    """Trials 1..``trials`` of one runner, trial i (1-based) with seed ``seed + i - 1``
    (as :func:`~drake_lfd.experiments.simulation.run_trials`); the first one carries
    ``record_html``."""
    return [TrialSpec(runner, i + 1, seed + i, None if (i or record_html is None) else str(record_html))
            for i in range(trials)]


# The TrialRunners of this process (a worker's, or the main process's), by spec.
_RUNNERS = ExactMemo(maxsize=RUNNERS_PER_WORKER)


def _runner_for(spec: RunnerSpec):
    return _RUNNERS.get(spec, spec.build)


def run_trial_spec(spec: TrialSpec):
    """Runs one trial on this process's runner for its spec (built on first use); returns
    its :class:`~drake_lfd.experiments.simulation.TrialOutcome`. What the workers run."""
    return _runner_for(spec.runner).run(trial=spec.trial, seed=spec.seed, record_html=spec.record_html)


#: Dask's periodic housekeeping, slowed: the system monitors' samples and the
#: event-loop tick check. At their defaults the main process (scheduler and client) takes
#: a noticeable share of a 2-core machine from the workers; with these, about half of
#: that, most of it loading the task and library (bench_sweep.py).
_QUIET_CLUSTER = {
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.admin.tick.interval": "1s",
}


#: How a LocalCluster's worker processes start. On Linux they are forked from the
#: command's process, pydrake and the project already imported, so a cluster starts and
#: stops without each worker importing pydrake again (spawned workers do). Elsewhere
#: (macOS, where forking a process that has loaded system frameworks is unsafe) they are
#: spawned.
WORKER_START_METHOD = "fork" if sys.platform.startswith("linux") else "spawn"


def _silence_dask() -> None:
    """Dask's and Tornado's loggers say nothing below CRITICAL, and dask's Python warnings
    are not shown (about closing workers, ports and heartbeats: not for the user)."""
    for name in ("distributed", "dask", "tornado", "bokeh"):
        logging.getLogger(name).setLevel(logging.CRITICAL)
    warnings.filterwarnings("ignore", module=r"(distributed|dask)(\.|$)")


def _worker_plugin():
    """A worker plugin for the processes of a LocalCluster, set up as each one joins:
    it makes the process ignore SIGINT (Ctrl-C reaches the whole process group, and only
    this process is to act on it: it shuts the cluster down; a worker would print its own
    traceback) and take SIGTERM's default action, then imports
    :mod:`drake_lfd.experiments.simulation` (pydrake; already there in a forked worker),
    so that import happens while the cluster starts rather than in the first trial. Made here so
    that importing this module does not import dask (the class travels to the workers by
    value)."""
    from distributed import WorkerPlugin

    class PrepareTrialWorker(WorkerPlugin):
        name = "drake-lfd-prepare-trial-worker"
        idempotent = True

        def setup(self, worker):
            with contextlib.suppress(ValueError):  # not the worker process's main thread
                signal.signal(signal.SIGINT, signal.SIG_IGN)
                # A forked worker has the command's SIGTERM handler (raise KeyboardInterrupt);
                # the nanny's terminate is to end it as it ends a spawned one.
                signal.signal(signal.SIGTERM, signal.SIG_DFL)
            with contextlib.suppress(Exception):  # a failing import fails the first trial, in full
                importlib.import_module("drake_lfd.experiments.simulation")

    return PrepareTrialWorker()


def _open_client(workers: int, scheduler: str | None):
    """``(client, cluster)``: a Client of ``scheduler`` (``cluster`` None), or of a new
    LocalCluster of ``workers`` single-threaded worker processes, each set up by
    :func:`_worker_plugin`. Raises InputError for a scheduler it cannot reach."""
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            return Client(scheduler, timeout="20s"), None
        except (OSError, TimeoutError, ValueError) as error:
            raise InputError(f"cannot reach the scheduler {scheduler!r}: {error}", field="--scheduler") from None
    # No dashboard, and no statistical profiling in the workers: the profiler samples
    # every thread's stack under the GIL every 10 ms, a cost on trials that are Python
    # all the way down.
    import dask

    dask.config.set({"distributed.worker.profile.enabled": False, **_QUIET_CLUSTER,
                     "distributed.worker.multiprocessing-method": WORKER_START_METHOD})
    if WORKER_START_METHOD == "fork":
        # The workers are copies of this process: what it has imported, they have.
        # (multiprocessing flushes stdout and stderr before it forks, so nothing buffered
        # there is written twice.)
        importlib.import_module("drake_lfd.experiments.simulation")
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                           memory_limit=0, silence_logs=logging.CRITICAL)
    # The scheduler's GC diagnosis only logs (silenced here), and a Ctrl-C that lands in
    # its gc callback, in whatever this process's main thread is doing, is swallowed.
    from distributed.gc import disable_gc_diagnosis

    disable_gc_diagnosis(force=True)
    client = None
    try:
        client = Client(cluster)
        client.register_plugin(_worker_plugin())
    except BaseException:
        _close_client(client, cluster)
        raise
    return client, cluster


def _close_client(client, cluster) -> None:
    """Closes ``client`` and then ``cluster`` (either may be None), errors ignored."""
    if client is not None:
        with contextlib.suppress(Exception):
            client.close(timeout=10)
    if cluster is not None:
        with contextlib.suppress(Exception):
            cluster.close(timeout=10)


class TrialCluster:
    """Where trials run: a dask Client of a new LocalCluster of ``workers`` worker
    processes, or of the workers of ``scheduler``, started when this is made. Made by
    :func:`trial_cluster`; pass it as ``cluster=`` to :func:`run_trial_specs` or
    :func:`run_trials_on_workers` (any number of times)."""

    def __init__(self, workers: int, scheduler: str | None = None):
        self.workers = int(workers)
        self.scheduler = scheduler
        _silence_dask()
        self._client, self._cluster = _open_client(self.workers, scheduler)

    def client(self):
        """The Client; RuntimeError once closed."""
        if self._client is None:
            raise RuntimeError("the trial cluster is closed")
        return self._client

    def close(self) -> None:
        """Closes the client and the LocalCluster (its worker processes end); idempotent."""
        client, cluster = self._client, self._cluster
        self._client = self._cluster = None
        if client is not None:
            _close_client(client, cluster)


@contextlib.contextmanager
def trial_cluster(workers: int, scheduler: str | None = None) -> Iterator[TrialCluster]:
    """A started :class:`TrialCluster`, closed on the way out however the block ends (an
    error, Ctrl-C, SIGTERM); pass it as ``cluster=`` to run several sets of trials on the
    same worker processes (each keeps the TrialRunners it built).

    Parameters
    ----------
    workers : int
        Worker processes of the LocalCluster (ignored with ``scheduler``).
    scheduler : str, optional
        The address of a running scheduler: a Client of it, and no LocalCluster.
    """
    cluster = TrialCluster(workers, scheduler)
    try:
        yield cluster
    finally:
        cluster.close()


def run_trial_specs(
    specs: Sequence[TrialSpec],
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    on_result: Callable[[int, int, TrialSpec, object], None] | None = None,
    in_order: bool = False,
    cluster: TrialCluster | None = None,
) -> list:
    """Runs the trials; returns their outcomes in the order of ``specs``.

    Parameters
    ----------
    specs : sequence of TrialSpec
    workers : int, optional
        Worker processes of the LocalCluster (default :func:`default_workers`); with 1
        (or a single trial) the trials run in this process.
    scheduler : str, optional
        The address of a running scheduler (``tcp://host:8786``): its workers run the
        trials (``workers`` is then ignored).
    on_result : callable, optional
        ``on_result(done, total, spec, outcome)`` for each finished trial, in the main
        process: as they finish, or with ``in_order`` in the order of ``specs``.
    in_order : bool
        Deliver in spec order (finished trials wait for the ones before them); an
        interrupt or an error first delivers every trial that finished.
    cluster : TrialCluster, optional
        Run the trials on this cluster (from :func:`trial_cluster`; ``workers`` and
        ``scheduler`` are then ignored), and leave it running. Without it, a cluster is
        started for these trials and shut down after them (none with one worker).
    """
    specs = list(specs)
    total = len(specs)
    outcomes: list = [None] * total
    finished: dict[int, object] = {}  # index -> outcome, finished but not yet delivered
    delivered = 0
    next_index = 0  # in_order: the next index to deliver

    def deliver(index: int) -> None:
        nonlocal delivered
        outcome = finished.pop(index)
        delivered += 1
        if on_result is not None:
            on_result(delivered, total, specs[index], outcome)

    def deliver_ready() -> None:
        nonlocal next_index
        if not in_order:
            deliver_all()
        while next_index in finished:
            deliver(next_index)
            next_index += 1

    def deliver_all() -> None:  # also after an interrupt: every finished trial, in order
        for index in sorted(finished):
            deliver(index)

    def run_on(client) -> None:
        from distributed import as_completed

        futures = {client.submit(run_trial_spec, spec, pure=False): index for index, spec in enumerate(specs)}
        try:
            for future in as_completed(futures):
                index = futures[future]
                outcomes[index] = finished[index] = future.result()
                deliver_ready()
        except BaseException:
            with contextlib.suppress(Exception):  # the original error is the one to report
                deliver_all()
            raise

    if cluster is not None:
        if specs:
            run_on(cluster.client())
        return outcomes
    workers = default_workers(total) if workers is None else int(workers)
    if scheduler is None and (workers <= 1 or total <= 1):
        try:
            for index, spec in enumerate(specs):
                outcomes[index] = finished[index] = run_trial_spec(spec)
                deliver_ready()
        finally:
            _RUNNERS.clear()  # this process is no worker: its Diagrams and features are not kept
            _FEATURES.clear()
        return outcomes
    with trial_cluster(workers, scheduler) as own:
        run_on(own.client())
    return outcomes


def run_trials_on_workers(
    runner: RunnerSpec,
    *,
    trials: int,
    seed: int = 0,
    record_html=None,
    progress: Callable[[int, int, object], None] | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    cluster: TrialCluster | None = None,
) -> tuple[list, float]:
    """:func:`~drake_lfd.experiments.simulation.run_trials` on workers: the same
    outcomes, in trial order, and the wall time; ``progress(done, total, outcome)`` in
    trial order. The first trial carries ``record_html``; if it did not run, the first
    trial that did is run once more here to record it (a trial's outcome is the same
    wherever it runs). ``workers``, ``scheduler`` and ``cluster`` are those of
    :func:`run_trial_specs`."""
    start = time.perf_counter()
    outcomes = run_trial_specs(
        trial_specs(runner, trials=trials, seed=seed, record_html=record_html), workers=workers,
        scheduler=scheduler, in_order=True, cluster=cluster,
        on_result=None if progress is None else lambda done, total, spec, outcome: progress(done, total, outcome),
    )
    if record_html is not None and outcomes and outcomes[0].run is None:
        first = next((o for o in outcomes if o.run is not None), None)
        if first is not None:
            runner.build().run(trial=first.trial, seed=first.seed, record_html=record_html)
    return outcomes, time.perf_counter() - start
