"""The library directory: add/remove/open, cached features equal recomputed ones, a
crash mid-save leaves it intact, corrupt manifests and frame mismatches are refused."""

import hashlib
import json
import math
import os
import shutil
import sqlite3

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw

import drake_lfd.core.resources as resources
import drake_lfd.io.library as mut
import drake_lfd.io.library_store as store
from drake_lfd.core.demonstrations import Demonstration
from drake_lfd.robot.kinematics import dual_quaternions_from_demonstration
from drake_lfd.core.errors import InputError
from drake_lfd.core.features import Feature
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.io.pose_records import pose_json_from_rigid_transform, rigid_transform_from_pose_json

Q_HOME = np.array([0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0])
X_TOOL0_E = RigidTransform(RollPitchYaw(0.1, -0.2, 0.3), [0.01, -0.02, 0.15])


def make_demo(seed=0, m=60, name="demo"):
    rng = np.random.default_rng(seed)
    t = 3.0 + np.linspace(0.0, 2.0, m)
    q = Q_HOME + np.outer(np.linspace(0, 1, m) ** 2, rng.uniform(-0.6, 0.6, 6))
    return Demonstration(name, t, q)


def tree_digest(root):
    """Hash of every directory and file (names and bytes) under ``root``."""
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


def cache_rows(root):
    """Name -> the feature cache's row (name, sha256 of the log, feature key, deltas blob)."""
    path = root / "cache" / "features.sqlite"
    if not path.exists():
        return {}
    with sqlite3.connect(path) as connection:
        rows = connection.execute("SELECT name, sha256, feature_key, deltas FROM demos").fetchall()
    connection.close()
    return {row[0]: row for row in rows}


def spoil_cache_row(root, name, **columns):
    with sqlite3.connect(root / "cache" / "features.sqlite") as connection:
        for column, value in columns.items():
            connection.execute(f"UPDATE demos SET {column} = ? WHERE name = ?", (value, name))
    connection.close()


@pytest.fixture
def library(tmp_path):
    dut = mut.Library.create(tmp_path / "lib", X_tool0_E=X_TOOL0_E)
    dut.add(make_demo(1), "screw_cw", "screw clockwise")
    dut.add(make_demo(2), "pour", "pouring")
    return dut


# ------------------------------------------------------------------------- basics


def test_add_then_open_round_trips(library, tmp_path):
    reopened = mut.Library.open(tmp_path / "lib")
    assert reopened.names == ("screw_cw", "pour")
    assert not reopened.read_only
    np.testing.assert_allclose(reopened.X_tool0_E.GetAsMatrix4(), X_TOOL0_E.GetAsMatrix4(), atol=1e-15)
    demo = reopened.demonstration("pour")
    expected = make_demo(2)
    np.testing.assert_array_equal(demo.timestamps, expected.timestamps)
    np.testing.assert_array_equal(demo.joint_positions, expected.joint_positions)
    assert demo.description == "pouring" and demo.name == "pour"
    entry = reopened.entry("pour")
    assert entry.file == "demos/pour.csv" and entry.samples == 60
    assert entry.duration_s == pytest.approx(2.0)
    assert reopened.log_path("pour") == (tmp_path / "lib" / "demos" / "pour.csv").resolve()
    manifest = json.loads((tmp_path / "lib" / "library.json").read_text())
    assert manifest["schema_version"] == 1
    assert [d["name"] for d in manifest["demos"]] == ["screw_cw", "pour"]
    assert "pour" in reopened and "stack" not in reopened and len(reopened) == 2


def test_features_recomputed_from_logs_equal_cached(library, tmp_path):
    root = tmp_path / "lib"
    assert sorted(cache_rows(root)) == ["pour", "screw_cw"]
    cached = mut.Library.open(root).feature("pour")
    # Independently: FK of the log with the library's frame, then Feature.from_poses.
    kinematics = UR5eKinematics(X_tool0_E=X_TOOL0_E)
    D = dual_quaternions_from_demonstration(make_demo(2), kinematics)
    recomputed = Feature.from_poses(D)
    for name in ("rotations", "translations", "deltas", "poses"):
        np.testing.assert_allclose(getattr(cached, name), getattr(recomputed, name), atol=1e-12)
    np.testing.assert_array_equal(mut.Library.open(root).resampled_poses("pour"), cached.poses)
    np.testing.assert_allclose(cached.poses[[0, -1]], D[[0, -1]], atol=1e-12)


