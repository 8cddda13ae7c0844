"""Fuzzed task files and joint logs through the real command line: no traceback, no hang.

The cases are the seeded mutations of ``tests/fuzzing.py`` (task files
for ``drake-lfd plan TASK --library paper5 --json OUT``, joint logs for ``drake-lfd
library add LIB LOG --name NAME`` into a fresh copy of ``paper5`` or a new library
directory). They run in ``--workers`` long-lived worker processes, each calling
``drake_lfd.cli.main(argv)`` in-process (what the ``drake-lfd`` script calls, without
its ~1 s start-up per case), with stdout and stderr captured, Python's and the native
file descriptors both. The parent is the watchdog: a case that takes longer than
``--timeout`` seconds (default 60) is a hang, its worker is killed and replaced; a
worker whose resident memory passes ``--memory-limit-mb`` (default 2048, sampled every
50 ms from /proc) is killed and the case counted over the limit. Peak memory is each
worker's own ``ru_maxrss`` (reported by the worker after every case; ``wait4`` of a
killed one), so it is the largest any single case reached in a process that also holds
drake-lfd and Drake.

Judged per case:

- traceback: ``Traceback`` in the output, or an exception escaping ``main``;
- exit code: not in {0, 2, 3, 4};
- a refusal (exit 2) that is not exactly one stderr line, or does not name the file
  (the task file; for a log, the log or the library, or the option for a fuzzed
  ``--name``), or, where the mutation knows the field it changed, does not name it
  (a refusal by the YAML reader names the line and column instead);
- NaN or Infinity in any JSON written (``plan --json``; after an accepted log,
  ``library show LIB --json``);
- a library that is not byte-identical after a refused ``library add`` (a new library
  directory must not exist after a refused add to it); an accepted log must leave a
  library that ``library show`` opens.

Prints the counts per problem, the slowest cases, peak memory and the exit codes per
mutation class; ``--json`` writes the report, ``--keep DIR`` keeps every failing case's
input. Exits 1 if any problem was found.

Usage: python benchmarks/fuzz_inputs.py [--tasks 2000] [--logs 500] [--seed 0]
       [--workers 2] [--timeout 60] [--json REPORT.json] [--keep DIR]
"""

from __future__ import annotations

import argparse
import collections
import hashlib
import json
import os
import queue
import re
import select
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

# The generators are test tooling: they live beside their seeded sample in tests/.
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from fuzzing import FuzzCase, log_cases, non_finite_json_tokens, task_cases  # noqa: E402

__all__ = ["Worker", "library_snapshot", "judge", "run_cases", "main"]

IDENTITY = ["--tool0-E-p", "0", "0", "0", "--tool0-E-euler-zyx", "0", "0", "0"]
EXPECTED_CODES = (0, 2, 3, 4)
PROGRESS_PREFIXES = ("trials [", "training [")

# The worker: imports drake-lfd once, then runs one command per line of stdin (argv as
# JSON), answering on a private copy of fd 1 with exit code, stdout, stderr (Python's
# and the native fd 2), seconds and its peak memory. fd 1 and fd 2 point elsewhere
# while a command runs, so nothing a command prints can break the protocol.
WORKER = r"""
import contextlib, io, json, os, resource, sys, tempfile, time, traceback
answer = os.fdopen(os.dup(1), "w")
devnull = os.open(os.devnull, os.O_WRONLY)
os.dup2(devnull, 1)
from drake_lfd.cli import main
from drake_lfd.cli.app import build_parser
build_parser()
import drake_lfd.cli.library_actions, drake_lfd.experiments.planning_api, drake_lfd.io.task_files  # what the commands load
answer.write("ready\n"); answer.flush()
for line in sys.stdin:
    request = json.loads(line)
    out, err = io.StringIO(), io.StringIO()
    escaped = None
    start = time.perf_counter()
    with tempfile.TemporaryFile() as native:
        saved = os.dup(2)
        os.dup2(native.fileno(), 2)
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                try:
                    code = main(request["argv"])
                except SystemExit as error:
                    code = error.code if isinstance(error.code, int) else 2
                except BaseException:
                    code = None
                    escaped = traceback.format_exc()
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
        native.seek(0)
        native_err = native.read().decode("utf-8", "replace")
    seconds = time.perf_counter() - start
    answer.write(json.dumps({"code": code, "out": out.getvalue(), "err": err.getvalue() + native_err,
                             "escaped": escaped, "seconds": seconds,
                             "maxrss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}) + "\n")
    answer.flush()
"""


