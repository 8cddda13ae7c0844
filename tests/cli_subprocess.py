"""Running ``drake-lfd`` in a subprocess for the error-path tests: the same package as
the tests import, its exit status, stdout and stderr, and its peak memory."""

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import drake_lfd

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


def run_cli(*args, env=None, timeout=90, cwd=None):
    """Runs ``drake-lfd ARGS``; returns ``(status, stdout, stderr, seconds, peak_rss_bytes)``,
    the peak resident memory being that child's own (``wait4``)."""
    start = time.perf_counter()
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        process = subprocess.Popen(cli_command(*args), stdout=out, stderr=err, text=True, env=cli_env(env), cwd=cwd)
        while True:
            pid, status, usage = os.wait4(process.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() - start > timeout:
                process.kill()
                os.wait4(process.pid, 0)
                raise subprocess.TimeoutExpired(process.args, timeout)
            time.sleep(0.02)
        process.returncode = os.waitstatus_to_exitcode(status)
        seconds = time.perf_counter() - start
        out.seek(0)
        err.seek(0)
        return process.returncode, out.read(), err.read(), seconds, usage.ru_maxrss * 1024


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