def test_stale_or_missing_cache_is_recomputed_and_rewritten(library, tmp_path):
    root = tmp_path / "lib"
    cache = root / "cache" / "features.sqlite"
    reference = np.array(mut.Library.open(root).feature("pour").deltas)
    fresh = cache_rows(root)
    # A damaged row (its arrays are not a feature) is recomputed, and rewritten on request.
    spoil_cache_row(root, "pour", deltas=b"garbage")
    dut = mut.Library.open(root)
    np.testing.assert_array_equal(dut.feature("pour").deltas, reference)
    assert cache_rows(root)["pour"][3] == b"garbage"  # reading writes nothing
    assert dut.write_feature_caches() == ("pour",)
    assert cache_rows(root) == fresh
    assert dut.write_feature_caches() == ()  # fresh rows are left alone
    assert mut.Library.open(root).write_feature_caches() == ()
    # A row whose key does not match (another log's feature) is not trusted.
    screw = cache_rows(root)["screw_cw"]
    spoil_cache_row(root, "pour", feature_key=screw[2], deltas=screw[3])
    np.testing.assert_array_equal(mut.Library.open(root).feature("pour").deltas, reference)
    # A file that is not a database, or none at all: every feature recomputed, nothing written.
    for damage in ("garbage", "delete"):
        if damage == "garbage":
            cache.write_bytes(b"garbage")
        else:
            cache.unlink()
        dut = mut.Library.open(root)
        np.testing.assert_array_equal(dut.feature("pour").deltas, reference)
        assert cache.exists() == (damage == "garbage")
        assert dut.write_feature_caches() == ("screw_cw", "pour")
        assert cache_rows(root) == fresh


def test_reading_a_library_writes_nothing(library, tmp_path):
    root = tmp_path / "lib"
    for path in (root / "cache").iterdir():
        path.unlink()
    before = tree_digest(root)
    dut = mut.Library.open(root)
    features = mut.library_features(dut)
    assert list(features) == ["screw_cw", "pour"]
    dut.demonstration("pour"), dut.resampled_poses("screw_cw")
    assert tree_digest(root) == before


def test_changed_log_invalidates_cache(library, tmp_path):
    root = tmp_path / "lib"
    before = np.array(mut.Library.open(root).feature("pour").deltas)
    other = make_demo(7)
    from drake_lfd.io.demonstration_logs import write_rtde_csv

    write_rtde_csv(other, root / "demos" / "pour.csv")  # same sample count, other motion
    after = mut.Library.open(root).feature("pour").deltas
    assert not np.allclose(before, after)


def test_remove_updates_manifest_and_deletes_log(library, tmp_path):
    root = tmp_path / "lib"
    library.remove("screw_cw")
    assert library.names == ("pour",)
    assert mut.Library.open(root).names == ("pour",)
    assert not (root / "demos" / "screw_cw.csv").exists()
    assert sorted(cache_rows(root)) == ["pour"]
    with pytest.raises(InputError, match="no demonstration 'screw_cw'"):
        library.remove("screw_cw")


def test_a_remove_that_removed_succeeds_when_the_cache_folder_is_a_file(library, tmp_path):
    # It used to remove the entry, then fail on cache/NAME.npz ("Not a directory").
    root = tmp_path / "lib"
    shutil.rmtree(root / "cache")
    (root / "cache").write_text("not a folder")
    library.remove("screw_cw")  # no error
    assert mut.Library.open(root).names == ("pour",)
    assert not (root / "demos" / "screw_cw.csv").exists()


@pytest.mark.parametrize("name", ["", "has space", "a/b", "../x", "é", "x.csv", "abc\n", "abc\r\n"])
def test_invalid_names_refused(library, tmp_path, name):
    before = tree_digest(tmp_path / "lib")
    with pytest.raises(InputError, match="name"):
        library.add(make_demo(3), name)
    assert tree_digest(tmp_path / "lib") == before


def test_duplicate_names_refused_ignoring_case(library, tmp_path):
    before = tree_digest(tmp_path / "lib")
    for name in ("pour", "POUR"):
        with pytest.raises(InputError, match="already"):
            library.add(make_demo(3), name)
    assert tree_digest(tmp_path / "lib") == before


