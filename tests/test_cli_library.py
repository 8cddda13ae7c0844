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

Q_HOME = np.array([0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0])
HEADER = "timestamp,actual_q_0,actual_q_1,actual_q_2,actual_q_3,actual_q_4,actual_q_5"


def log_text(seed=0, m=40, delimiter=","):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, m)
    q = Q_HOME + np.outer(np.linspace(0, 1, m), rng.uniform(-0.6, 0.6, 6))
    lines = [HEADER.replace(",", delimiter)]
    lines += [delimiter.join(repr(float(v)) for v in (t[k], *q[k])) for k in range(m)]
    return "\n".join(lines) + "\n"


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
