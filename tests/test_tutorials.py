"""The tutorials (tutorials/*.py, and the same cells as tutorials/*.ipynb) run top to bottom
headless in their short mode, write their figures and recordings, and reach the outcome
their narrative promises; each notebook is in sync with its script.

Each tutorial is executed once, as its notebook (nbclient, the ``python3`` kernel), not
also as its script: the two are the same cells (the sync test holds them to it), and
the notebook run is the stricter one: it is where a kernel-only failure shows (Meshcat
and scipy imported in the wrong order once aborted the kernel of tutorial 4 while the
script ran), where the figures must display, and where the default ``--out`` is used.
What only the script form has, its command line, is covered without running the
tutorial: each script is run until it has parsed ``--short --out DIR`` and stopped
there (:func:`test_each_script_reads_short_and_out_from_its_command_line`). A second
run of tutorial 4 into the same folder, which must start its library afresh, is the
notebook run itself: its output folder holds a previous run's library beforehand.
"""

import asyncio
import json
import os
import runpy
import sys
from pathlib import Path

import numpy as np
import pytest

from drake_lfd.io.library import Library

TUTORIALS = Path(__file__).resolve().parent.parent / "tutorials"
STEMS = ("01_transferring", "02_filling_pouring", "03_assembling", "04_record_your_own", "05_real_robot",
         "06_compose_your_own_diagram")
# A notebook has no command line: this environment variable selects the short run.
SHORT = "DRAKE_LFD_TUTORIAL_SHORT"
REGENERATE = "jupytext --to ipynb tutorials/{stem}.py"

pytestmark = pytest.mark.skipif(not TUTORIALS.is_dir(), reason="tutorials/ ships with the repository, not the wheel")


def _summary(out):
    return json.loads((out / "summary.json").read_text())


def _assert_files(out, names):
    for name in names:
        path = out / name
        assert path.is_file() and path.stat().st_size > 0, f"{name} missing"


# -- what each tutorial must reach (summary.json, as written by the script or the notebook)
def _check_transferring(summary, out):
    _assert_files(out, ["transferring_plan.png", "transferring_joints.png", "transferring_trial1.html",
                        "transferring_trials.json"])
    assert "<html" in (out / "transferring_trial1.html").read_text()[:2000].lower()
    assert summary["plan_status"] == "planned"
    assert summary["trials"] == 1
    assert summary["successes"] == [True], summary["failures"]
    # The plan passes exactly through the critical configurations after a small bend.
    assert summary["max_correction_position_m"] < 0.01


def _check_filling_pouring(summary, out):
    _assert_files(out, ["filling_pouring_plan.png", "filling_pouring_joints.png", "filling_pouring_training.png",
                        "filling_pouring_trial1.html", "filling_pouring_trials.json", "policy.json"])
    demos = [demo for demo, _, _ in summary["composition"]]
    assert demos[0] == "filling" and demos[-1].startswith("screw")
    assert len(summary["gamma_deg"]) == 3
    assert all(-180 <= g <= 180 for g in summary["gamma_deg"])
    for row in summary["q_vs_exact"]:  # the exact planner's cost is the optimum
        assert row["q_cost"] >= row["exact_cost"] - 1e-12
    assert summary["successes"] == [True], summary["failures"]


def _check_assembling(summary, out):
    _assert_files(out, ["assembling_request.json", "assembling_retraining.png", "assembling_plan.png",
                        "assembling_joints.png", "assembling_trial1.html", "policy_paper6.json"])
    assert summary["paper5_status"] == "demonstration_requested"
    assert summary["paper5_q_status"] == "demonstration_requested"
    ((con_from, con_to, axis, angle),) = summary["uncovered"]
    assert (con_from, con_to) == (2, 3)
    np.testing.assert_allclose(np.abs(axis), [1, 0, 0], atol=1e-9)
    assert np.degrees(angle) == pytest.approx(90)
    assert summary["paper6_status"] == "planned"
    assert ["span", 2, 3] in summary["composition"]
    assert summary["successes"] == [True], summary["failures"]


