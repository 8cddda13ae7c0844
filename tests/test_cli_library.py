"""``drake-lfd library add|show|remove``: exit codes, one-line errors, the JSON schema of
docs/cli.rst, and a library left untouched by every refused add."""

import hashlib
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from drake_lfd.cli import main
from drake_lfd.io.demonstration_logs import read_rtde_csv
from helpers import joint_log_text, linear_motion


def log_text(seed=0, m=40, delimiter=","):
    return joint_log_text(*linear_motion(seed, m), delimiter)


def tree_digest(root):
    digest = hashlib.sha256()
    for directory, subdirectories, files in sorted(os.walk(root)):
        subdirectories.sort()
        digest.update(os.path.relpath(directory, root).encode() + b"/\0")
        for name in sorted(files):
            path = os.path.join(directory, name)
            digest.update(os.path.relpath(path, root).encode() + b"\0")
            with open(path, "rb") as file:
                digest.update(file.read())
    return digest.hexdigest()


# A new library's frame must be given (no silent identity); this is E = tool0.
IDENTITY = ["--tool0-E-p", "0", "0", "0", "--tool0-E-euler-zyx", "0", "0", "0"]


@pytest.fixture
def library(tmp_path, capsys):
    """A library directory holding one demonstration, ``first``."""
    log = tmp_path / "first.csv"
    log.write_text(log_text(1))
    root = tmp_path / "lib"
    assert main(["library", "add", str(root), str(log), "--name", "first", *IDENTITY]) == 0
    capsys.readouterr()
    return root


def bad_logs():
    good = log_text(2).splitlines()
    middle_cut = list(good)
    middle_cut[5] = middle_cut[5][: middle_cut[5].rindex(",")]
    with_nan = list(good)
    cells = with_nan[3].split(",")
    cells[3] = "nan"
    with_nan[3] = ",".join(cells)
    return {
        "truncated": ("\n".join(middle_cut) + "\n", "line 6: has 6 fields but the header has 7"),
        "nan": ("\n".join(with_nan) + "\n", "line 4, column actual_q_2: nan is not a finite number"),
        "wrong_column": (
            "\n".join([good[0].replace("actual_q_4", "actual_qd_4")] + good[1:]) + "\n",
            "wrong number of joints",
        ),
        "empty": ("", "the file is empty"),
        "one_sample": ("\n".join(good[:2]) + "\n", "has 1 sample(s); a demonstration needs at least 2"),
    }


@pytest.mark.parametrize("kind", sorted(bad_logs()))
def test_bad_logs_refused_with_one_line_and_library_unchanged(library, tmp_path, capsys, kind):
    text, expected = bad_logs()[kind]
    log = tmp_path / f"{kind}.csv"
    log.write_text(text)
    before = tree_digest(library)
    assert main(["library", "add", str(library), str(log), "--name", "second"]) == 2
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("drake-lfd library: error: ")
    assert str(log) in lines[0] and expected in lines[0]
    assert "Traceback" not in captured.err
    assert tree_digest(library) == before
    # Nor is a new library created by a refused add.
    fresh = tmp_path / f"fresh_{kind}"
    assert main(["library", "add", str(fresh), str(log), "--name", "second", *IDENTITY]) == 2
    assert str(log) in capsys.readouterr().err
    assert not fresh.exists()


def test_log_cut_off_mid_line_is_kept_with_warning(library, tmp_path, capsys):
    text = log_text(3)
    log = tmp_path / "cut.csv"
    log.write_text(text[: text.rindex(",", 0, len(text) - 10)])
    assert main(["library", "add", str(library), str(log), "--name", "cut"]) == 0
    captured = capsys.readouterr()
    (warning,) = captured.err.splitlines()
    assert warning.startswith("drake-lfd library: warning: ") and "line 41" in warning
    assert "added 'cut'" in captured.out and "39 samples" in captured.out
    assert main(["library", "show", str(library), "--json", str(tmp_path / "show.json")]) == 0
    listing = json.loads((tmp_path / "show.json").read_text())
    assert [d["samples"] for d in listing["demos"]] == [40, 39]