def test_motionless_and_invalid_demonstrations_refused(library, tmp_path):
    before = tree_digest(tmp_path / "lib")
    still = Demonstration("still", np.arange(5.0), np.tile(Q_HOME, (5, 1)))
    with pytest.raises(InputError, match="does not move"):
        library.add(still, "still")
    backwards = make_demo(3)
    backwards = Demonstration("b", backwards.timestamps[::-1], backwards.joint_positions)
    with pytest.raises(InputError, match="strictly increase"):
        library.add(backwards, "backwards")
    assert tree_digest(tmp_path / "lib") == before


# ---------------------------------------------------------------------- durability


class Crash(Exception):
    pass


@pytest.mark.parametrize("failing_call", [1, 2])
def test_crash_mid_add_leaves_library_intact(library, tmp_path, monkeypatch, failing_call):
    """os.replace fails on the log (1) or on the manifest (2): nothing changes."""
    root = tmp_path / "lib"
    before = tree_digest(root)
    real_replace = os.replace
    calls = []

    def crashing_replace(source, destination):
        calls.append(destination)
        if len(calls) == failing_call:
            raise Crash("power cut")
        return real_replace(source, destination)

    monkeypatch.setattr(os, "replace", crashing_replace)
    with pytest.raises(Crash):
        library.add(make_demo(5), "stack", "stacking")
    monkeypatch.setattr(os, "replace", real_replace)
    assert str(calls[-1]).endswith("stack.csv" if failing_call == 1 else "library.json")
    assert tree_digest(root) == before
    reopened = mut.Library.open(root)
    assert reopened.names == ("screw_cw", "pour")
    np.testing.assert_array_equal(reopened.demonstration("pour").joint_positions, make_demo(2).joint_positions)
    reopened.add(make_demo(5), "stack")  # and it can still be extended
    assert mut.Library.open(root).names == ("screw_cw", "pour", "stack")


def test_crash_mid_remove_leaves_library_intact(library, tmp_path, monkeypatch):
    root = tmp_path / "lib"
    before = tree_digest(root)

    def crashing_replace(source, destination):
        raise Crash("power cut")

    monkeypatch.setattr(os, "replace", crashing_replace)
    with pytest.raises(Crash):
        library.remove("pour")
    monkeypatch.undo()
    assert tree_digest(root) == before
    assert mut.Library.open(root).names == ("screw_cw", "pour")


def test_unreferenced_log_from_a_crash_is_ignored_then_overwritten(library, tmp_path):
    root = tmp_path / "lib"
    (root / "demos" / "stack.csv").write_text("half a log")  # killed between log and manifest
    reopened = mut.Library.open(root)
    assert reopened.names == ("screw_cw", "pour")
    reopened.add(make_demo(5), "stack")
    np.testing.assert_array_equal(
        mut.Library.open(root).demonstration("stack").joint_positions, make_demo(5).joint_positions
    )


# ----------------------------------------------------------------- corrupt manifests


def corrupt(root, change):
    manifest = root / "library.json"
    data = json.loads(manifest.read_text())
    change(data)
    manifest.write_text(json.dumps(data))


def test_bad_json_names_line(library, tmp_path):
    manifest = tmp_path / "lib" / "library.json"
    manifest.write_text(manifest.read_text()[:-20])
    with pytest.raises(InputError, match=r"library\.json: line \d+ column \d+: not valid JSON"):
        mut.Library.open(tmp_path / "lib")


@pytest.mark.parametrize(
    "change, field",
    [
        (lambda d: d.update(schema_version=2), "schema_version"),
        (lambda d: d.pop("X_tool0_E"), "X_tool0_E"),
        (lambda d: d["X_tool0_E"].update(q_wxyz=[1, 1, 0, 0]), "X_tool0_E.q_wxyz"),
        (lambda d: d["X_tool0_E"].update(p=[0, float("nan"), 0]), "X_tool0_E.p[1]"),
        (lambda d: d["demos"][1].pop("samples"), "demos[1].samples"),
        (lambda d: d["demos"][0].update(file="demos/absent.csv"), "demos[0].file"),
        (lambda d: d["demos"][0].update(file="../../etc/passwd"), "demos[0].file"),
        (lambda d: d["demos"][1].update(name="screw_cw"), "demos[1].name"),
        (lambda d: d["demos"][0].update(colour="red"), "demos[0].colour"),
        (lambda d: d.update(demos={}), "demos"),
    ],
)
def test_corrupt_manifest_names_file_and_field(library, tmp_path, change, field):
    corrupt(tmp_path / "lib", change)
    with pytest.raises(InputError) as info:
        mut.Library.open(tmp_path / "lib")
    assert f"library.json: {field}:" in str(info.value)


