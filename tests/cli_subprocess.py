"""Running ``drake-lfd`` in a subprocess for the error-path tests: the same package as
the tests import, its exit status, stdout and stderr, and its peak memory."""

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import drake_lfd
from helpers import wait_until

__all__ = ["cli_command", "cli_env", "run_cli", "stderr_lines", "unwritable_folder"]


def cli_env(extra=None):
    """The environment of a ``drake-lfd`` subprocess that imports this checkout."""
    env = dict(os.environ)
    package_parent = str(Path(drake_lfd.__file__).resolve().parent.parent)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (package_parent, env.get("PYTHONPATH")) if p)
    env.update(extra or {})
    return env


def cli_command(*args):
    return [sys.executable, "-m", "drake_lfd", *map(str, args)]


# Runs ``python -m drake_lfd ARGS`` and, at exit, writes the process's own peak resident
# memory (VmHWM of its address space) to the file named by the environment. The child's
# ``ru_maxrss`` (``wait4``) is no measure of it: Linux carries the parent's peak over
# ``fork``/``vfork`` and ``exec`` into it, so a large test process would be charged.
_PEAK_WRAPPER = """
import atexit, os, runpy, sys
def _report(path=os.environ.pop("DRAKE_LFD_TEST_PEAK_FILE")):
    with open("/proc/self/status") as status:
        peak = [line.split()[1] for line in status if line.startswith("VmHWM:")]
    with open(path, "w") as out:
        out.write(peak[0] if peak else "")
atexit.register(_report)
sys.argv = ["drake-lfd", *sys.argv[1:]]
runpy.run_module("drake_lfd", run_name="__main__", alter_sys=True)
"""


def run_cli(*args, env=None, timeout=90, cwd=None):
    """Runs ``drake-lfd ARGS``; returns ``(status, stdout, stderr, seconds, peak_rss_bytes)``,
    the peak resident memory being that child's own (its VmHWM where ``/proc`` exists, else
    ``wait4``'s, which may include the test process's)."""
    start = time.perf_counter()
    measured = Path("/proc/self/status").is_file()
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err, \
            tempfile.NamedTemporaryFile("r", suffix=".peak") as peak_file:
        command = ([sys.executable, "-c", _PEAK_WRAPPER, *map(str, args)] if measured else cli_command(*args))
        extra = dict(env or {}, DRAKE_LFD_TEST_PEAK_FILE=peak_file.name) if measured else env
        process = subprocess.Popen(command, stdout=out, stderr=err, text=True, env=cli_env(extra), cwd=cwd)
        ended = []  # (status, usage) once reaped

        def reaped():
            if not ended:
                pid, status, usage = os.wait4(process.pid, os.WNOHANG)
                if pid:
                    ended.append((status, usage))
            return bool(ended)

        if not wait_until(reaped, timeout_s=timeout):
            process.kill()
            os.wait4(process.pid, 0)
            raise subprocess.TimeoutExpired(process.args, timeout)
        status, usage = ended[0]
        process.returncode = os.waitstatus_to_exitcode(status)
        seconds = time.perf_counter() - start
        out.seek(0)
        err.seek(0)
        peak_kb = peak_file.read().strip() if measured else ""
        peak = int(peak_kb) * 1024 if peak_kb else usage.ru_maxrss * 1024
        return process.returncode, out.read(), err.read(), seconds, peak


def stderr_lines(err):
    """stderr's lines without the progress bar's."""
    return [line for line in err.splitlines() if line.strip() and not line.lstrip("\r").startswith(
        ("trials [", "training ["))]


def unwritable_folder(tmp_path):
    """A folder in which no file can be created, also for root: a read-only folder
    where permissions hold, else ``/proc``."""
    folder = tmp_path / "read_only"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        probe = folder / "probe"
        probe.write_text("x")
    except OSError:
        return folder
    probe.unlink()
    folder.chmod(0o700)
    return Path("/proc")
