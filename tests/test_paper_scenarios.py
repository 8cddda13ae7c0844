"""The paper's scenarios (sims/*.yaml) with the bundled libraries plan as the paper says."""

import json
from pathlib import Path

import numpy as np
import pytest

import drake_lfd.cli as cli

SIMS = Path(__file__).resolve().parent.parent / "sims"
if not (SIMS / "assembling.yaml").is_file():  # installed package: scenarios ship inside it
    import drake_lfd.sims

    SIMS = Path(drake_lfd.sims.__file__).parent


def plan(tmp_path, scenario, library, *extra):
    out = tmp_path / f"{scenario}_{library}.json"
    code = cli.main(["plan", str(SIMS / f"{scenario}.yaml"), "--library", library, "--json", str(out), *extra])
    return code, json.loads(out.read_text())


def test_assembling_requests_a_quarter_turn_about_body_x_with_paper5(tmp_path):
    code, document = plan(tmp_path, "assembling", "paper5")
    assert code == 3
    assert document["status"] == "demonstration_requested"
    (request,) = document["uncovered"]
    assert (request["from"], request["to"]) == (2, 3)
    np.testing.assert_allclose(np.abs(request["axis"]), [1, 0, 0], atol=1e-9)
    assert np.degrees(request["angle_rad"]) == pytest.approx(90)


def test_assembling_uses_span_with_paper6(tmp_path):
    code, document = plan(tmp_path, "assembling", "paper6")
    assert code == 0
    composition = [(c["demo"], c["from"], c["to"]) for c in document["composition"]]
    assert ("span", 2, 3) in composition