def test_add_show_remove(library, tmp_path, capsys):
    log = tmp_path / "second.csv"
    log.write_text(log_text(4, m=30, delimiter=" "))
    assert main(["library", "add", str(library), str(log), "--name", "second", "--description", "pouring"]) == 0
    assert "added 'second'" in capsys.readouterr().out

    out = tmp_path / "show.json"
    assert main(["library", "show", str(library), "--json", str(out)]) == 0
    table = capsys.readouterr().out
    for text in ("first", "second", "pouring", "deg about", "start", "middle", "late"):
        assert text in table
    listing = json.loads(out.read_text())
    assert set(listing) >= {"library", "X_tool0_E", "demos"}
    assert listing["library"] == str(library.resolve())
    assert listing["X_tool0_E"] == {"p": [0.0, 0.0, 0.0], "q_wxyz": [1.0, 0.0, 0.0, 0.0]}
    assert [d["name"] for d in listing["demos"]] == ["first", "second"]
    for demo in listing["demos"]:
        assert set(demo) >= {"name", "path", "samples", "duration_s", "description"}
        assert isinstance(demo["samples"], int) and isinstance(demo["duration_s"], float)
        assert isinstance(demo["description"], str)
        assert Path(demo["path"]).is_absolute()
        # The log at "path" is an RTDE-style CSV anyone can read back.
        recorded, warnings = read_rtde_csv(demo["path"])
        assert warnings == () and recorded.num_samples == demo["samples"]
        assert recorded.duration_s == pytest.approx(demo["duration_s"])
        summary = demo["feature"]["summary"]
        assert [row["label"] for row in summary] == ["start", "middle", "late"]
        for row in summary:
            assert np.linalg.norm(row["q_wxyz"]) == pytest.approx(1.0)
    assert listing["demos"][1]["description"] == "pouring"

    assert main(["library", "show", str(library), "--json", "-"]) == 0
    assert json.loads(capsys.readouterr().out) == listing

    assert main(["library", "remove", str(library), "first"]) == 0
    assert "removed 'first'" in capsys.readouterr().out
    assert main(["library", "show", str(library), "--json", str(out)]) == 0
    assert [d["name"] for d in json.loads(out.read_text())["demos"]] == ["second"]
    assert not (library / "demos" / "first.csv").exists()


def test_add_creates_library_with_tool_frame(tmp_path, capsys):
    log = tmp_path / "demo.csv"
    log.write_text(log_text(5))
    root = tmp_path / "new" / "lib"
    argv = ["library", "add", str(root), str(log), "--name", "a", "--tool0-E-p", "0", "0", "0.15",
            "--tool0-E-euler-zyx", "pi/2", "0", "0"]
    assert main(argv) == 0
    capsys.readouterr()
    assert main(["library", "show", str(root), "--json", "-"]) == 0
    pose = json.loads(capsys.readouterr().out)["X_tool0_E"]
    np.testing.assert_allclose(pose["p"], [0, 0, 0.15])
    np.testing.assert_allclose(pose["q_wxyz"], [math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)])
    # The same frame again is fine; another frame cannot be slipped into this library.
    assert main(argv[:5] + ["b"] + argv[6:]) == 0
    capsys.readouterr()
    before = tree_digest(root)
    assert main(["library", "add", str(root), str(log), "--name", "c", "--tool0-E-p", "0", "0", "0.2"]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert "X_tool0_E" in line
    assert tree_digest(root) == before


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["library", "remove", "{lib}", "absent"], "no demonstration 'absent' (it has: first)"),
        (["library", "show", "{tmp}/no_such_lib"], "no such library"),
        (["library", "add", "{lib}", "{tmp}/first.csv", "--name", "first"], "already"),
        (["library", "add", "{lib}", "{tmp}/first.csv", "--name", "bad name"], "invalid demonstration name"),
        (["library", "add", "{lib}", "{tmp}/absent.csv", "--name", "x"], "no such file"),
    ],
)
def test_refusals_exit_2_with_one_line(library, tmp_path, capsys, argv, expected):
    before = tree_digest(library)
    argv = [a.format(lib=library, tmp=tmp_path) for a in argv]
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert expected in line
    assert tree_digest(library) == before


