"""Library writes under stress: concurrent ``library add`` and ``kill -9`` mid-write.

Every writer is a separate process running the real command line
(``drake_lfd.cli.main``, what the ``drake-lfd`` script calls). A writer imports
drake-lfd first, says it is ready, and (for the concurrency rounds) waits for a start
line shared by all writers of the round, so their adds overlap instead of being spread
out by the ~1 s of start-up.

* Concurrency: each round starts ``--writers`` adds of different demonstrations at the
  same instant into one library (even rounds: a directory that does not exist yet, so
  the writers also race to create it; odd rounds: a library holding one demonstration).
  Counted per add: lost (exit 0 but not in the manifest, or a non-zero exit), orphans
  (logs or caches in the directory that the manifest does not list), corrupt (the
  library does not open with every check, or a log or feature differs from what was
  added), temporary files left.
* ``--control-rounds`` repeats the concurrency rounds with the library's lock replaced
  by a no-op in the writers, to show that the harness sees what the lock prevents.
* Kill -9: each round starts one ``library add`` (of a new demonstration) or
  ``library remove`` on a library of several demonstrations and sends SIGKILL at a
  uniformly random time within the operation's measured duration. Then the next command
  (``library show``) runs. Counted: lost (a demonstration the killed command did not
  touch that is gone, or one it touched that is neither before nor after), corrupt,
  temporary files left after the next command (and, for information, before it: the
  debris the kills made), orphan logs.

Usage: python benchmarks/stress_library.py [--rounds 100] [--writers 4] [--kills 100]
       [--control-rounds 20] [--seed 0] [--keep DIR]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = ["write_demo_logs", "inspect_library", "concurrency_rounds", "kill_rounds", "main"]

HEADER = "timestamp,actual_q_0,actual_q_1,actual_q_2,actual_q_3,actual_q_4,actual_q_5"
Q_HOME = np.array([0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0])
IDENTITY = ["--tool0-E-p", "0", "0", "0", "--tool0-E-euler-zyx", "0", "0", "0"]

# The writer process: import everything (and build the parser once, which imports every
# command's module), say "ready", wait for the start line, run the CLI. With "--serve" it
# runs one command per line of stdin instead (argv as JSON, then the start line to wait
# for), answering with a JSON line of exit code, stdout and stderr.
WRITER = r"""
import contextlib, io, json, os, sys, time
import drake_lfd.cli.library_actions, drake_lfd.io.library, drake_lfd.io.library_feature_reads
import drake_lfd.io.library_store
from drake_lfd.cli import main
from drake_lfd.cli.app import build_parser
build_parser()
if os.environ.get("STRESS_LIBRARY_NO_LOCK"):  # the control: writers do not take turns
    drake_lfd.io.library_store.exclusive_lock = lambda path: contextlib.nullcontext()
    for module in (drake_lfd.io.library, drake_lfd.io.library_feature_reads):
        module.shared_lock = lambda path: contextlib.nullcontext()

def wait(start):
    while start != "-" and not os.path.exists(start):
        time.sleep(0.0002)

if sys.argv[1] == "--serve":
    print("ready", flush=True)
    for line in sys.stdin:
        request = json.loads(line)
        out, err = io.StringIO(), io.StringIO()
        wait(request["start"])
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(request["argv"])
            except BaseException as error:
                code = 1
                print(f"{type(error).__name__}: {error}", file=sys.stderr)
        print(json.dumps({"code": code, "out": out.getvalue(), "err": err.getvalue()}), flush=True)
