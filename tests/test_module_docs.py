"""Every module is named in its sub-package's docstring, and the exported names import.

Each sub-package of ``drake_lfd`` (one per layer) says in its docstring what each of its
modules is for. The check lists the module files on disk, so a module added without a
line in the docstring fails it. A module counts as named when it appears as an inline
literal: ``joint_path_source`` or ``planner.PlannerSystem`` (its name, then optionally
a dotted attribute), not merely as an ordinary English word ("library", "plan").

``drake_lfd.systems`` and ``drake_lfd.diagrams`` export their public systems and
Diagram helpers; every name in their ``__all__`` must import from the package.
"""

from __future__ import annotations

import ast
import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parent.parent
PACKAGE = REPOSITORY / "drake_lfd"
LAYERS = ("core", "robot", "planning", "io", "systems", "diagrams", "experiments", "cli")

SYSTEMS_EXPORTS = (
    "DemoRecorder", "FeatureLibrarySystem", "LibraryFeatures", "PlannerSystem", "NO_PLAN",
    "JointPathSource", "JointTrajectoryController", "PlanTrajectorySource",
    "DifferentialIKController", "ShellMonitor", "TrialEnd", "VirtualHand",
    "demonstration_from_log", "add_joint_logger",
)
DIAGRAMS_EXPORTS = (
    "Station", "build_station", "Pipeline", "build_pipeline", "TrialStart", "joint_path_checker",
    "ClosedLoopRunner", "run_closed_loop", "plan_through_joint_configurations",
    "ClosedLoopResult", "CriticalError", "judge_run", "RunJudgement",
)


def package_docstring(layer: str) -> str:
    """The docstring of ``drake_lfd/<layer>/__init__.py``, read without importing it."""
    source = (PACKAGE / layer / "__init__.py").read_text(encoding="utf-8")
    return ast.get_docstring(ast.parse(source)) or ""


def module_names(layer: str) -> list[str]:
    """The modules of a sub-package, from its files (``__init__`` left out)."""
    return sorted(path.stem for path in (PACKAGE / layer).glob("*.py") if path.stem != "__init__")


def names_module(docstring: str, module: str) -> bool:
    """Whether the docstring names ``module`` as a literal: ````module```` or
    ````module.Attribute````, whole words only."""
    return re.search(r"``" + re.escape(module) + r"(\.[A-Za-z_][A-Za-z0-9_]*)*``", docstring) is not None


def test_the_layers_are_the_sub_packages():
    on_disk = sorted(path.parent.name for path in PACKAGE.glob("*/__init__.py")
                     if path.parent.name not in ("models", "sims"))
    assert on_disk == sorted(LAYERS)


@pytest.mark.parametrize("layer", LAYERS)
def test_every_module_is_named_in_its_package_docstring(layer):
    docstring = package_docstring(layer)
    assert docstring.startswith(f"Layer {LAYERS.index(layer) + 1}, "), "the layer sentence comes first"
    missing = [module for module in module_names(layer) if not names_module(docstring, module)]
    assert not missing, (
        f"drake_lfd/{layer}/__init__.py names no ``module`` literal for: {', '.join(missing)}; "
        "add a line with its role to the docstring")


def test_the_check_wants_the_module_as_a_literal():
    assert names_module("* ``planner``: the planner system.", "planner")
    assert names_module("``planner.PlannerSystem`` -> ...", "planner")
    assert not names_module("the planner plans", "planner")
    assert not names_module("``planner_x``", "planner")
    assert not names_module("``drake_lfd.planning.planner``", "planning")
    assert not names_module("``library_source``", "library")


@pytest.mark.parametrize("layer", ["systems", "diagrams", "planning", "robot"])
def test_the_pipeline_is_drawn(layer):
    """The sub-packages on the default pipeline draw it as an arrow chain (``--...-->``)
    and name the paper's baseline beside it."""
    docstring = package_docstring(layer)
    assert re.search(r"--\S.*-->", docstring), "an arrow chain"
    assert "baseline" in docstring


@pytest.mark.parametrize("package, names", [("drake_lfd.systems", SYSTEMS_EXPORTS),
                                            ("drake_lfd.diagrams", DIAGRAMS_EXPORTS)])
def test_the_exported_names_import(package, names):
    module = importlib.import_module(package)
    assert set(names) <= set(module.__all__)
    for name in module.__all__:
        value = getattr(module, name)
        defined_in = getattr(value, "__module__", None)
        if defined_in is not None and isinstance(value, type):
            assert defined_in.startswith(package + "."), (name, defined_in)


def test_from_package_import_star():
    """``from drake_lfd.diagrams import *`` works though its names load on first use."""
    code = ("from drake_lfd.systems import *\nfrom drake_lfd.diagrams import *\n"
            f"print(all(n in globals() for n in {SYSTEMS_EXPORTS + DIAGRAMS_EXPORTS!r}))")
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                               timeout=120, cwd=REPOSITORY)
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout.strip() == "True"