def _rss_bytes(pid):
    try:
        with open(f"/proc/{pid}/status") as status:
            for line in status:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


class Worker:
    """One long-lived worker process running ``drake_lfd.cli.main`` per request."""

    def __init__(self, cwd, memory_limit):
        self.cwd = cwd
        self.memory_limit = memory_limit
        self.peak_rss = 0
        self.process = None
        self._start()

    def _start(self):
        self.stderr = tempfile.TemporaryFile()
        self.process = subprocess.Popen([sys.executable, "-c", WORKER], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, stderr=self.stderr, cwd=self.cwd)
        line = self.process.stdout.readline()
        if line.strip() != b"ready":
            self.stderr.seek(0)
            raise RuntimeError(f"worker did not start: {self.stderr.read().decode(errors='replace')[-2000:]}")

    def _kill(self):
        self.process.kill()
        _, _, usage = os.wait4(self.process.pid, 0)
        self.peak_rss = max(self.peak_rss, usage.ru_maxrss * 1024)
        self.process.stdout.close()
        self.process.stdin.close()

    def run(self, argv, timeout):
        """Runs one command. Returns the worker's answer (a dict), with ``hang`` or
        ``memory`` set when the watchdog killed it."""
        self.process.stdin.write((json.dumps({"argv": [str(a) for a in argv]}) + "\n").encode())
        self.process.stdin.flush()
        start = time.perf_counter()
        sampled = 0
        while True:
            ready, _, _ = select.select([self.process.stdout], [], [], 0.05)
            if ready:
                line = self.process.stdout.readline()
                if not line:  # the worker died
                    self._kill()
                    self._start()
                    return {"code": None, "out": "", "err": "", "escaped": "the worker process died",
                            "seconds": time.perf_counter() - start, "maxrss": 0}
                answer = json.loads(line)
                self.peak_rss = max(self.peak_rss, answer["maxrss"], sampled)
                return answer
            sampled = max(sampled, _rss_bytes(self.process.pid))
            elapsed = time.perf_counter() - start
            over_memory = sampled > self.memory_limit
            if elapsed > timeout or over_memory:
                self._kill()
                self._start()
                return {"code": None, "out": "", "err": "", "escaped": None, "seconds": elapsed,
                        "maxrss": sampled, "hang": elapsed > timeout, "memory": over_memory}

    def close(self):
        if self.process and self.process.poll() is None:
            self.process.stdin.close()
            try:
                _, _, usage = os.wait4(self.process.pid, 0)
                self.peak_rss = max(self.peak_rss, usage.ru_maxrss * 1024)
            except ChildProcessError:
                pass


def library_snapshot(directory):
    """Every file and folder under ``directory``: relative path -> SHA-256 of the bytes
    (``"dir"`` for a folder); None if it does not exist."""
    directory = Path(directory)
    if not directory.exists():
        return None
    snapshot = {}
    for path in sorted(directory.rglob("*")):
        relative = str(path.relative_to(directory))
        snapshot[relative] = "dir" if path.is_dir() else hashlib.sha256(path.read_bytes()).hexdigest()
    return snapshot


def _lines(text):
    return [line for line in text.splitlines() if line.strip() and not line.lstrip("\r").startswith(PROGRESS_PREFIXES)]


# Where the YAML reader refuses a file, the field is its place: "line 4 column 7".
_YAML_PLACE = re.compile(r": line \d+ column \d+: ")


def _names_field(line, field):
    """Whether a refusal names ``field`` (``a|b``: either), or the line and column."""
    return any(name in line for name in field.split("|")) or bool(_YAML_PLACE.search(line))


def judge(case: FuzzCase, answer, *, names, field=None):
    """The problems of one finished command: a list of ``(kind, detail)``.

    ``names`` are the strings of which a refusal must contain one (the file's path, or
    the library's); ``field`` a word it must contain too (None: not checked)."""
    problems = []
    if answer.get("hang"):
        return [("hang", f"still running after {answer['seconds']:.0f} s")]
    if answer.get("memory"):
        return [("memory", f"resident memory {answer['maxrss'] / 2**20:.0f} MB")]
    text = answer["err"] + answer["out"]
    if answer.get("escaped") or "Traceback" in text:
        problems.append(("traceback", (answer.get("escaped") or text)[-1500:]))
    code = answer["code"]
    if code not in EXPECTED_CODES:
        problems.append(("exit_code", f"exit {code}: {answer['err'][-500:]}"))
    if code == 2:
        lines = _lines(answer["err"])
        if len(lines) != 1:
            problems.append(("not_one_line", f"{len(lines)} lines: {lines[:5]}"))
        elif not any(name in lines[0] for name in names):
            problems.append(("file_not_named", lines[0][:500]))
        elif field is not None and not _names_field(lines[0], field):
            problems.append(("field_not_named", f"expected {field!r}: {lines[0][:500]}"))
    return problems


