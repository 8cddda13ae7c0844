"""The last reliability leftovers: long demonstration names, strict JSON everywhere,
``library show`` into a closed pipe, and ``library copy`` under the source's lock.

A ``--name`` too long for a file name is refused before anything is created; every JSON
drake-lfd writes is strict (``atomic_write_json``, ``library show --json``, the
manifest); ``library show --json`` is atomic, and a device or pipe (``/dev/stdout``) is
written into rather than replaced; a real shell pipe whose reader has gone ends the
command quietly; ``library copy`` waits for a writer of the source to finish.
"""

import json
import math
import os
import subprocess
import sys
import threading
import time

import pytest

from cli_subprocess import cli_command, cli_env
from drake_lfd.cli import main
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.io.atomic_files import atomic_write_bytes, atomic_write_json
from drake_lfd.io.library import Library, copy_library
from drake_lfd.io.library_manifest import MAX_NAME_LENGTH, Manifest, DemoEntry, manifest_text

SIMS = scenarios_directory()
IDENTITY = ["--tool0-E-p", "0", "0", "0", "--tool0-E-euler-zyx", "0", "0", "0"]


def snapshot(directory):
    return {str(p.relative_to(directory)): (p.read_bytes() if p.is_file() else None)
            for p in sorted(directory.rglob("*"))}


def strict_loads(text):
    def refuse(token):
        raise ValueError(f"non-strict JSON token {token}")
    return json.loads(text, parse_constant=refuse)


# -------------------------------------------------------------------- long --name

def test_a_long_name_is_refused_before_a_new_library_is_created(tmp_path, capsys):
    target = tmp_path / "new_library"
    status = main(["library", "add", str(target), str(SIMS / "demos" / "span.csv"), "--name", "a" * 240, *IDENTITY])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1
    assert "--name" in err[0] and "too long" in err[0] and str(target) in err[0]
    assert not target.exists()


def test_a_long_name_leaves_an_existing_library_byte_identical(tmp_path, capsys):
    library = copy_library("paper5", tmp_path / "lib").path
    before = snapshot(library)
    for name in ("b" * (MAX_NAME_LENGTH + 1), "c" * 300):
        assert main(["library", "add", str(library), str(SIMS / "demos" / "span.csv"), "--name", name]) == 2
    assert snapshot(library) == before
    assert main(["library", "add", str(library), str(SIMS / "demos" / "span.csv"), "--name", "d" * MAX_NAME_LENGTH]) == 0


# -------------------------------------------------------------------- strict JSON

def test_atomic_write_json_writes_non_finite_numbers_as_null(tmp_path):
    path = tmp_path / "a.json"
    atomic_write_json(path, {"a": math.nan, "b": [math.inf, -math.inf, 1.5]})
    assert strict_loads(path.read_text()) == {"a": None, "b": [None, None, 1.5]}


def test_a_manifest_never_holds_a_non_finite_number():
    entry = DemoEntry(name="x", file="demos/x.csv", samples=3, duration_s=math.nan, description="", added="now")
    manifest = Manifest(X_tool0_E_json={"p": [0, 0, 0], "q_wxyz": [1, 0, 0, 0]}, entries=(entry,))
    with pytest.raises(ValueError):
        manifest_text(manifest)


def test_library_show_json_is_strict_and_atomic(tmp_path, capsys):
    library = copy_library("paper5", tmp_path / "lib").path
    out = tmp_path / "out" / "show.json"
    assert main(["library", "show", str(library), "--json", str(out)]) == 0
    listing = strict_loads(out.read_text())
    assert tuple(demo["name"] for demo in listing["demos"]) == tuple(Library.open(library).names)
    assert sorted(p.name for p in out.parent.iterdir()) == ["show.json"]  # no temporary file left
    capsys.readouterr()
    assert main(["library", "show", "paper5", "--json", "-"]) == 0
    assert strict_loads(capsys.readouterr().out)["library"] == "paper5"


def test_a_pipe_is_written_into_not_replaced(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    received = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_bytes()))
    reader.start()
    atomic_write_bytes(fifo, b"through the pipe\n")
    reader.join(timeout=10)
    assert received == [b"through the pipe\n"]
    assert fifo.is_fifo()  # still the pipe, not a regular file renamed over it


def test_library_show_json_to_dev_stdout_through_a_shell_pipe():
    command = " ".join(map(str, cli_command("library", "show", "paper5", "--json", "/dev/stdout")))
    process = subprocess.run(["sh", "-c", f"{command} | head -c 100"], capture_output=True, text=True,
                             env=cli_env(), timeout=90)
    assert process.returncode == 0 and process.stdout.startswith("{") and process.stderr == ""
    assert os.path.islink("/dev/stdout") or not os.path.isfile("/dev/stdout")


# -------------------------------------------------------------------- broken pipes

@pytest.mark.parametrize("args", [("library", "show", "paper5"), ("library", "show", "paper5", "--json", "-"),
                                  ("library", "show", "paper5", "--json", "/dev/stdout")],
                         ids=["table", "json-stdout", "dev-stdout"])
def test_a_shell_pipe_whose_reader_has_gone_ends_quietly(args):
    # `true` exits before reading, so the command writes into a closed pipe (EPIPE).
    command = " ".join(map(str, cli_command(*args)))
    process = subprocess.run(["sh", "-c", f"{command} | true; echo status=$?"], capture_output=True,
                             text=True, env=cli_env(), timeout=90)
    assert process.stderr == "", process.stderr


# -------------------------------------------------------------------- copy and lock

HOLD_LOCK = """
import fcntl, sys, time
fd = open(sys.argv[1], "a")
fcntl.flock(fd, fcntl.LOCK_EX)
print("locked", flush=True)
sys.stdin.readline()
"""


@pytest.mark.slow
def test_library_copy_waits_for_a_writer_of_the_source(tmp_path):
    source = copy_library("paper5", tmp_path / "source").path
    holder = subprocess.Popen([sys.executable, "-c", HOLD_LOCK, str(source / "library.lock")],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        done = []
        copier = threading.Thread(target=lambda: done.append(copy_library(source, tmp_path / "copy")))
        copier.start()
        time.sleep(1.0)
        assert not done and copier.is_alive()  # waiting for the writer's exclusive lock
        holder.stdin.write("\n")
        holder.stdin.flush()
        copier.join(timeout=60)
        assert done and tuple(done[0].names) == tuple(Library.open(source).names)
    finally:
        holder.kill()
        holder.wait()


def test_a_full_disk_names_the_file_being_written(tmp_path, monkeypatch):
    import errno

    from drake_lfd.cli.app import describe_os_error
    from drake_lfd.io import atomic_files

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")  # as a write reports it: no file name

    monkeypatch.setattr(atomic_files.os, "fsync", full)
    target = tmp_path / "plan.json"
    for write in (lambda: atomic_files.atomic_write_bytes(target, b"{}"),
                  lambda: atomic_files.atomic_write_many([(target, b"{}")])):
        with pytest.raises(OSError) as raised:
            write()
        assert raised.value.errno == errno.ENOSPC
        assert describe_os_error(raised.value) == f"{target}: No space left on device"
        assert list(tmp_path.iterdir()) == []  # the temporary file is gone, nothing half-written
