"""A first hour without friction: tool frames of libraries, editable copies of the
bundled ones, and policies that know the library they were trained on.

Each friction a new user met is replayed as the commands they typed (docs/cli.rst,
``library add``/``show``/``copy``, ``plan --policy``), with the behaviour that replaces it.
"""

import json
import math
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from drake_lfd.cli import main
from drake_lfd.core.errors import InputError
from drake_lfd.core.tasks import rigid_transform_from_euler_zyx
from drake_lfd.io import library_store
from drake_lfd.io.library import (
    Library,
    bundled_library_paths,
    check_end_effector_frame,
    copy_library,
    library_features,
    tool_frame_options,
)
from drake_lfd.io.policy_files import check_policy_library, load_policy, policy_document, save_policy
from drake_lfd.io.pose_records import angle_text, pose_yaml_text
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.training import feature_hash, feature_hashes

SIMS = Path(__file__).resolve().parent.parent / "sims"
TRANSFERRING = str(SIMS / "transferring.yaml")
PAPER_FRAME = "--tool0-E-p 0 0 0.2 --tool0-E-euler-zyx 0 pi/2 0"
IDENTITY_FRAME = "--tool0-E-p 0 0 0 --tool0-E-euler-zyx 0 0 0"


def run(capsys, *argv):
    """``drake-lfd ARGV``: (exit status, stdout, stderr lines)."""
    status = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return status, captured.out, captured.err.splitlines()


@pytest.fixture
def slide_csv(tmp_path):
    """A joint log a new user brings: paper5's stacking motion, as a CSV."""
    path = tmp_path / "slide.csv"
    path.write_bytes(Library.open("paper5").log_path("stacking").read_bytes())
    return path


@pytest.fixture
def pouring_csv(tmp_path):
    path = tmp_path / "tip.csv"
    path.write_bytes(Library.open("paper5").log_path("pouring").read_bytes())
    return path


def tree(root):
    return sorted((str(p.relative_to(root)), p.read_bytes() if p.is_file() else None) for p in root.rglob("*"))


# ---------------------------------------------------------------- readable frames


@pytest.mark.parametrize("value, text, option", [
    (0.0, "0", "0"), (-1e-13, "0", "0"), (math.pi, "pi", "pi"), (-math.pi, "-pi", "pi"),
    (math.pi / 2, "pi/2", "pi/2"), (-math.pi / 2, "-pi/2", "3*pi/2"), (3 * math.pi / 4, "3*pi/4", "3*pi/4"),
    (-math.pi / 6, "-pi/6", "11*pi/6"), (0.3, "0.3", "0.3"), (-0.25, "-0.25", "-0.25"),
])
def test_angles_are_written_as_multiples_of_pi_where_exact(value, text, option):
    assert angle_text(value) == text
    assert angle_text(value, non_negative=True) == option