def _json_problems(path):
    if not Path(path).exists():
        return []
    text = Path(path).read_text(encoding="utf-8", errors="replace")
    tokens = non_finite_json_tokens(text)
    if tokens < 0:
        return [("invalid_json", str(path))]
    if tokens:
        return [("nan_json", f"{tokens} NaN/Infinity tokens in {path}")]
    return []


def _run_task(worker, case, directory, timeout):
    task = directory / f"task_{case.index}.yaml"
    task.write_bytes(case.data)
    output = directory / f"plan_{case.index}.json"
    answer = worker.run(["plan", task, "--library", "paper5", "--json", output], timeout)
    problems = judge(case, answer, names=[str(task)], field=case.field)
    if answer["code"] in (0, 3, 4) and not output.exists():
        problems.append(("json_missing", f"exit {answer['code']} without {output}"))
    problems += _json_problems(output)
    task.unlink()
    output.unlink(missing_ok=True)
    return answer, problems


def _run_log(worker, case, directory, template, timeout):
    log = directory / f"log_{case.index}.csv"
    log.write_bytes(case.data)
    if case.new_library:
        library = directory / f"new_{case.index}"
        argv = ["library", "add", library, log, "--name", case.name, *IDENTITY]
    else:
        library = directory / f"lib_{case.index}"
        shutil.copytree(template, library)
        argv = ["library", "add", library, log, "--name", case.name]
    before = library_snapshot(library)
    answer = worker.run(argv, timeout)
    names = [str(log), str(library), str(library.resolve())]
    if "+name" in case.mutation:
        names.append("name")
    problems = judge(case, answer, names=names)
    if answer["code"] not in (None, 0) and library_snapshot(library) != before:
        problems.append(("library_changed", f"exit {answer['code']} but {library} changed"))
    if answer["code"] == 0:
        listing = directory / f"show_{case.index}.json"
        shown = worker.run(["library", "show", library, "--json", listing], timeout)
        if shown["code"] != 0:
            problems.append(("library_broken", f"library show after the add: exit {shown['code']}: {shown['err'][-500:]}"))
        problems += [(kind, detail) for kind, detail in judge(case, shown, names=[str(library)]) if kind != "not_one_line"]
        problems += _json_problems(listing)
        listing.unlink(missing_ok=True)
    shutil.rmtree(library, ignore_errors=True)
    log.unlink()
    return answer, problems


