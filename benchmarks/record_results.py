"""Records a benchmark's printed figures in benchmarks/RESULTS.md, with the machine, the date and the commit.

Figures belong to the machine and the code that measured them, so no figure is written
anywhere else (not in the README, not in docstrings): this script is the one writer of
``benchmarks/RESULTS.md``. It runs a benchmark (or takes the printed output of a run
just made) and adds one entry at the top of the file's "Runs": the command, the date
(UTC), the commit (and whether the checkout had uncommitted changes), the machine (CPU,
cores, memory, load average when the run started, Python, Drake and numpy versions),
the exit status and everything the benchmark printed, as printed.

Usage::

    python benchmarks/record_results.py bench_similarity.py
    python benchmarks/record_results.py bench_pipeline.py --trials 10
    python benchmarks/bench_sweep.py | tee out.txt
    python benchmarks/record_results.py --output out.txt bench_sweep.py

The benchmark is named by its file in ``benchmarks/``; the words after it are its
arguments. With ``--output FILE`` (``-``: stdin) nothing is run: FILE is recorded as
that command's output, with this checkout's commit and this machine, so record it on
the machine and the checkout that ran it. ``--results PATH`` writes elsewhere (a trial
run of this script). The entry is added even when the benchmark fails (its exit status
says so); this script then exits with the benchmark's status.
"""

from __future__ import annotations

import argparse
import datetime
import importlib.metadata
import os
import platform
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
RESULTS = HERE / "RESULTS.md"
#: New entries go right below this line, newest first.
MARKER = "<!-- benchmarks/record_results.py adds each run below this line, newest first -->"

__all__ = ["machine_description", "commit_description", "entry_text", "add_entry", "main"]


def _first_line_with(path: str, key: str) -> str | None:
    try:
        with open(path, encoding="utf-8") as file:
            for line in file:
                if line.startswith(key):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return None


def _version(distribution: str) -> str:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def machine_description() -> str:
    """One line: the CPU, cores, memory, the load average now, OS, Python, Drake, numpy."""
    cpu = _first_line_with("/proc/cpuinfo", "model name") or platform.processor() or platform.machine()
    memory = _first_line_with("/proc/meminfo", "MemTotal")
    try:
        load = "load average {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())
    except OSError:
        load = "load average unknown"
    parts = [cpu, f"{os.cpu_count()} cores"]
    if memory:
        parts.append(f"{int(memory.split()[0]) / 2**20:.1f} GiB")
    parts += [load, platform.platform(), f"Python {platform.python_version()}",
              f"drake {_version('drake')}", f"numpy {_version('numpy')}"]
    return ", ".join(parts)


def commit_description() -> str:
    """The checked-out commit (short hash, its date), and whether files were changed."""
    def git(*args):
        return subprocess.run(["git", *args], cwd=REPOSITORY, capture_output=True, text=True,
                              check=True, timeout=60).stdout.strip()

    try:
        commit = git("log", "-1", "--format=%h (%cs)")
        changed = git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.CalledProcessError, subprocess.TimeoutExpired):
        return "unknown (not a git checkout)"
    return commit + (", with uncommitted changes" if changed else "")


def entry_text(command: str, output: str, *, status: int | None, date: str, commit: str, machine: str) -> str:
    """One RESULTS.md entry (Markdown); ``status`` None: the output of a run made before."""
    fence = "```"
    while fence in output:
        fence += "`"
    return (f"### `{command}`\n\n"
            f"- date: {date}\n- commit: {commit}\n- machine: {machine}\n"
            f"- exit status: {'not recorded (output of an earlier run)' if status is None else status}\n\n"
            f"{fence}text\n{output.rstrip()}\n{fence}\n\n")


def add_entry(results: Path, entry: str) -> None:
    """Puts ``entry`` right below the marker line of ``results`` (written whole, atomically)."""
    text = results.read_text(encoding="utf-8")
    if MARKER not in text:
        raise SystemExit(f"{results}: the line {MARKER!r} is missing; entries go below it")
    text = text.replace(MARKER + "\n", MARKER + "\n\n" + entry, 1).replace("\n\n\n", "\n\n")
    temporary = results.with_name(f".{results.name}.tmp")
    temporary.write_text(text, encoding="utf-8")
    os.replace(temporary, results)


def _run(script: Path, arguments: list[str]) -> tuple[int, str]:
    """Runs the benchmark, its output shown as it comes and kept (stderr merged)."""
    process = subprocess.Popen([sys.executable, str(script), *arguments], cwd=REPOSITORY,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
    lines = []
    for line in process.stdout:
        sys.stdout.write(line)
        lines.append(line)
    return process.wait(), "".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", type=Path, default=RESULTS, help="the file to add to (default: %(default)s)")
    parser.add_argument("--output", metavar="FILE",
                        help="record FILE ('-': stdin) as the benchmark's printed output instead of running it")
    parser.add_argument("benchmark", help="the benchmark's file in benchmarks/ (bench_similarity.py)")
    parser.add_argument("arguments", nargs=argparse.REMAINDER, help="the benchmark's arguments")
    args = parser.parse_args(argv)
    script = HERE / Path(args.benchmark).name
    if not script.is_file():
        parser.error(f"no benchmark {script}")
    command = " ".join(["python", f"benchmarks/{script.name}", *args.arguments])
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    machine, commit = machine_description(), commit_description()  # before the run: its load, its code
    if args.output is None:
        status, output = _run(script, args.arguments)
    else:
        status = None
        output = sys.stdin.read() if args.output == "-" else Path(args.output).read_text(encoding="utf-8")
    add_entry(args.results, entry_text(command, output, status=status, date=date, commit=commit, machine=machine))
    print(f"recorded in {args.results}", file=sys.stderr)
    return status or 0


if __name__ == "__main__":
    sys.exit(main())