@pytest.mark.parametrize("p, euler", [
    ([0, 0, 0.2], [0, math.pi / 2, 0]),
    ([0, 0, 0], [0, 0, 0]),
    ([0.01, -0.1, 0.2], [0.3, -math.pi / 4, 3 * math.pi / 4]),
    ([0, 0, 0.15], [-math.pi / 2, 0.1234567, -math.pi]),
])
def test_frame_mismatch_names_option_values_that_fix_it(tmp_path, capsys, slide_csv, p, euler):
    """The error names the exact ``library add`` options for the task's frame; typing
    them gives a library that the task's frame is accepted with."""
    X_task = rigid_transform_from_euler_zyx(p, euler)
    X_library = rigid_transform_from_euler_zyx([0, 0.05, 0.1], [0.5, 0, -math.pi / 3])
    other = Library.create(tmp_path / "other", X_tool0_E=X_library)
    other.add(Library.open("paper5").demonstration("stacking"), "slide")
    with pytest.raises(InputError) as info:
        check_end_effector_frame(other, X_task, file="task.yaml")
    message = str(info.value)
    assert message.startswith("task.yaml: X_tool0_E: ")
    assert tool_frame_options(X_task) in message
    assert "set the task's X_tool0_E to {p: [0, 0.05, 0.1], euler_zyx: [0.5, 0, -pi/3]}" in message
    assert pose_yaml_text(X_task) in message
    # Follow the advice: the quoted command, with a real directory and log.
    command = re.search(r"'drake-lfd (library add NEWLIB [^']*)'", message).group(1)
    argv = [a.replace("NEWLIB", str(tmp_path / "fixed")).replace("DEMO.csv", str(slide_csv)).replace("NAME", "slide")
            for a in shlex.split(command)]
    assert run(capsys, *argv)[0] == 0
    check_end_effector_frame(Library.open(tmp_path / "fixed"), X_task)  # accepted now
    # Or follow the other advice: the task's X_tool0_E as the message writes it.
    suggested = re.search(r"set the task's X_tool0_E to (\{.*\})$", message).group(1)
    task_text = re.sub(r"(?m)^X_tool0_E: .*$", f"X_tool0_E: {suggested}", Path(TRANSFERRING).read_text())
    (tmp_path / "task.yaml").write_text(task_text)
    check_end_effector_frame(other, load_task(tmp_path / "task.yaml").X_tool0_E)


def test_paper_frame_mismatch_message(tmp_path, capsys, slide_csv):
    """The friction: a library made with E = tool0, planned with the paper's task."""
    assert run(capsys, "library", "add", tmp_path / "mylib", slide_csv, "--name", "slide",
               *IDENTITY_FRAME.split())[0] == 0
    status, out, err = run(capsys, "plan", TRANSFERRING, "--library", tmp_path / "mylib")
    assert status == 2 and len(err) == 1
    assert f"'drake-lfd library add NEWLIB DEMO.csv --name NAME {PAPER_FRAME}'" in err[0]
    assert "{p: [0, 0, 0.2], euler_zyx: [0, pi/2, 0]}" in err[0]  # the task's frame, readable
    assert "set the task's X_tool0_E to {p: [0, 0, 0], euler_zyx: [0, 0, 0]}" in err[0]
    # The fix the message names works.
    assert run(capsys, "library", "add", tmp_path / "fixed", slide_csv, "--name", "slide",
               *PAPER_FRAME.split())[0] == 0
    status, out, err = run(capsys, "plan", TRANSFERRING, "--library", tmp_path / "fixed")
    assert status == 0 and "planned with slide" in out


# ------------------------------------------------------------ library add's frame


def test_new_library_asks_for_its_frame(tmp_path, capsys, slide_csv):
    mylib = tmp_path / "mylib"
    status, out, err = run(capsys, "library", "add", mylib, slide_csv, "--name", "slide")
    assert status == 2 and len(err) == 1, err
    assert err[0].startswith(f"drake-lfd library: error: {mylib}: X_tool0_E: a new library needs its end-effector frame")
    assert "--tool0-E-p X Y Z" in err[0] and "--tool0-E-euler-zyx YAW PITCH ROLL" in err[0]
    assert f"identity, is {IDENTITY_FRAME}" in err[0]
    assert not mylib.exists()
    # One of the two is not enough: the message names the missing one.
    status, out, err = run(capsys, "library", "add", mylib, slide_csv, "--name", "slide", "--tool0-E-p", 0, 0, 0.2)
    assert status == 2 and "give --tool0-E-euler-zyx YAW PITCH ROLL" in err[0] and "--tool0-E-p X Y Z" not in err[0]
    assert not mylib.exists()
    # Both: created with that frame; later adds take it from the library.
    assert run(capsys, "library", "add", mylib, slide_csv, "--name", "slide", *PAPER_FRAME.split())[0] == 0
    assert run(capsys, "library", "add", mylib, slide_csv, "--name", "slide2")[0] == 0
    assert run(capsys, "library", "add", mylib, slide_csv, "--name", "slide3", "--tool0-E-euler-zyx", 0, "90deg", 0)[0] == 0
    assert Library.open(mylib).names == ("slide", "slide2", "slide3")
    check_end_effector_frame(Library.open(mylib), Library.open("paper5").X_tool0_E)