def test_missing_log_is_refused(library, tmp_path):
    (tmp_path / "lib" / "demos" / "pour.csv").unlink()
    with pytest.raises(InputError, match=r"demos\[1\]\.file: the joint log demos/pour.csv is missing"):
        mut.Library.open(tmp_path / "lib")


def test_damaged_log_is_refused_when_read(library, tmp_path):
    log = tmp_path / "lib" / "demos" / "pour.csv"
    log.write_text(log.read_text()[:-30])
    with pytest.raises(InputError, match="pour.csv"):
        mut.Library.open(tmp_path / "lib").demonstration("pour")


# ------------------------------------------------------------------ names and frames


def test_unknown_library_lists_what_was_tried(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError) as info:
        mut.Library.open("no_such_bundle")
    message = str(info.value)
    assert message.startswith("no_such_bundle: no such library")
    assert str(tmp_path / "no_such_bundle") in message
    for directory in mut.bundled_library_directories():
        assert str(directory) in message
    with pytest.raises(InputError, match="not a drake-lfd library"):
        mut.Library.open(tmp_path)


def test_bundled_library_by_name_is_read_only(library, tmp_path, monkeypatch):
    bundled = tmp_path / "bundled"
    bundled.mkdir()
    os.replace(tmp_path / "lib", bundled / "mine")
    folders = lambda: (tmp_path / "nowhere", bundled)  # noqa: E731
    monkeypatch.setattr(store, "bundled_library_directories", folders)  # where Library.open looks
    monkeypatch.setattr(resources, "bundled_library_directories", folders)  # where the names are listed
    monkeypatch.chdir(tmp_path)
    assert mut.bundled_library_names() == ["mine"]
    dut = mut.Library.open("mine")
    assert dut.read_only and dut.label == "mine"
    before = tree_digest(bundled)
    assert dut.feature("pour") is not None
    assert dut.write_feature_caches() == ()
    with pytest.raises(InputError, match="read-only"):
        dut.add(make_demo(4), "stack")
    with pytest.raises(InputError, match="read-only"):
        dut.remove("pour")
    assert tree_digest(bundled) == before


def test_create_refuses_existing_content(library, tmp_path):
    with pytest.raises(InputError, match="already"):
        mut.Library.create(tmp_path / "lib")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "notes.txt").write_text("x")
    with pytest.raises(InputError, match="not empty"):
        mut.Library.create(tmp_path / "full")
    (tmp_path / "empty").mkdir()
    assert mut.Library.create(tmp_path / "empty").names == ()
    assert mut.Library.open(tmp_path / "empty").names == ()


def test_end_effector_frame_mismatch_refused(library):
    mut.check_end_effector_frame(library, RigidTransform(X_TOOL0_E), "task.yaml")
    moved = RigidTransform(X_TOOL0_E.rotation(), X_TOOL0_E.translation() + [0, 0, 1e-6])
    with pytest.raises(InputError) as info:
        mut.check_end_effector_frame(library, moved, "task.yaml")
    assert str(info.value).startswith("task.yaml: X_tool0_E: ")
    with pytest.raises(InputError, match="X_tool0_E"):
        mut.check_end_effector_frame(library, RigidTransform(), "task.yaml")


# ------------------------------------------------------------------- pose records


def test_pose_json_round_trip():
    pose = pose_json_from_rigid_transform(X_TOOL0_E)
    assert set(pose) == {"p", "q_wxyz"} and pose["q_wxyz"][0] >= 0
    json.dumps(pose)  # plain floats
    X = rigid_transform_from_pose_json(pose)
    np.testing.assert_allclose(X.GetAsMatrix4(), X_TOOL0_E.GetAsMatrix4(), atol=1e-15)
    slightly_off = dict(pose, q_wxyz=[v * (1 + 5e-7) for v in pose["q_wxyz"]])
    np.testing.assert_allclose(
        rigid_transform_from_pose_json(slightly_off).GetAsMatrix4(), X_TOOL0_E.GetAsMatrix4(), atol=1e-6
    )


