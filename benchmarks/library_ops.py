"""How long a library's everyday operations take as it grows: open, show, add, remove.

:func:`measure_library_operations` builds a library of ``size`` distinct generated
demonstrations (random joint motions from the UR5e's home pose, each its own seed;
prepared by worker processes and written in batches through
``Library.add_prepared``, what ``library add`` of a folder uses) in a directory, then
times, in this process, with the page cache warm (each the median of ``repeats``):

- ``open_s``: ``Library.open`` (the manifest read and every entry checked against its
  log, by the log's stamp and the feature cache's row);
- ``show_s``: the ``library show LIB`` command (``drake_lfd.cli.main``), its output
  to a null stream;
- ``add_s`` / ``remove_s``: ``library add LIB DEMO.csv --name NAME`` of one more
  demonstration and ``library remove LIB NAME`` of it, through the command line;
- ``features_s``: ``library_features`` of every demonstration (what planning loads);
- ``build_s`` and ``peak_rss_mb`` (this process's peak resident memory so far).

``python benchmarks/library_ops.py --sizes 10 100 1000 10000`` prints a table.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import multiprocessing
import os
import resource
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw

from drake_lfd.cli import main as cli_main
from drake_lfd.core.demonstrations import Demonstration
from drake_lfd.io.demonstration_logs import rtde_csv_text
from drake_lfd.io.library import Library, library_features

__all__ = ["generated_demonstration", "build_library", "measure_library_operations", "main"]

Q_HOME = np.array([0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0])
# The paper scenarios' end-effector frame (sims/*.yaml), so the libraries plan those tasks' frame.
X_TOOL0_E = RigidTransform(RollPitchYaw(0.0, math.pi / 2, 0.0), [0.0, 0.0, 0.2])
# Demonstrations prepared per batch (each batch one turn of the library's lock).
BATCH = 1000
KEYS = ("build_s", "open_s", "show_s", "add_s", "remove_s", "features_s", "peak_rss_mb")
# Processor seconds of the same operations: what the work costs when other processes share
# the cores (the wall times above then include waiting for a core, and for the disk).
CPU_KEYS = ("open_cpu_s", "show_cpu_s", "add_cpu_s", "remove_cpu_s", "features_cpu_s")


def generated_demonstration(index: int, samples: int = 50) -> Demonstration:
    """Demonstration ``index``: 2 s from the home pose along its own seeded joint motion
    (a straight move of up to 0.6 rad per joint plus a bend of up to 0.3 rad), named
    ``g<index>``. Distinct indices give distinct motions."""
    rng = np.random.default_rng(index)
    s = np.linspace(0.0, 1.0, samples)
    q = Q_HOME + np.outer(s, rng.uniform(-0.6, 0.6, 6)) + np.outer(np.sin(math.pi * s), rng.uniform(-0.3, 0.3, 6))
    return Demonstration(f"g{index:05d}", np.linspace(0.0, 2.0, samples), q, description=f"generated motion {index}")


_worker_library = None


def _prepare(arguments):
    global _worker_library
    root, index = arguments
    if _worker_library is None:
        _worker_library = Library.open(root)
    demo = generated_demonstration(index)
    return _worker_library.prepare(demo, demo.name, demo.description)


def build_library(root: Path, size: int, *, workers: int = 2) -> float:
    """Makes a new library of ``size`` generated demonstrations at ``root`` (replacing any);
    returns the seconds it took."""
    start = time.perf_counter()
    if root.exists():
        shutil.rmtree(root)
    library = Library.create(root, X_TOOL0_E)
    context = multiprocessing.get_context("fork")
    with context.Pool(workers) as pool:
        for first in range(0, size, BATCH):
            batch = [(root, index) for index in range(first, min(first + BATCH, size))]
            pending = pool.map(_prepare, batch, chunksize=50)
            added, refused = library.add_prepared(pending)
            if refused or len(added) != len(batch):
                raise RuntimeError(f"building the library refused {refused[:1]}")
    return time.perf_counter() - start


def _timed(action, repeats):
    """Median wall and processor seconds of ``repeats`` runs of ``action``."""
    walls, cpus = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        action()
        walls.append(time.perf_counter() - start)
        cpus.append(time.process_time() - start_cpu)
    return statistics.median(walls), statistics.median(cpus)


def _run_quietly(argv):
    with open(os.devnull, "w") as null, contextlib.redirect_stdout(null), contextlib.redirect_stderr(null):
        status = cli_main([str(a) for a in argv])
    if status != 0:
        raise RuntimeError(f"drake-lfd {' '.join(map(str, argv))} exited with {status}")


def measure_library_operations(size: int, workdir: Path, *, repeats: int = 3) -> dict:
    """Builds a library of ``size`` distinct generated demonstrations in ``workdir`` and
    times its operations (module docstring).

    Parameters
    ----------
    size : int
    workdir : Path
        The library goes to ``workdir/library-<size>`` (replaced if present); the extra
        log to ``workdir/extra.csv``.
    repeats : int
        Each operation's time is the median of this many runs.

    Returns
    -------
    dict
        Seconds for ``build_s``, ``open_s``, ``show_s``, ``add_s``, ``remove_s``,
        ``features_s`` (wall) and ``open_cpu_s`` .. ``features_cpu_s`` (processor time of
        this process); ``peak_rss_mb``; ``size``.
    """
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    root = workdir / f"library-{size}"
    result = {"size": size, "build_s": build_library(root, size)}
    extra = workdir / "extra.csv"
    extra.write_text(rtde_csv_text(generated_demonstration(10**6)))
    _run_quietly(["library", "show", root])  # as after any bulk add: the first show settles the caches
    result["open_s"], result["open_cpu_s"] = _timed(lambda: Library.open(root), repeats)
    result["show_s"], result["show_cpu_s"] = _timed(lambda: _run_quietly(["library", "show", root]), repeats)
    adds, removes = [], []
    for _ in range(repeats):
        adds.append(_timed(lambda: _run_quietly(["library", "add", root, extra, "--name", "extra_ops"]), 1))
        removes.append(_timed(lambda: _run_quietly(["library", "remove", root, "extra_ops"]), 1))
    result["add_s"], result["add_cpu_s"] = (statistics.median(times) for times in zip(*adds))
    result["remove_s"], result["remove_cpu_s"] = (statistics.median(times) for times in zip(*removes))
    result["features_s"], result["features_cpu_s"] = _timed(lambda: library_features(Library.open(root)), repeats)
    result["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return result


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000, 10000])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--keep", type=Path, help="build the libraries here and keep them (default: a temporary directory)")
    args = parser.parse_args(argv)
    print(f"{'size':>6}  " + "  ".join(f"{key:>11}" for key in KEYS + CPU_KEYS), flush=True)
    with contextlib.ExitStack() as stack:
        workdir = args.keep or Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="library-ops-")))
        for size in args.sizes:
            result = measure_library_operations(size, workdir, repeats=args.repeats)
            print(f"{size:>6}  " + "  ".join(f"{result[key]:>11.3f}" for key in KEYS + CPU_KEYS), flush=True)
            if args.keep is None:
                shutil.rmtree(workdir / f"library-{size}")
    print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())} on {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    sys.exit(main())