def test_other_frame_for_existing_library_refused_naming_its_frame(tmp_path, capsys, slide_csv):
    mylib = tmp_path / "mylib"
    assert run(capsys, "library", "add", mylib, slide_csv, "--name", "slide", *PAPER_FRAME.split())[0] == 0
    before = tree(mylib)
    for options in (["--tool0-E-p", 0, 0, 0.1], ["--tool0-E-euler-zyx", 0, 0, 0], IDENTITY_FRAME.split()):
        status, out, err = run(capsys, "library", "add", mylib, slide_csv, "--name", "other", *options)
        assert status == 2 and len(err) == 1
        assert f"recorded with the end-effector frame {PAPER_FRAME}" in err[0]
        assert tree(mylib) == before


# ------------------------------------------------- bundled libraries and copies


def test_show_and_help_name_the_bundled_libraries_and_where_they_are(capsys, tmp_path, slide_csv):
    paths = bundled_library_paths()
    assert {"paper5", "paper6"} <= set(paths)
    status, out, err = run(capsys, "library", "show", "paper5")
    assert status == 0
    assert f"installed in {paths['paper5']}" in out and "drake-lfd library copy paper5 DIR" in out
    assert PAPER_FRAME in out
    for name in ("paper5", "paper6"):
        assert f"{name} ({paths[name]})" in out
    status, out, err = run(capsys, "library", "show", "paper5", "--json", "-")
    listing = json.loads(out)
    assert listing["directory"] == str(paths["paper5"]) and listing["read_only"] is True
    assert listing["X_tool0_E_options"] == PAPER_FRAME
    assert {"name": "paper6", "directory": str(paths["paper6"])} in listing["bundled_libraries"]
    with pytest.raises(SystemExit):
        main(["library", "--help"])
    # argparse wraps the epilog, also inside a path at its hyphens: compare without spaces.
    text = "".join(capsys.readouterr().out.split())
    assert "copy" in text
    for name in ("paper5", "paper6"):
        assert "".join(f"{name} ({paths[name]})".split()) in text
    # Adding to a bundled library says how to get an editable copy, and where it is.
    status, out, err = run(capsys, "library", "add", "paper5", slide_csv, "--name", "slide")
    assert status == 2 and len(err) == 1
    assert "drake-lfd library copy paper5 DIR" in err[0] and str(paths["paper5"]) in err[0]


def test_copy_is_editable(tmp_path, capsys, slide_csv):
    mine = tmp_path / "work" / "mylib5"
    status, out, err = run(capsys, "library", "copy", "paper5", mine)
    assert status == 0 and "copied paper5" in out
    copy, original = Library.open(mine), Library.open("paper5")
    assert not copy.read_only and copy.names == original.names
    assert copy.entries == original.entries
    assert tool_frame_options(copy.X_tool0_E) == PAPER_FRAME
    assert feature_hashes(library_features(copy)) == feature_hashes(library_features(original))
    assert sorted(p.name for p in (mine / "cache").iterdir()) == ["features.sqlite"]  # fresh, one row each
    assert sorted(Library.open(mine)._rows) == sorted(original.names) and Library.open(mine).write_feature_caches() == ()
    assert sorted(p.name for p in mine.parent.iterdir()) == ["mylib5"]  # no staging directory left
    # Editable: add (the frame comes from the library) and remove.
    assert run(capsys, "library", "add", mine, slide_csv, "--name", "slide")[0] == 0
    assert run(capsys, "library", "remove", mine, "screw_cw")[0] == 0
    assert Library.open(mine).names == ("screw_ccw", "filling", "pouring", "stacking", "slide")
    assert Library.open("paper5").names == original.names
    # A non-empty destination is refused and left alone; an empty one is fine.
    before = tree(mine)
    status, out, err = run(capsys, "library", "copy", "paper6", mine)
    assert status == 2 and len(err) == 1 and "not empty" in err[0]
    assert tree(mine) == before
    (tmp_path / "empty").mkdir()
    assert run(capsys, "library", "copy", mine, tmp_path / "empty")[0] == 0  # a directory library as SRC
    assert Library.open(tmp_path / "empty").names == Library.open(mine).names
    (tmp_path / "file").write_text("x")
    assert run(capsys, "library", "copy", "paper5", tmp_path / "file")[0] == 2
    assert run(capsys, "library", "copy", "no_such_library", tmp_path / "x")[0] == 2
    assert not (tmp_path / "x").exists()


