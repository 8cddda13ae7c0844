"""Library reliability: concurrent writers take turns (the library lock), kill -9 loses
and corrupts nothing, stale temporary files go on the next write, a refused add creates
nothing, ``library remove`` repairs an entry whose log is gone, and a manifest that
disagrees with its logs is refused naming the file and the field.

The concurrency and kill rounds are ``benchmarks/stress_library.py`` with fewer rounds
(its 100 + 100 are the measured figures)."""

import importlib.util
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from drake_lfd.cli import main
from drake_lfd.core.errors import InputError
from drake_lfd.io.file_lock import exclusive_lock, shared_lock
from drake_lfd.io.library import Library, is_unused_library_directory
from helpers import linear_motion, wait_until, write_joint_log

ROOT = Path(__file__).resolve().parent.parent
IDENTITY = ["--tool0-E-p", "0", "0", "0", "--tool0-E-euler-zyx", "0", "0", "0"]


def stress_module():
    spec = importlib.util.spec_from_file_location("stress_library", ROOT / "benchmarks" / "stress_library.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def write_log(path, seed=0, m=40, still=False, end="\n"):
    return write_joint_log(path, *linear_motion(seed, m, still), end=end)


def tree(root):
    """Every path under ``root`` with its bytes (directories as None)."""
    return {
        str(p.relative_to(root)): (None if p.is_dir() else p.read_bytes()) for p in sorted(Path(root).rglob("*"))
    }


@pytest.fixture
def library(tmp_path, capsys):
    root = tmp_path / "lib"
    for index, name in enumerate(("first", "second")):
        log = write_log(tmp_path / f"{name}.csv", seed=index)
        assert main(["library", "add", str(root), str(log), "--name", name, *IDENTITY]) == 0
    capsys.readouterr()
    return root


def one_error_line(capsys):
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert "Traceback" not in captured.err
    return lines[0]


# ----------------------------------------------------------- concurrency and kills


@pytest.mark.slow
def test_concurrent_adds_of_different_demos_all_land(tmp_path):
    """5 rounds of 4 writer processes adding at the same instant (the benchmark: 100)."""
    totals = stress_module().concurrency_rounds(5, 4, tmp_path)
    assert totals["adds"] == 20
    assert totals["failed_exits"] == 0, totals["examples"]
    assert totals["lost"] == 0 and totals["orphans"] == 0 and totals["corrupt"] == 0, totals["examples"]
    assert totals["temporaries"] == 0


@pytest.mark.slow
def test_kill_9_during_add_and_remove_loses_and_corrupts_nothing(tmp_path):
    """4 writers killed at random moments (the benchmark: 100); after the next command no
    temporary file is left."""
    totals = stress_module().kill_rounds(4, tmp_path, seed=1, calibrations=1)
    assert totals["kills"] == 4
    assert totals["lost"] == 0 and totals["corrupt"] == 0, totals["examples"]
    assert totals["next_command_failed"] == 0
    assert totals["temporaries_after_next"] == 0


@pytest.mark.slow
def test_a_writer_waits_for_the_lock(library, tmp_path):
    """While another process holds the library's lock, ``library add`` waits; it adds as
    soon as the lock is released."""
    log = write_log(tmp_path / "third.csv", seed=3)
    with exclusive_lock(library / "library.lock"):
        process = subprocess.Popen(
            [sys.executable, "-m", "drake_lfd", "library", "add", str(library), str(log), "--name", "third"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )
        time.sleep(3.0)  # start-up takes about 1 s
        assert process.poll() is None  # still waiting
        assert Library.open(library).names == ("first", "second")
    out, err = process.communicate(timeout=60)
    assert process.returncode == 0, err
    assert "added 'third'" in out
    assert Library.open(library).names == ("first", "second", "third")


# The second writer of a race to create a library, in its own process: the command found
# the directory unused (a manifest temporary is debris), then create's own check listed the
# debris just before the first writer's manifest temporary appeared.
RACING_WRITER = """
import os, pathlib, sys
import drake_lfd.io.library_store as store
real, calls = store.library_temporaries, []
def listed_too_early(directory):
    calls.append(directory)
    if len(calls) != 2:
        return real(directory)
    pathlib.Path(os.environ["LISTED"]).touch()  # create's check is done: the lock is next
    return []
store.library_temporaries = listed_too_early
from drake_lfd.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.slow
def test_a_library_being_created_by_another_writer_is_waited_for(tmp_path):
    """Two writers racing to create a library: the second sees the first's manifest
    temporary but no manifest yet. It waits for the lock and adds to the library the
    first writer made, instead of calling the directory "not empty"."""
    root = tmp_path / "lib"
    made = tmp_path / "made"  # what the first writer's create_with ends with
    assert main(["library", "add", str(made), str(write_log(tmp_path / "first.csv", seed=0)), "--name", "first",
                 *IDENTITY]) == 0
    log = write_log(tmp_path / "second.csv", seed=1)
    root.mkdir()
    with exclusive_lock(root / "library.lock"):  # the first writer, mid-create
        (root / "demos").mkdir()
        (root / "cache").mkdir()
        temporary = root / ".library.json.r4c3e1.tmp"
        temporary.write_text("{")
        listed = tmp_path / "listed"
        process = subprocess.Popen(
            [sys.executable, "-c", RACING_WRITER, "library", "add", str(root), str(log), "--name", "second",
             *IDENTITY], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env={**os.environ, "LISTED": str(listed)},
        )
        assert wait_until(listed.exists, timeout_s=120, while_running=process, interval_s=0.05), process.communicate()
        time.sleep(1.0)
        assert process.poll() is None, process.communicate()  # waiting for the lock, not refusing
        for path in (made / "demos").iterdir():
            path.rename(root / "demos" / path.name)
        temporary.write_bytes((made / "library.json").read_bytes())
        temporary.rename(root / "library.json")  # the first writer's manifest lands
    out, err = process.communicate(timeout=60)
    assert process.returncode == 0, err
    assert "added 'second'" in out
    assert Library.open(root).names == ("first", "second")


def test_creating_in_a_non_empty_directory_without_a_library_lock_is_refused_at_once(tmp_path):
    """No library writer was ever there: refused without waiting and without a lock file."""
    root = tmp_path / "notes"
    root.mkdir()
    (root / "mine.txt").write_text("keep")
    with pytest.raises(InputError, match="exists and is not empty"):
        Library.create(root)
    assert sorted(p.name for p in root.iterdir()) == ["mine.txt"]


def test_creating_in_a_directory_with_a_lock_and_other_files_is_refused_under_the_lock(tmp_path):
    """A lock file (a writer was there) but someone else's files: refused once the lock is
    free, the files kept."""
    root = tmp_path / "lib"
    root.mkdir()
    (root / "library.lock").write_text("")
    (root / "mine.txt").write_text("keep")
    with pytest.raises(InputError, match="exists and is not empty"):
        Library.create(root)
    assert sorted(p.name for p in root.iterdir()) == ["library.lock", "mine.txt"]
    assert (root / "mine.txt").read_text() == "keep"


def test_stale_temporaries_are_removed_by_the_next_write(library, tmp_path, capsys):
    stale = [library / ".library.json.k2j3h4.tmp", library / "demos" / ".first.csv.x8y7z6.tmp",
             library / "cache" / ".first.npz.a1b2c3.tmp"]
    for path in stale:
        path.write_bytes(b"half a file")
    keep = library / "notes.tmp"  # not an atomic write's temporary file
    keep.write_text("mine")
    assert Library.open(library).names == ("first", "second")  # reading leaves them
    assert all(path.exists() for path in stale)
    assert main(["library", "remove", str(library), "second"]) == 0
    assert not any(path.exists() for path in stale)
    assert keep.exists()
    # And the next "library show" (which writes caches) clears them too.
    stale[1].write_bytes(b"x")
    assert main(["library", "show", str(library), "--json", str(tmp_path / "show.json")]) == 0
    assert not stale[1].exists()
    capsys.readouterr()


def test_shared_lock_never_creates_the_lock_file(tmp_path):
    with shared_lock(tmp_path / "library.lock") as locked:
        assert locked is False
    assert not (tmp_path / "library.lock").exists()
    with exclusive_lock(tmp_path / "library.lock"):
        with exclusive_lock(tmp_path / "library.lock"), shared_lock(tmp_path / "library.lock") as locked:
            assert locked  # nested in one process: passes through instead of waiting for itself
    assert (tmp_path / "library.lock").read_bytes() == b""


# ------------------------------------------------------------ refusals and repairs


def test_stationary_log_refusal_names_the_file(library, tmp_path, capsys):
    log = write_log(tmp_path / "still.csv", still=True)
    before = tree(library)
    assert main(["library", "add", str(library), str(log), "--name", "still"]) == 2
    line = one_error_line(capsys)
    assert line.startswith(f"drake-lfd library: error: {log}: ") and "does not move the tool" in line
    assert tree(library) == before


@pytest.mark.parametrize("kind", ["still", "jump", "ms", "name", "pre-existing empty directory"])
def test_refused_add_to_a_new_library_creates_nothing(tmp_path, capsys, kind):
    log = write_log(tmp_path / "demo.csv", still=kind == "still")
    if kind == "jump":
        text = log.read_text().splitlines()
        cells = text[20].split(",")
        cells[2] = repr(float(cells[2]) + 1.5)
        text[20] = ",".join(cells)
        log.write_text("\n".join(text) + "\n")
    if kind == "ms":
        text = log.read_text().splitlines()
        text[1:] = [",".join([repr(float(line.split(",")[0]) * 1000)] + line.split(",")[1:]) for line in text[1:]]
        log.write_text("\n".join(text) + "\n")
    root = tmp_path / "new" / "lib"
    name = "bad name" if kind == "name" else "demo"
    if kind == "pre-existing empty directory":
        root.mkdir(parents=True)
        log = write_log(tmp_path / "demo.csv", still=True)
    assert main(["library", "add", str(root), str(log), "--name", name, *IDENTITY]) == 2
    assert str(log) in one_error_line(capsys) or kind == "name"
    if kind == "pre-existing empty directory":
        assert root.is_dir() and list(root.iterdir()) == []
    else:
        assert not (tmp_path / "new").exists()


def test_new_library_in_a_directory_a_killed_create_left(tmp_path, capsys):
    root = tmp_path / "lib"
    (root / "demos").mkdir(parents=True)
    (root / "library.lock").write_bytes(b"")
    (root / ".library.json.abc123.tmp").write_text("{")
    assert is_unused_library_directory(root)
    log = write_log(tmp_path / "demo.csv")
    assert main(["library", "add", str(root), str(log), "--name", "demo", *IDENTITY]) == 0
    assert Library.open(root).names == ("demo",)
    assert not (root / ".library.json.abc123.tmp").exists()
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("x")
    assert not is_unused_library_directory(tmp_path / "other")
    capsys.readouterr()


def test_remove_drops_an_entry_whose_log_is_missing(library, tmp_path, capsys):
    (library / "demos" / "first.csv").unlink()
    assert main(["library", "show", str(library)]) == 2
    line = one_error_line(capsys)
    assert f"{library / 'library.json'}: demos[0].file: the joint log demos/first.csv is missing" in line
    assert f"drake-lfd library remove {library} first" in line  # the repair, spelled out
    assert main(["library", "remove", str(library), "first"]) == 0
    assert "removed 'first'" in capsys.readouterr().out
    assert Library.open(library).names == ("second",)
    assert not (library / "cache" / "first.npz").exists()
    assert "first" not in Library.open(library)._rows  # its feature cache row went with it
    assert main(["library", "show", str(library), "--json", str(tmp_path / "show.json")]) == 0
    assert [d["name"] for d in json.loads((tmp_path / "show.json").read_text())["demos"]] == ["second"]


@pytest.mark.parametrize(
    "field, value, expected",
    [
        ("samples", 41, "demos[1].samples: is 41 but the joint log demos/second.csv has 40 samples"),
        ("duration_s", 2.5, "demos[1].duration_s: is 2.5 s but the joint log demos/second.csv spans 2.0 s"),
    ],
)
def test_edited_manifest_is_detected_on_open(library, tmp_path, capsys, field, value, expected):
    manifest = library / "library.json"
    data = json.loads(manifest.read_text())
    data["demos"][1][field] = value
    manifest.write_text(json.dumps(data))
    for argv in (["library", "show", str(library)],
                 ["library", "add", str(library), str(write_log(tmp_path / "x.csv", seed=9)), "--name", "x"]):
        assert main(argv) == 2
        line = one_error_line(capsys)
        assert f"{manifest}: {expected}" in line
    assert not (library / "demos" / "x.csv").exists()
    # The caches are fresh, so only the check on open can see it (features alone would not).
    assert main(["library", "remove", str(library), "second"]) == 0  # the repair
    assert Library.open(library).names == ("first",)


def test_edited_log_sample_count_is_detected(library, capsys):
    log = library / "demos" / "first.csv"
    log.write_text("\n".join(log.read_text().splitlines()[:-1]) + "\n")  # one sample less
    assert main(["library", "show", str(library)]) == 2
    assert "demos[0].samples: is 40 but the joint log demos/first.csv has 39 samples" in one_error_line(capsys)


def test_a_reader_opened_before_a_remove_reads_the_library_as_it_is_now(tmp_path):
    # ``plan`` opened the library, then another process removed a demonstration: reading
    # the features failed with "cannot read the joint log: No such file or directory".
    from drake_lfd.io.library import Library, copy_library, library_features

    copy = tmp_path / "lib"
    copy_library("paper5", copy)
    reader = Library.open(copy)
    Library.open(copy).remove("filling")  # another writer
    features = library_features(reader)
    assert "filling" not in features and len(features) == 4
    reader.write_feature_caches()  # no error either
    assert reader.names == ("screw_cw", "screw_ccw", "pouring", "stacking")