else:
    ready, start, argv = sys.argv[1], sys.argv[2], sys.argv[3:]
    if os.environ.get("STRESS_LIBRARY_TIMING"):  # calibration: when the writing starts
        writing = drake_lfd.io.library_store.locked_for_writing
        @contextlib.contextmanager
        def timed(*args, **kwargs):
            print(f"writing-starts {time.perf_counter() - began}", file=sys.stderr, flush=True)
            with writing(*args, **kwargs):
                yield
            print(f"writing-ends {time.perf_counter() - began}", file=sys.stderr, flush=True)
        for module in (drake_lfd.io.library, drake_lfd.io.library_store, drake_lfd.io.library_feature_reads):
            module.locked_for_writing = timed  # (every module that takes the lock to write)
    open(ready, "w").close()
    began = time.perf_counter()
    wait(start)
    sys.exit(main(argv))
"""


def write_demo_logs(directory, count, m=120, prefix="demo"):
    """``count`` different joint logs (seeded motions), name -> path."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    logs = {}
    for index in range(count):
        rng = np.random.default_rng(1000 + index)
        t = np.linspace(0.0, 2.0, m)
        s = 0.5 - 0.5 * np.cos(np.pi * t / 2.0)
        q = Q_HOME + np.outer(s, rng.uniform(-0.6, 0.6, 6))
        lines = [HEADER] + [",".join(repr(float(v)) for v in (t[k], *q[k])) for k in range(m)]
        path = directory / f"{prefix}_{index}.csv"
        path.write_text("\n".join(lines) + "\n")
        logs[f"{prefix}_{index}"] = path
    return logs


def _writer(argv, ready, start="-", control=False, timing=False):
    env = dict(os.environ)
    if control:
        env["STRESS_LIBRARY_NO_LOCK"] = "1"
    if timing:
        env["STRESS_LIBRARY_TIMING"] = "1"
    return subprocess.Popen(
        [sys.executable, "-c", WRITER, str(ready), str(start), *map(str, argv)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )


def _wait_for(path, process, timeout=60.0):
    deadline = time.monotonic() + timeout
    while not os.path.exists(path):
        if process.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f"writer did not start: {process.communicate()[1].decode()[-400:]}")
        time.sleep(0.001)


def inspect_library(root, sources):
    """What is in the library at ``root``, checked against the source logs.

    Returns a dict: ``names`` (manifest order; None if it does not open), ``orphans``
    (files in demos/ or cache/ the manifest does not list), ``temporaries``,
    ``corrupt`` (a message, or None).
    """
    from drake_lfd.io.demonstration_logs import read_rtde_csv
    from drake_lfd.io.library import Library
    from drake_lfd.io.library_store import library_temporaries

    root = Path(root)
    result = {"names": None, "orphans": [], "temporaries": [], "corrupt": None}
    if not root.exists():
        return result
    result["temporaries"] = sorted(str(p.relative_to(root)) for p in library_temporaries(root))
    try:
        library = Library.open(root)
        for name in library.names:
            stored = library.demonstration(name)
            source, _ = read_rtde_csv(sources[name])
            if not (np.array_equal(stored.timestamps, source.timestamps)
                    and np.array_equal(stored.joint_positions, source.joint_positions)):
                raise ValueError(f"{name}: the stored log differs from the one added")
            library.feature(name)
    except Exception as error:  # noqa: BLE001 - any failure is corruption here
        result["corrupt"] = f"{type(error).__name__}: {error}"
        return result
    result["names"] = list(library.names)
    listed = {entry.file for entry in library.entries}
    listed.add("cache/features.sqlite")  # the feature cache, one database for the library
    listed |= {str(p.relative_to(root)) for p in library_temporaries(root)}  # counted as temporaries
    for sub in ("demos", "cache"):
        if (root / sub).is_dir():
            for path in (root / sub).iterdir():
                relative = path.relative_to(root).as_posix()
                if relative not in listed and not path.name.endswith(".tmp"):
                    result["orphans"].append(relative)
    return result


