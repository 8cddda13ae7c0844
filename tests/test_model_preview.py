"""The UR5e Meshcat HTML is self-contained and, rendered headless, shows the arm."""

import re

import numpy as np
import pytest

import drake_lfd.cli as cli
from browser import CHROMIUM, fraction_of_hue, screenshot


def test_show_model_writes_self_contained_html(tmp_path):
    out = tmp_path / "ur5e.html"
    assert cli.main(["show-model", "--out", str(out)]) == 0
    html = out.read_text()
    assert "<html" in html.lower()
    # Offline: no script or stylesheet fetched from the network.
    assert not re.search(r"<script[^>]+src=\"https?://", html)
    assert not re.search(r"<link[^>]+href=\"https?://", html)
    assert len(html) > 1_000_000  # three.js and the scene are inlined


def test_show_model_refuses_bad_configuration(tmp_path, capsys):
    code = cli.main(["show-model", "--out", str(tmp_path / "x.html"), "--q", "0", "0", "nan", "0", "0", "0"])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--q" in err[0]


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (installed by .ci/run)")
def test_screenshot_shows_the_arm(tmp_path):
    out = tmp_path / "ur5e.html"
    assert cli.main(["show-model", "--out", str(out)]) == 0
    image = screenshot(out, tmp_path / "ur5e.png")
    # Not blank: the UR's blue joint caps cover well over the ~0.01% of the axis triad.
    assert fraction_of_hue(image, channel=2) > 0.001
    assert np.std(image[..., :3]) > 0.05