def test_copy_is_atomic(tmp_path, monkeypatch):
    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(library_store, "write_manifest", fail)
    with pytest.raises(OSError):
        copy_library("paper5", tmp_path / "copy")
    assert list(tmp_path.iterdir()) == []  # neither the copy nor its staging directory


# ---------------------------------------------------------------------- policies


@pytest.fixture
def paper5_policy(tmp_path, capsys):
    path = tmp_path / "pol_paper5.json"
    assert run(capsys, "train", "--library", "paper5", "--random-tasks", 2, "--episodes", 3, "--out", path)[0] == 0
    return path


def test_train_records_demonstrations_and_feature_hashes(paper5_policy):
    document = json.loads(paper5_policy.read_text())
    assert document["format_version"] == 1
    features = library_features(Library.open("paper5"))
    assert document["library_demos"] == list(features)
    assert document["library_feature_sha256"] == feature_hashes(features)
    assert all(re.fullmatch(r"[0-9a-f]{64}", v) for v in document["library_feature_sha256"].values())
    policy = load_policy(paper5_policy)
    assert policy.library_feature_hashes == document["library_feature_sha256"]
    assert policy_document(policy)["library_feature_sha256"] == document["library_feature_sha256"]


def test_feature_hash_tells_features_apart():
    features = library_features(Library.open("paper5"))
    again = library_features(Library.open("paper5"))
    assert {feature_hash(f) for f in features.values()} == {feature_hash(f) for f in again.values()}
    assert len({feature_hash(f) for f in features.values()}) == len(features)


def test_policy_trained_on_another_library_is_refused(tmp_path, capsys, paper5_policy, slide_csv):
    """The friction: plan --library mylib --policy pol_paper5.json planned silently."""
    mylib = tmp_path / "mylib"
    assert run(capsys, "library", "copy", "paper5", mylib)[0] == 0
    assert run(capsys, "library", "add", mylib, slide_csv, "--name", "slide")[0] == 0
    for command in ("plan", "simulate"):
        status, out, err = run(capsys, command, TRANSFERRING, "--library", mylib, "--planner", "q",
                               "--policy", paper5_policy)
        assert status == 2 and len(err) == 1 and out == ""
        assert err[0].startswith(f"drake-lfd {command}: error: {paper5_policy}: library_demos: ")
        assert "not trained on (slide)" in err[0] and "--allow-policy-mismatch" in err[0]
        assert f"--warm-start {paper5_policy}" in err[0]
    status, out, err = run(capsys, "plan", TRANSFERRING, "--library", mylib, "--planner", "q",
                           "--policy", paper5_policy, "--allow-policy-mismatch")
    assert status == 0 and "planned with" in out
    (warning,) = err
    assert warning.startswith(f"drake-lfd plan: warning: {paper5_policy}: ") and "(slide)" in warning
    # The library it was trained on, or a copy of it with fewer demonstrations: accepted.
    for library in ("paper5", tmp_path / "paper5_copy"):
        if library != "paper5":
            assert run(capsys, "library", "copy", "paper5", library)[0] == 0
            assert run(capsys, "library", "remove", library, "pouring")[0] == 0
        status, out, err = run(capsys, "plan", TRANSFERRING, "--library", library, "--planner", "q",
                               "--policy", paper5_policy)
        assert status == 0 and err == []
    # The exact planner does not use the policy: nothing to check.
    assert run(capsys, "plan", TRANSFERRING, "--library", mylib, "--policy", paper5_policy)[0] == 0