def _check_record_your_own(summary, out):
    _assert_files(out, ["roll_carry.yaml", "roll_carry.csv", "roll_carry_joints.png",
                        "roll_carry_demonstration.html", "assembling_plan.png", "assembling_trial1.html",
                        "summary.json"])
    assert summary["request"] == [[2, 3]]
    reopened = Library.open(out / "my_library")
    assert reopened.names == ("screw_cw", "screw_ccw", "filling", "pouring", "stacking", "roll_carry")
    assert summary["plan_status"] == "planned"
    assert ["roll_carry", 2, 3] in summary["composition"]
    assert list(summary["trials"]) == ["assembling"]  # the short run
    assert summary["trials"]["assembling"]["success"], summary["trials"]["assembling"]["failures"]


def _check_real_robot(summary, out):
    _assert_files(out, ["plan.json", "plan.script", "plan.csv", "plan.yaml", "exported_joints.png", "summary.json"])
    assert (out / "span_bag" / "metadata.yaml").is_file()
    assert summary["library"][-1] == "span_from_bag"
    assert summary["plan_status"] == "planned"
    assert ["span_from_bag", 2, 3] in summary["composition"]
    assert summary["slow_down"] >= 1.0 and summary["servoj_targets"] > 1000
    script = (out / "plan.script").read_text()
    assert "movej(" in script and "stopj(" in script


def _check_compose_your_own_diagram(summary, out):
    _assert_files(out, ["compose_joints.png", "summary.json"])
    assert summary["success"], summary["failures"]
    assert len(summary["composition"]) >= 1
    # The hand-built Diagram with a pass-through system of the user's commands what
    # build_pipeline's does, to the bit; the watchdog saw the command move.
    assert summary["same_as_pipeline"] is True
    assert 0.0 < summary["largest_command_step_rad"] < 0.1
    assert summary["log_samples"] > 100


CHECKS = {
    "01_transferring": _check_transferring,
    "02_filling_pouring": _check_filling_pouring,
    "03_assembling": _check_assembling,
    "04_record_your_own": _check_record_your_own,
    "05_real_robot": _check_real_robot,
    "06_compose_your_own_diagram": _check_compose_your_own_diagram,
}


def test_every_tutorial_is_tested_listed_and_has_its_notebook():
    scripts = sorted(p.stem for p in TUTORIALS.glob("[0-9][0-9]_*.py"))
    assert scripts == list(STEMS) == list(CHECKS)
    assert sorted(p.stem for p in TUTORIALS.glob("[0-9][0-9]_*.ipynb")) == scripts
    readme = (TUTORIALS / "README.md").read_text()
    for stem in scripts:
        assert f"{stem}.py" in readme and f"{stem}.ipynb" in readme


# -- the scripts' command line ------------------------------------------------------------
class _Parsed(Exception):
    """Stops a tutorial script once it has read its command line."""


@pytest.mark.parametrize("stem", STEMS)
def test_each_script_reads_short_and_out_from_its_command_line(stem, tmp_path, monkeypatch):
    """``python tutorials/STEM.py --short --out DIR`` selects the short run and DIR, read
    the way the notebook run reads its settings (``parse_tutorial_arguments``); the script
    is stopped right there, before it computes or writes anything."""
    from drake_lfd.experiments import notebooks

    parsed = {}
    parse = notebooks.parse_tutorial_arguments

    def parse_and_stop(parser):
        args, short = parse(parser)
        parsed.update(out=args.out, short=short)
        raise _Parsed

    script = TUTORIALS / f"{stem}.py"
    out = tmp_path / "out"
    monkeypatch.setattr(notebooks, "parse_tutorial_arguments", parse_and_stop)
    monkeypatch.setattr(sys, "argv", [str(script), "--short", "--out", str(out)])
    monkeypatch.delenv(SHORT, raising=False)
    with pytest.raises(_Parsed):
        runpy.run_path(str(script), run_name="__main__")
    assert parsed == {"out": str(out), "short": True}
    assert not out.exists()


# -- the notebooks -------------------------------------------------------------------------
@pytest.mark.parametrize("stem", STEMS)
def test_notebook_is_in_sync_with_its_script(stem):
    """The .ipynb has exactly the script's cells (jupytext's percent format: ``# %%``),
    with no outputs: regenerate it with ``jupytext --to ipynb`` after editing the script."""
    import jupytext
    import nbformat

    script = jupytext.read(TUTORIALS / f"{stem}.py", fmt="py:percent")
    notebook = nbformat.read(TUTORIALS / f"{stem}.ipynb", as_version=4)
    nbformat.validate(notebook)
    hint = f"tutorials/{stem}.ipynb is out of date: {REGENERATE.format(stem=stem)}"
    assert [(c.cell_type, c.source) for c in notebook.cells] == [(c.cell_type, c.source) for c in script.cells], hint
    assert sum(c.cell_type == "markdown" for c in notebook.cells) >= 5  # the narrative, not one big cell
    for cell in notebook.cells:
        if cell.cell_type == "code":
            assert cell.outputs == [] and cell.execution_count is None, f"{hint} (outputs must be cleared)"
    assert notebook.metadata.kernelspec.name == "python3"
    assert notebook.metadata.jupytext.formats == "ipynb,py:percent"