@pytest.mark.parametrize(
    "value, field",
    [
        ({"p": [0, 0], "q_wxyz": [1, 0, 0, 0]}, "X.p"),
        ({"p": [0, 0, "a"], "q_wxyz": [1, 0, 0, 0]}, "X.p[2]"),
        ({"p": [0, 0, 0], "q_wxyz": [1, 0, 0, float("inf")]}, "X.q_wxyz[3]"),
        ({"p": [0, 0, 0], "q_wxyz": [1, 0.01, 0, 0]}, "X.q_wxyz"),
        ({"p": [0, 0, 0]}, "X"),
        ({"p": [0, 0, 0], "q_wxyz": [1, 0, 0, 0], "rpy": [0, 0, 0]}, "X"),
        ([0, 0, 0], "X"),
    ],
)
def test_pose_json_refusals_name_the_field(value, field):
    with pytest.raises(InputError) as info:
        rigid_transform_from_pose_json(value, file="f.json", field="X")
    assert str(info.value).startswith(f"f.json: {field}: ")


# ------------------------------------------------------------ many demonstrations


def test_open_reads_no_log_whose_stamp_is_its_cache_row(library, tmp_path, monkeypatch):
    """The cache row vouches for an unchanged log (size, times, inode); a log touched since
    is read and checked again, and one edited by hand is refused as before."""
    root = tmp_path / "lib"
    read = []
    real = store.log_sample_summary
    monkeypatch.setattr(store, "log_sample_summary", lambda data, path: read.append(str(path)) or real(data, path))
    assert mut.Library.open(root).names == ("screw_cw", "pour")
    assert read == []
    log = root / "demos" / "pour.csv"
    os.utime(log, ns=(1, 1))  # the same bytes, another stamp
    assert mut.Library.open(root).names == ("screw_cw", "pour")
    assert read == [str(log)]
    log.write_text("\n".join(log.read_text().splitlines()[:-1]) + "\n")  # one sample less
    with pytest.raises(InputError, match=r"demos\[1\].samples: is 60 but the joint log demos/pour.csv has 59"):
        mut.Library.open(root)


def test_many_demonstrations_are_added_in_one_turn_of_the_lock(library, tmp_path):
    root = tmp_path / "lib"
    pending = [library.prepare(make_demo(10 + i), f"bulk{i}") for i in range(12)]  # >= 8: one sync for all
    pending.append(library.prepare(make_demo(30), "POUR"))  # taken, ignoring case
    pending.append(library.prepare(make_demo(31), "bulk3"))  # repeated
    added, refused = library.add_prepared(pending)
    assert [entry.name for entry in added] == [f"bulk{i}" for i in range(12)]
    assert [(position, "already" in str(error)) for position, error in refused] == [(12, True), (13, True)]
    reopened = mut.Library.open(root)
    assert reopened.names == ("screw_cw", "pour", *(f"bulk{i}" for i in range(12)))
    np.testing.assert_array_equal(reopened.demonstration("bulk7").joint_positions, make_demo(17).joint_positions)
    assert sorted(cache_rows(root)) == sorted(reopened.names)
    features = mut.library_features(reopened)
    np.testing.assert_array_equal(features["bulk7"].deltas, pending[7].feature.deltas)


def test_a_crash_while_adding_many_adds_none_of_them(library, tmp_path, monkeypatch):
    root = tmp_path / "lib"
    before = tree_digest(root)
    pending = [library.prepare(make_demo(40 + i), f"many{i}") for i in range(9)]

    def crash(*args):
        raise Crash("power cut")

    monkeypatch.setattr(store, "write_manifest", crash)
    with pytest.raises(Crash):
        library.add_prepared(pending)
    monkeypatch.undo()
    assert tree_digest(root) == before
    assert mut.Library.open(root).names == ("screw_cw", "pour")


def test_one_feature_is_read_by_name_from_the_cache(library, tmp_path, monkeypatch):
    """Reading one demonstration's feature reads its row, not the whole cache, and no log
    is recomputed."""
    root = tmp_path / "lib"
    dut = mut.Library.open(root)
    monkeypatch.setattr(mut.Library, "_compute_feature", lambda self, demo: pytest.fail("recomputed"))
    queries = []
    real_connect = sqlite3.connect

    def connect(*args, **kwargs):
        connection = real_connect(*args, **kwargs)
        connection.set_trace_callback(queries.append)
        return connection

    monkeypatch.setattr(sqlite3, "connect", connect)
    feature = dut.feature("pour")
    assert any("WHERE name IN" in query for query in queries)
    np.testing.assert_array_equal(feature.deltas.ravel(), np.frombuffer(cache_rows(root)["pour"][3]))