def test_changed_features_are_refused(tmp_path, capsys, paper5_policy, pouring_csv):
    """Same names, other motion: 'stacking' recorded again as something else."""
    mylib = tmp_path / "mylib"
    assert run(capsys, "library", "copy", "paper5", mylib)[0] == 0
    assert run(capsys, "library", "remove", mylib, "stacking")[0] == 0
    assert run(capsys, "library", "add", mylib, pouring_csv, "--name", "stacking")[0] == 0
    status, out, err = run(capsys, "plan", TRANSFERRING, "--library", mylib, "--planner", "q",
                           "--policy", paper5_policy)
    assert status == 2 and "features differ from the ones it was trained on (stacking)" in err[0]
    assert "not trained on" not in err[0]
    message = check_policy_library(load_policy(paper5_policy), library_features(Library.open(mylib)),
                                   allow_mismatch=True)
    assert "(stacking)" in message


def test_warm_start_on_a_new_demonstration_is_allowed(tmp_path, capsys, paper5_policy, slide_csv):
    mylib = tmp_path / "mylib"
    assert run(capsys, "library", "copy", "paper5", mylib)[0] == 0
    assert run(capsys, "library", "add", mylib, slide_csv, "--name", "slide")[0] == 0
    retrained = tmp_path / "pol_mylib.json"
    status, out, err = run(capsys, "train", "--library", mylib, "--random-tasks", 2, "--episodes", 3,
                           "--warm-start", paper5_policy, "--out", retrained)
    assert status == 0
    assert "slide" in json.loads(retrained.read_text())["library_feature_sha256"]
    status, out, err = run(capsys, "plan", TRANSFERRING, "--library", mylib, "--planner", "q", "--policy", retrained)
    assert status == 0 and err == []


def test_old_policy_files_without_hashes_load_and_are_checked_by_name(tmp_path, capsys, paper5_policy, pouring_csv):
    document = json.loads(paper5_policy.read_text())
    del document["library_feature_sha256"]
    old = tmp_path / "old_policy.json"
    old.write_text(json.dumps(document))
    policy = load_policy(old)
    assert policy.library_feature_hashes is None and policy.library_demos == document["library_demos"]
    save_policy(policy, tmp_path / "resaved.json")
    assert "library_feature_sha256" not in json.loads((tmp_path / "resaved.json").read_text())
    assert run(capsys, "plan", TRANSFERRING, "--library", "paper5", "--planner", "q", "--policy", old)[0] == 0
    # Names are still compared; features cannot be.
    features = dict(library_features(Library.open("paper5")))
    features["tip"] = features["pouring"]
    with pytest.raises(InputError, match=r"not trained on \(tip\)"):
        check_policy_library(policy, features, file=old)
    features = dict(library_features(Library.open("paper5")))
    features["stacking"] = features["pouring"]
    assert check_policy_library(policy, features, file=old) is None


@pytest.mark.parametrize("hashes", [["x"], {"stacking": "not hex"}, {"stacking": 3}])
def test_malformed_feature_hashes_refused(tmp_path, paper5_policy, hashes):
    document = json.loads(paper5_policy.read_text())
    document["library_feature_sha256"] = hashes
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(document))
    with pytest.raises(InputError, match="library_feature_sha256"):
        load_policy(path)


def test_paper_frame_round_trips_through_the_options():
    X = Library.open("paper5").X_tool0_E
    assert tool_frame_options(X) == PAPER_FRAME
    assert pose_yaml_text(X) == "{p: [0, 0, 0.2], euler_zyx: [0, pi/2, 0]}"
    np.testing.assert_allclose(
        rigid_transform_from_euler_zyx([0, 0, 0.2], [0, math.pi / 2, 0]).GetAsMatrix4(), X.GetAsMatrix4(), atol=1e-12)