class _Server:
    """A writer process that runs one CLI command per request (``--serve``)."""

    def __init__(self, control=False):
        env = dict(os.environ)
        if control:
            env["STRESS_LIBRARY_NO_LOCK"] = "1"
        self.process = subprocess.Popen(
            [sys.executable, "-c", WRITER, "--serve"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            env=env, text=True,
        )
        if self.process.stdout.readline().strip() != "ready":
            raise RuntimeError("writer did not start")

    def send(self, argv, start):
        self.process.stdin.write(json.dumps({"argv": [str(a) for a in argv], "start": str(start)}) + "\n")
        self.process.stdin.flush()

    def answer(self):
        answer = json.loads(self.process.stdout.readline())
        return answer["code"], answer["out"], answer["err"]

    def close(self):
        self.process.stdin.close()
        self.process.wait(timeout=60)


def concurrency_rounds(rounds, writers, workdir, *, control=False, fresh=False, progress=None):
    """``rounds`` rounds of ``writers`` concurrent ``library add``; totals.

    Each add runs in its own process: one long-lived writer process per writer, each
    add a new ``drake_lfd.cli.main`` call in it (``fresh=False``), or a new process per
    add (``fresh=True``, slower)."""
    from drake_lfd.cli import main

    workdir = Path(workdir)
    sources = write_demo_logs(workdir / "logs", writers + 1)
    seed_name = f"demo_{writers}"
    totals = {"rounds": 0, "adds": 0, "lost": 0, "orphans": 0, "corrupt": 0, "temporaries": 0,
              "failed_exits": 0, "seconds": 0.0, "examples": []}
    servers = [] if fresh else [_Server(control) for _ in range(writers)]
    started = time.perf_counter()
    try:
        for r in range(rounds):
            root = workdir / f"round{r:03d}" / "lib"
            root.parent.mkdir(parents=True)
            names = [f"demo_{i}" for i in range(writers)]
            expected = list(names)
            if r % 2 == 1:  # an existing library
                with contextlib.redirect_stdout(io.StringIO()):
                    assert main(["library", "add", str(root), str(sources[seed_name]), "--name", seed_name,
                                 *IDENTITY]) == 0
                expected.append(seed_name)
            start = root.parent / "start"
            argvs = {name: ["library", "add", str(root), str(sources[name]), "--name", name, *IDENTITY]
                     for name in names}
            exits = {}
            if fresh:
                processes = []
                for i, name in enumerate(names):
                    ready = root.parent / f"ready{i}"
                    processes.append((name, ready, _writer(argvs[name], ready, start, control=control)))
                for _, ready, process in processes:
                    _wait_for(ready, process)
                start.touch()
                for name, _, process in processes:
                    out, err = process.communicate(timeout=120)
                    exits[name] = (process.returncode, out.decode(), err.decode())
            else:
                for server, name in zip(servers, names):
                    server.send(argvs[name], start)
                time.sleep(0.01)  # every writer is waiting at the start line
                start.touch()
                for server, name in zip(servers, names):
                    exits[name] = server.answer()
            report = inspect_library(root, sources)
            totals["rounds"] += 1
            totals["adds"] += writers
            failed = [name for name, (code, out, _) in exits.items() if code != 0 or "added" not in out]
            totals["failed_exits"] += len(failed)
            present = set(report["names"] or ())
            lost = [name for name in expected if name not in present]
            totals["lost"] += len(lost)
            totals["orphans"] += len(report["orphans"])
            totals["temporaries"] += len(report["temporaries"])
            totals["corrupt"] += report["corrupt"] is not None
            if (lost or failed or report["orphans"] or report["corrupt"]) and len(totals["examples"]) < 3:
                totals["examples"].append(
                    {"round": r, "lost": lost, "failed": {n: exits[n][2].strip()[-200:] for n in failed},
                     "orphans": report["orphans"], "corrupt": report["corrupt"]}
                )
            if progress and (r + 1) % 25 == 0:
                progress(f"  {r + 1} rounds: lost {totals['lost']}, orphans {totals['orphans']}, "
                         f"corrupt {totals['corrupt']}")
            shutil.rmtree(root.parent)
    finally:
        for server in servers:
            server.close()
    totals["seconds"] = time.perf_counter() - started
    return totals


def _run_writer(argv, workdir, tag, timing=False):
    ready = Path(workdir) / f"ready-{tag}"
    process = _writer(argv, ready, timing=timing)
    _wait_for(ready, process)
    began = time.perf_counter()
    return process, began


def kill_rounds(kills, workdir, *, seed=0, calibrations=3, progress=None):
    """``kills`` rounds of ``library add``/``remove`` killed at a random moment; totals."""
    from drake_lfd.cli import main

    rng = random.Random(seed)
    workdir = Path(workdir)
    sources = write_demo_logs(workdir / "logs", 6, prefix="base")
    sources.update(write_demo_logs(workdir / "logs", 12, prefix="extra"))
    root = workdir / "lib"
    quiet = contextlib.redirect_stdout(io.StringIO())
    with quiet:
        for name in [n for n in sources if n.startswith("base")]:
            assert main(["library", "add", str(root), str(sources[name]), "--name", name, *IDENTITY]) == 0
    present = list(inspect_library(root, sources)["names"])

    # Measured unkilled, per command: when its writing (under the lock) starts and when
    # the last write ends, from "ready" (the process then still takes a while to exit).
    windows, writing_starts = {}, {}
    for tag in range(calibrations):
        for argv in (["library", "add", str(root), str(sources["extra_0"]), "--name", "extra_0"],
                     ["library", "remove", str(root), "extra_0"]):
            process, began = _run_writer(argv, workdir, f"calibrate{tag}-{argv[1]}", timing=True)
            _, err = process.communicate(timeout=120)
            marks = {}
            for line in err.decode().splitlines():
                if line.startswith(("writing-starts ", "writing-ends ")):
                    key, value = line.split()
                    marks.setdefault(key, []).append(float(value))
            windows[argv[1]] = max(windows.get(argv[1], 0.0), max(marks["writing-ends"]) + 0.002)
            writing_starts[argv[1]] = min(writing_starts.get(argv[1], math.inf), min(marks["writing-starts"]))
            os.unlink(workdir / f"ready-calibrate{tag}-{argv[1]}")

    totals = {"kills": 0, "aimed_at_writing": 0, "killed_mid_command": 0, "completed_before_kill": 0, "adds": 0, "removes": 0,
              "lost": 0, "corrupt": 0, "temporaries_before_next": 0, "rounds_with_temporaries": 0,
              "temporaries_after_next": 0, "orphans_at_end": 0, "next_command_failed": 0,
              "windows_s": windows, "writing_starts_s": writing_starts, "seconds": 0.0, "examples": []}
    started = time.perf_counter()
    for k in range(kills):
        absent = [n for n in sources if n not in present]
        if absent and (len(present) <= 3 or rng.random() < 0.5):
            name = rng.choice(absent)
            argv = ["library", "add", str(root), str(sources[name]), "--name", name]
            totals["adds"] += 1
        else:
            name = rng.choice(present)
            argv = ["library", "remove", str(root), name]
            totals["removes"] += 1
        process, began = _run_writer(argv, workdir, f"kill{k}")
        # Half the kills anywhere from the command's start to its last write, half while
        # it writes (the lock held).
        aimed = k % 2 == 1
        totals["aimed_at_writing"] += aimed
        command = argv[1]
        moment = rng.uniform(max(0.0, writing_starts[command] - 0.002) if aimed else 0.0, windows[command])
        time.sleep(max(0.0, began + moment - time.perf_counter()))
        completed = process.poll() is not None
        if not completed:
            process.kill()  # SIGKILL, this writer only
        process.communicate(timeout=60)
        os.unlink(workdir / f"ready-kill{k}")
        totals["kills"] += 1
        totals["completed_before_kill" if completed else "killed_mid_command"] += 1

        debris = inspect_library(root, sources)["temporaries"]
        totals["temporaries_before_next"] += len(debris)
        totals["rounds_with_temporaries"] += bool(debris)
        with quiet:  # the next command
            code = main(["library", "show", str(root), "--json", str(workdir / "show.json")])
        totals["next_command_failed"] += code != 0
        report = inspect_library(root, sources)
        totals["temporaries_after_next"] += len(report["temporaries"])
        totals["orphans_at_end"] = len(report["orphans"])
        if report["corrupt"] is not None:
            totals["corrupt"] += 1
            totals["examples"].append({"kill": k, "argv": argv, "corrupt": report["corrupt"]})
            break
        after = report["names"]
        untouched_before = [n for n in present if n != name]
        untouched_after = [n for n in after if n != name]
        lost = [n for n in untouched_before if n not in untouched_after]
        extra = [n for n in untouched_after if n not in untouched_before]
        if completed and code == 0 and ((argv[1] == "add") != (name in after)):
            lost.append(name)  # the command finished, so its change must be there
        totals["lost"] += len(lost) + len(extra)
        if (lost or extra) and len(totals["examples"]) < 3:
            totals["examples"].append({"kill": k, "argv": argv, "lost": lost, "extra": extra})
        present = after
        if progress and (k + 1) % 10 == 0:
            progress(f"  {k + 1} kills: lost {totals['lost']}, corrupt {totals['corrupt']}, "
                     f"temporaries after the next command {totals['temporaries_after_next']}")
    totals["seconds"] = time.perf_counter() - started
    return totals


def _print_totals(title, totals, keys):
    print(title)
    for key in keys:
        value = totals[key]
        print(f"  {key}: {value:.3f}" if isinstance(value, float) else f"  {key}: {value}")
    for example in totals["examples"]:
        print(f"  example: {example}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=100, help="concurrency rounds")
    parser.add_argument("--writers", type=int, default=4, help="concurrent adds per round")
    parser.add_argument("--control-rounds", type=int, default=20,
                        help="concurrency rounds with the lock disabled in the writers (0: none)")
    parser.add_argument("--fresh-processes", action="store_true",
                        help="a new process for every concurrent add (default: one writer process per writer)")
    parser.add_argument("--kills", type=int, default=100, help="kill -9 rounds")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--keep", metavar="DIR", help="work in DIR and keep it (default: a temporary folder)")
    args = parser.parse_args(argv)
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="stress_library."))
    work.mkdir(parents=True, exist_ok=True)
    echo = lambda text: print(text, flush=True)  # noqa: E731
    try:
        keys = ("rounds", "adds", "failed_exits", "lost", "orphans", "corrupt", "temporaries", "seconds")
        if args.rounds:
            totals = concurrency_rounds(args.rounds, args.writers, work / "concurrent", fresh=args.fresh_processes,
                                        progress=echo)
            _print_totals(f"{args.rounds} rounds of {args.writers} concurrent 'library add' (lock on):", totals, keys)
        if args.control_rounds:
            totals = concurrency_rounds(args.control_rounds, args.writers, work / "control", control=True,
                                        fresh=args.fresh_processes)
            _print_totals(f"control, {args.control_rounds} rounds with the lock disabled:", totals, keys)
        if args.kills:
            totals = kill_rounds(args.kills, work / "kills", seed=args.seed, progress=echo)
            _print_totals(
                f"{args.kills} kill -9 during 'library add'/'remove', at a random moment from the command's "
                f"start to its last write (add {1000 * totals['windows_s']['add']:.0f} ms, remove "
                f"{1000 * totals['windows_s']['remove']:.0f} ms), every other one while it writes (add from "
                f"{1000 * totals['writing_starts_s']['add']:.0f} ms, remove from "
                f"{1000 * totals['writing_starts_s']['remove']:.0f} ms):",
                totals,
                ("kills", "adds", "removes", "aimed_at_writing", "killed_mid_command", "completed_before_kill", "lost", "corrupt",
                 "rounds_with_temporaries", "temporaries_before_next", "temporaries_after_next",
                 "next_command_failed", "orphans_at_end", "seconds"),
            )
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