# ------------------------------------------------------------------- bulk add in Python


def test_add_many_returns_a_typed_report(library, tmp_path):
    """``Library.add_many``: each valid log added, each other one refused with a kind from
    a closed set and a reason; progress after each log; the library holds exactly the
    added ones."""
    from drake_lfd.io.bulk_add import BAD_LOG, NAME_TAKEN, NOT_FOUND, REFUSAL_KINDS, AddManyReport
    from drake_lfd.io.demonstration_logs import rtde_csv_text

    logs = tmp_path / "logs"
    logs.mkdir()
    for index, name in enumerate(["alpha", "beta", "pour"]):
        (logs / f"{name}.csv").write_text(rtde_csv_text(make_demo(50 + index, name=name)))
    (logs / "broken.csv").write_text("")
    calls = []
    report = library.add_many([logs, tmp_path / "absent.csv"], "bulk",
                              progress=lambda *counts: calls.append(counts))
    assert isinstance(report, AddManyReport) and report.library is library and report.logs == 5
    assert [added.entry.name for added in report.added] == ["alpha", "beta"]
    assert [(str(r.path), r.kind) for r in report.refused] == [
        (str(tmp_path / "absent.csv"), NOT_FOUND), (str(logs / "broken.csv"), BAD_LOG), (str(logs / "pour.csv"), NAME_TAKEN)]
    assert all(r.kind in REFUSAL_KINDS and "\n" not in r.reason for r in report.refused)
    assert report.refusal_counts() == {NOT_FOUND: 1, BAD_LOG: 1, NAME_TAKEN: 1}
    assert calls[0] == (0, 4, 0, 1) and calls[-1] == (4, 4, 2, 3)
    assert mut.Library.open(tmp_path / "lib").names == ("screw_cw", "pour", "alpha", "beta")
    assert mut.Library.open(tmp_path / "lib").entry("alpha").description == "bulk"


def test_create_many_creates_nothing_when_no_log_is_accepted(tmp_path):
    (tmp_path / "bad name.csv").write_text("x")
    report = mut.Library.create_many(tmp_path / "new", [tmp_path / "bad name.csv"], X_tool0_E=X_TOOL0_E)
    assert report.library is None and report.added == () and not (tmp_path / "new").exists()


def test_an_error_whose_fix_is_a_command_carries_it_as_a_hint(library, tmp_path):
    from drake_lfd.core.errors import Hint

    (tmp_path / "lib" / "demos" / "pour.csv").unlink()
    with pytest.raises(InputError) as info:
        mut.Library.open(tmp_path / "lib")
    assert info.value.hints == (Hint("library remove", (str(tmp_path / "lib"), "pour")),)
    assert f"drop the entry with 'drake-lfd library remove {tmp_path / 'lib'} pour'" in str(info.value)


def test_each_bundled_joint_log_is_stored_once():
    """In a checkout a bundled library's logs are links to ``sims/demos/<name>.csv`` (an
    installed wheel holds copies); the library opens by name and by path, and a link
    out of a user's library is still refused."""
    sims = resources.package_directory().parent / "sims"
    if not (sims / "libraries" / "paper6").is_dir():
        pytest.skip("not a source checkout")
    for name in ("paper5", "paper6"):
        for library in (mut.Library.open(name), mut.Library.open(sims / "libraries" / name)):
            for entry in library.entries:
                log = library.path / entry.file
                assert log.is_symlink() and log.resolve() == (sims / "demos" / f"{entry.name}.csv").resolve()
                library.demonstration(entry.name)


def test_a_log_linked_out_of_a_users_library_is_refused(library, tmp_path):
    root = tmp_path / "lib"
    outside = tmp_path / "outside.csv"
    os.replace(root / "demos" / "pour.csv", outside)
    (root / "demos" / "pour.csv").symlink_to(outside)
    with pytest.raises(InputError, match="not a path inside the library directory"):
        mut.Library.open(root)
