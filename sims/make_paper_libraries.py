"""Re-record the paper's demonstrations and rebuild the bundled libraries.

    python sims/make_paper_libraries.py [--skip-recording]

For each guidance script ``sims/demos/<name>.yaml`` (the paper's five demonstrations of
Fig. 5 and the sixth, ``span``, that the assembling task asks for) this simulates the
kinesthetic demonstration (``drake_lfd.diagrams.kinesthetic``, the same as ``drake-lfd record``)
and writes ``sims/demos/<name>.csv``; then it builds

- ``sims/libraries/paper5/``: screw_cw, screw_ccw, filling, pouring, stacking;
- ``sims/libraries/paper6/``: the same plus span,

with the ``X_tool0_E`` the scripts share (the paper scenarios' end-effector frame).
Each joint log is stored once: a library's ``demos/<name>.csv`` is a symbolic link to
``sims/demos/<name>.csv`` (checked byte for byte against what the library would have
written). An installed wheel holds copies (setuptools follows the links), so
``Library.open("paper5")`` works offline there too.
Everything is seeded (each script carries its seed) and the simulation is
deterministic, so re-running reproduces the joint logs byte for byte; only the
manifests' ``added`` times change. Each library is built in a temporary directory beside
the old one and swapped in at the end, so an interrupted run leaves the old library.
The feature caches (derived data) are not kept in the bundled libraries.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from pathlib import Path

from drake_lfd.io.demonstration_logs import read_rtde_csv, write_rtde_csv
from drake_lfd.io.guidance_scripts import load_guidance_script
from drake_lfd.diagrams.kinesthetic import record_demonstration
from drake_lfd.io.library import Library
from drake_lfd.io.library_manifest import CACHE_DIRECTORY, LOCK_NAME

HERE = Path(__file__).resolve().parent
DEMOS_DIRECTORY = HERE / "demos"
LIBRARIES_DIRECTORY = HERE / "libraries"
PAPER5 = ("screw_cw", "screw_ccw", "filling", "pouring", "stacking")
PAPER6 = PAPER5 + ("span",)
LIBRARIES = {"paper5": PAPER5, "paper6": PAPER6}


def record_all(names=PAPER6, *, out=print):
    """Records every demonstration from its script; returns {name: wall time (s)}."""
    wall_times = {}
    for name in names:
        script = load_guidance_script(DEMOS_DIRECTORY / f"{name}.yaml")
        result = record_demonstration(script)
        write_rtde_csv(result.demonstration, DEMOS_DIRECTORY / f"{name}.csv")
        wall_times[name] = result.wall_time_s
        out(
            f"recorded {name}: {result.demonstration.num_samples} samples, {script.duration_s:.1f} s simulated "
            f"in {result.wall_time_s:.2f} s; tool within {1000 * result.max_position_error_m:.1f} mm of the hand"
        )
    return wall_times


def build_library(library_name, names, *, out=print):
    """Builds ``sims/libraries/<library_name>`` from ``sims/demos/<name>.csv``."""
    LIBRARIES_DIRECTORY.mkdir(parents=True, exist_ok=True)
    final = LIBRARIES_DIRECTORY / library_name
    staging = LIBRARIES_DIRECTORY / f".{library_name}.building"
    if staging.exists():
        shutil.rmtree(staging)
    scripts = {name: load_guidance_script(DEMOS_DIRECTORY / f"{name}.yaml") for name in names}
    X_tool0_E = scripts[names[0]].X_tool0_E
    for name, script in scripts.items():
        if not script.X_tool0_E.IsExactlyEqualTo(X_tool0_E):
            raise RuntimeError(f"{name}.yaml: X_tool0_E differs from {names[0]}.yaml's")
    library = Library.create(staging, X_tool0_E)
    for name in names:
        script = scripts[name]
        demonstration, warnings = read_rtde_csv(DEMOS_DIRECTORY / f"{name}.csv", name=name)
        if warnings:
            raise RuntimeError(f"{name}.csv: {warnings[0]}")
        library.add(demonstration, name, script.description)
    shutil.rmtree(staging / CACHE_DIRECTORY, ignore_errors=True)
    (staging / LOCK_NAME).unlink(missing_ok=True)  # (no writer: a bundled library is read-only)
    for entry in library.entries:  # each log stored once: a link to sims/demos/<name>.csv
        log, stored = staging / entry.file, DEMOS_DIRECTORY / f"{entry.name}.csv"
        if log.read_bytes() != stored.read_bytes():
            raise RuntimeError(f"{log}: differs from {stored}, which it would link to")
        log.unlink()
        log.symlink_to(os.path.relpath(stored, log.parent))
    retired = LIBRARIES_DIRECTORY / f".{library_name}.old"
    if retired.exists():
        shutil.rmtree(retired)
    if final.exists():
        final.rename(retired)
    staging.rename(final)
    shutil.rmtree(retired, ignore_errors=True)
    out(f"built {final} ({', '.join(names)})")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--skip-recording", action="store_true", help="rebuild the libraries from the existing sims/demos/*.csv"
    )
    args = parser.parse_args(argv)
    start = time.perf_counter()
    if not args.skip_recording:
        record_all()
    for library_name, names in LIBRARIES.items():
        build_library(library_name, names)
    print(f"done in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