def run_cases(cases, *, workers=2, timeout=60.0, memory_limit_mb=2048, keep=None, progress=None):
    """Runs every case (task files and logs, mixed) in ``workers`` worker processes.

    Returns a report dict: ``cases``, ``by_kind``, ``problems`` (kind -> list of
    ``{case, mutation, detail}``), ``peak_memory_bytes``, ``slowest`` (seconds, case),
    ``codes`` (kind/mutation -> exit code -> count), ``wall_time_s``.
    """
    cases = list(cases)
    jobs = queue.Queue()
    for case in cases:
        jobs.put(case)
    results = []
    lock = threading.Lock()
    root = Path(tempfile.mkdtemp(prefix="drake-lfd-fuzz-"))
    template = root / "paper5"
    started = time.perf_counter()
    try:
        from drake_lfd.io.library import copy_library  # the template library, once

        copy_library("paper5", template)
        pool = []
        errors = []

        def serve(number):
            directory = root / f"worker_{number}"
            directory.mkdir()
            try:
                worker = Worker(directory, memory_limit_mb * 2**20)
            except Exception as error:  # noqa: BLE001 - reported below
                errors.append(error)
                return
            pool.append(worker)
            while True:
                try:
                    case = jobs.get_nowait()
                except queue.Empty:
                    break
                if case.kind == "task":
                    answer, problems = _run_task(worker, case, directory, timeout)
                else:
                    answer, problems = _run_log(worker, case, directory, template, timeout)
                with lock:
                    results.append((case, answer, problems))
                    if problems and keep is not None:
                        Path(keep).mkdir(parents=True, exist_ok=True)
                        suffix = "yaml" if case.kind == "task" else "csv"
                        (Path(keep) / f"{case.kind}_{case.index}.{suffix}").write_bytes(case.data)
                    if progress:
                        progress(len(results), len(cases))
            worker.close()

        threads = [threading.Thread(target=serve, args=(n,)) for n in range(workers)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        if errors:
            raise errors[0]
        peak = max([worker.peak_rss for worker in pool] or [0])
    finally:
        shutil.rmtree(root, ignore_errors=True)
    problems = collections.defaultdict(list)
    codes = collections.defaultdict(collections.Counter)
    for case, answer, found in results:
        codes[f"{case.kind}/{case.mutation.split('+')[0]}"][str(answer["code"])] += 1
        for kind, detail in found:
            problems[kind].append({"case": f"{case.kind}_{case.index}", "mutation": case.mutation, "detail": detail})
    slowest = sorted(((answer["seconds"], f"{case.kind}_{case.index} ({case.mutation})")
                      for case, answer, _ in results), reverse=True)[:5]
    return {
        "cases": len(results),
        "by_kind": dict(collections.Counter(case.kind for case, _, _ in results)),
        "problems": dict(problems),
        "peak_memory_bytes": peak,
        "slowest": slowest,
        "codes": {key: dict(value) for key, value in sorted(codes.items())},
        "wall_time_s": time.perf_counter() - started,
    }


def _print_report(report, timeout):
    print(f"cases: {report['cases']} ({', '.join(f'{n} {k}' for k, n in report['by_kind'].items())}), "
          f"{report['wall_time_s']:.0f} s wall")
    counts = {kind: len(report["problems"].get(kind, ())) for kind in (
        "traceback", "exit_code", "hang", "memory", "nan_json", "invalid_json", "not_one_line", "file_not_named",
        "field_not_named", "library_changed", "library_broken", "json_missing")}
    print(f"tracebacks: {counts['traceback']}")
    print(f"exit codes outside 0/2/3/4: {counts['exit_code']}")
    print(f"hangs past {timeout:g} s: {counts['hang']}")
    print(f"peak memory (largest worker process): {report['peak_memory_bytes'] / 2**20:.0f} MB"
          f"{'' if report['peak_memory_bytes'] < 2**30 else '  OVER 1 GB'}; killed over the limit: {counts['memory']}")
    print(f"NaN/Infinity in JSON: {counts['nan_json']} (invalid JSON: {counts['invalid_json']})")
    print(f"refusals not one line: {counts['not_one_line']}; not naming the file: {counts['file_not_named']}; "
          f"not naming the field: {counts['field_not_named']}")
    print(f"library changed by a refused add: {counts['library_changed']}; "
          f"broken after an accepted one: {counts['library_broken']}; plan JSON missing: {counts['json_missing']}")
    print("slowest: " + "; ".join(f"{seconds:.2f} s {name}" for seconds, name in report["slowest"]))
    print("exit codes per mutation class:")
    for key, value in report["codes"].items():
        print(f"  {key:<32} " + " ".join(f"{code}:{count}" for code, count in sorted(value.items())))
    for kind, items in report["problems"].items():
        print(f"-- {kind} ({len(items)}), first ones:")
        for item in items[:5]:
            print(f"   {item['case']} [{item['mutation']}]: {item['detail'][:600]}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tasks", type=int, default=2000, help="fuzzed task files")
    parser.add_argument("--logs", type=int, default=500, help="fuzzed joint logs")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds after which a case is a hang")
    parser.add_argument("--memory-limit-mb", type=int, default=2048, help="resident memory at which a worker is killed")
    parser.add_argument("--json", help="write the report here")
    parser.add_argument("--keep", help="keep the inputs of failing cases in this directory")
    args = parser.parse_args(argv)
    cases = list(task_cases(args.tasks, args.seed)) + list(log_cases(args.logs, args.seed))
    # Interleave, so both kinds run from the start and a slow class does not bunch up.
    cases.sort(key=lambda case: (case.index / (args.tasks if case.kind == "task" else max(args.logs, 1))))

    def progress(done, total):
        if done % 100 == 0 or done == total:
            print(f"  {done}/{total}", file=sys.stderr, flush=True)

    report = run_cases(cases, workers=args.workers, timeout=args.timeout, memory_limit_mb=args.memory_limit_mb,
                       keep=args.keep, progress=progress)
    _print_report(report, args.timeout)
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1) + "\n")
    bad = {kind for kind in report["problems"]} | ({"memory"} if report["peak_memory_bytes"] >= 2**30 else set())
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