# ------------------------------------------------------------------------- bulk add


def write_logs(folder, names, seed=10):
    folder.mkdir(parents=True, exist_ok=True)
    for index, name in enumerate(names):
        (folder / f"{name}.csv").write_text(log_text(seed + index))
    return folder


def test_bulk_add_of_a_folder_and_a_glob_names_each_log_after_its_stem(library, tmp_path, capsys):
    write_logs(tmp_path / "logs", ["alpha", "beta"])
    write_logs(tmp_path / "more", ["gamma", "delta"], seed=20)
    (tmp_path / "logs" / "notes.txt").write_text("not a log")
    status = main(["library", "add", str(library), str(tmp_path / "logs"), str(tmp_path / "more" / "*.csv")])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    assert captured.err == ""  # no progress lines when stderr is not a terminal, no refusals
    assert captured.out.splitlines()[-1] == f"added 4 of 4 logs to {library.resolve()}"
    from drake_lfd.io.library import Library

    opened = Library.open(library)
    assert opened.names == ("first", "alpha", "beta", "delta", "gamma")  # folder sorted, then the glob sorted
    stored = read_rtde_csv(opened.log_path("gamma"))[0]
    np.testing.assert_array_equal(stored.joint_positions, read_rtde_csv(tmp_path / "more" / "gamma.csv")[0].joint_positions)
    assert opened.write_feature_caches() == ()  # every added one has its cache row


def test_bulk_add_refuses_each_bad_log_with_one_line_and_adds_the_rest(library, tmp_path, capsys):
    logs = write_logs(tmp_path / "logs", ["good_1", "good_2", "first", "Twin", "twin"])
    (logs / "bad name.csv").write_text(log_text(3))
    (logs / "broken.csv").write_text(bad_logs()["nan"][0])
    status = main(["library", "add", str(library), str(logs), str(tmp_path / "absent.csv")])
    captured = capsys.readouterr()
    assert status == 2
    errors = captured.err.splitlines()
    assert len(errors) == 5 and "Traceback" not in captured.err
    expected = {
        str(tmp_path / "absent.csv"): "no such file",
        str(logs / "bad name.csv"): "invalid demonstration name 'bad name'",
        str(logs / "broken.csv"): "line 4, column actual_q_2: nan is not a finite number",
        str(logs / "first.csv"): "the library has a demonstration named 'first' already",
        str(logs / "twin.csv"): "its name 'twin' is also the name of",
    }
    for line in errors:
        path = line.removeprefix("drake-lfd library: refused ").split(": ")[0]
        assert expected.pop(path) in line, line
    assert expected == {}
    assert captured.out.splitlines()[-1] == (
        f"added 3 of 8 logs to {library.resolve()}; refused 5: 1 not found, 1 file name not a demonstration name, "
        "1 log refused, 1 name already in the library, 1 name repeated in this add"
    )
    from drake_lfd.io.library import Library

    assert Library.open(library).names == ("first", "Twin", "good_1", "good_2")
    # Nothing of a refused log was written.
    assert sorted(p.name for p in (library / "demos").iterdir()) == ["Twin.csv", "first.csv", "good_1.csv", "good_2.csv"]