def _requested_notebooks(request):
    """The stems of the notebook tests this session runs (so ``-k`` runs only those)."""
    return sorted({item.callspec.params["stem"] for item in request.session.items
                   if getattr(item, "originalname", None) == "test_notebook_runs_in_short_mode"
                   and item.path == Path(__file__)})


def _previous_run(stem, out):
    """What a previous run of tutorial STEM left in its output folder ``out``: for
    tutorial 4, a library, which the run must replace (its check lists the library's
    demonstrations: "stale" must be gone)."""
    if stem == "04_record_your_own":
        paper5 = Library.open("paper5")
        stale = Library.create(out / "my_library", X_tool0_E=paper5.X_tool0_E)
        stale.add(paper5.demonstration("stacking"), "stale")


async def _execute_all(stems, root, parallel):
    """Executes tutorials/STEM.ipynb for every stem, ``parallel`` kernels at a time, each
    in its own working directory under ``root`` (where the tutorial's default ``--out``,
    ``tutorials_out/STEM``, lands) with the short run selected by the environment."""
    import nbformat
    from nbclient import NotebookClient

    env = dict(os.environ, **{SHORT: "1"})
    gate = asyncio.Semaphore(parallel)

    async def one(stem):
        work = root / stem
        work.mkdir()
        _previous_run(stem, work / "tutorials_out" / stem)
        for attempt in range(2):
            notebook = nbformat.read(TUTORIALS / f"{stem}.ipynb", as_version=4)
            # One more cell, so the test can tell the kernel runs this environment's Python.
            notebook.cells.append(nbformat.v4.new_code_cell("import sys\nprint(sys.prefix)"))
            client = NotebookClient(notebook, kernel_name="python3", timeout=600, startup_timeout=120,
                                    resources={"metadata": {"path": str(work)}})
            async with gate:
                try:
                    await client.async_execute(env=env)
                except Exception as error:  # noqa: BLE001 - reported by the test of this notebook
                    # A kernel process that died (seen once in CI, with two kernels on two
                    # loaded cores) is given one more run; any other error is the notebook's.
                    if type(error).__name__ == "DeadKernelError" and attempt == 0:
                        continue
                    return stem, work / "tutorials_out" / stem, notebook, error
            return stem, work / "tutorials_out" / stem, notebook, None

    return {stem: result for stem, *result in await asyncio.gather(*(one(stem) for stem in stems))}


@pytest.fixture(scope="module")
def executed_notebooks(request, tmp_path_factory):
    stems = _requested_notebooks(request)
    parallel = max(1, min(len(stems), os.cpu_count() or 1))
    return asyncio.run(_execute_all(stems, tmp_path_factory.mktemp("notebooks"), parallel))


@pytest.mark.slow
@pytest.mark.parametrize("stem", STEMS)
def test_notebook_runs_in_short_mode(stem, executed_notebooks):
    """Each notebook runs headless (nbclient, the ``python3`` kernel ipykernel provides)
    with ``DRAKE_LFD_TUTORIAL_SHORT=1`` and reaches what its script does."""
    out, notebook, error = executed_notebooks[stem]
    if error is not None:
        raise AssertionError(f"tutorials/{stem}.ipynb failed:\n{error}")
    errors = [o for c in notebook.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors, errors
    prefix = "".join(o.get("text", "") for o in notebook.cells[-1].outputs).strip()
    assert Path(prefix) == Path(sys.prefix), "the python3 kernel ran another environment's Python"
    # The figures were shown in the notebook, not only written.
    assert any("image/png" in o.get("data", {}) for c in notebook.cells if c.cell_type == "code" for o in c.outputs)
    summary = _summary(out)
    assert summary["short"] is True
    CHECKS[stem](summary, out)