def test_bulk_add_to_a_new_library_applies_the_options_to_every_log(tmp_path, capsys):
    logs = write_logs(tmp_path / "logs", ["one", "two", "three"])
    root = tmp_path / "new"
    assert main(["library", "add", str(root), str(logs), "--start", "0.5", "--end", "1.5",
                 "--description", "cut", *IDENTITY]) == 0
    from drake_lfd.io.library import Library

    opened = Library.open(root)
    assert opened.names == ("one", "three", "two")
    for entry in opened.entries:
        assert entry.duration_s == pytest.approx(1.0, abs=0.06) and entry.description == "cut"
    capsys.readouterr()


def test_bulk_add_where_every_log_is_refused_creates_nothing(tmp_path, capsys):
    logs = tmp_path / "logs"
    logs.mkdir()
    (logs / "broken.csv").write_text("")
    root = tmp_path / "new" / "lib"
    assert main(["library", "add", str(root), str(logs), *IDENTITY]) == 2
    captured = capsys.readouterr()
    assert captured.err.splitlines() == [f"drake-lfd library: refused {logs / 'broken.csv'}: the file is empty; "
                                         "expected an RTDE CSV log with a header row"]
    assert "refused 1: 1 log refused (no library was created)" in captured.out
    assert not (tmp_path / "new").exists()
    # A folder without logs is one error line, exit 2.
    assert main(["library", "add", str(root), str(tmp_path / "logs" / "*.bag"), *IDENTITY]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert "found no logs in" in line


@pytest.mark.parametrize("argv, expected", [
    (["library", "add", "{lib}", "{tmp}/a.csv", "{tmp}/b.csv", "--name", "x"], "names one demonstration but 2 logs"),
    (["library", "add", "paper5", "{tmp}/a.csv"], "drake-lfd library copy paper5 DIR"),
])
def test_bulk_add_refusals_of_the_whole_command(library, tmp_path, capsys, argv, expected):
    for name in ("a", "b"):
        (tmp_path / f"{name}.csv").write_text(log_text(5))
    before = tree_digest(library)
    assert main([a.format(lib=library, tmp=tmp_path) for a in argv]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert expected in line
    assert tree_digest(library) == before


def test_progress_bar_redraws_on_a_terminal_and_is_quiet_otherwise():
    import io

    from drake_lfd.cli.progress import ProgressBar

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    terminal, pipe = Terminal(), io.StringIO()
    for stream in (terminal, pipe):
        bar = ProgressBar("adding", 3, stream=stream, quiet_unless_terminal=True)
        for done in (1, 2, 3):
            bar.update(done)
        bar.close()
    assert pipe.getvalue() == ""
    assert terminal.getvalue().startswith("\radding [") and "3/3" in terminal.getvalue()
    assert terminal.getvalue().endswith("\n")


def test_a_bulk_add_killed_while_creating_its_library_leaves_no_library(tmp_path, capsys):
    """The new library and its first batch are one step: killed after the logs and before
    the manifest (here: the process ends hard where the manifest would be written), the
    directory is no library, and the next bulk add there creates it whole."""
    import subprocess
    import sys

    from cli_subprocess import cli_env
    from drake_lfd.io.library import Library, is_unused_library_directory

    logs = write_logs(tmp_path / "logs", ["one", "two", "three"])
    root = tmp_path / "new"
    killed = subprocess.run(
        [sys.executable, "-c",
         "import os, sys\n"
         "import drake_lfd.io.library_store as store\n"
         "store.write_manifest = lambda *args, **kwargs: os._exit(9)\n"
         "from drake_lfd.cli import main\n"
         "sys.exit(main(sys.argv[1:]))\n",
         "library", "add", str(root), str(logs), *IDENTITY],
        env=cli_env(), capture_output=True, text=True)
    assert killed.returncode == 9
    assert list((root / "demos").iterdir())  # the logs were written, the manifest not
    assert not (root / "library.json").exists() and is_unused_library_directory(root)
    assert main(["library", "show", str(root)]) == 2
    capsys.readouterr()
    assert main(["library", "add", str(root), str(logs), *IDENTITY]) == 0
    assert Library.open(root).names == ("one", "three", "two")
    capsys.readouterr()
