"""Headless-Chromium screenshots of Meshcat HTML recordings, for tests.

Chromium comes from Debian's package (``.ci/run`` installs it); tests that need it skip
when it is absent. Flags as measured on this kind of machine (a virtual-time budget of 0 hangs;
background networking must be off on this closed network).
"""

import os
import shutil
import signal
import subprocess
from pathlib import Path

import numpy as np

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def screenshot(html: Path, png: Path, *, budget_ms: int = 4500, size=(800, 600),
               attempts: int = 3, timeout_s: float = 40.0) -> np.ndarray:
    """Renders ``html`` headless, writes ``png`` and returns its pixels (h, w, channels).

    Headless Chromium occasionally hangs at start-up on this machine (seen twice in a few
    hundred runs); a hung attempt is killed with its whole process group and retried with
    a fresh profile.
    """
    import matplotlib.image

    for attempt in range(attempts):
        command = [
            CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--no-first-run", f"--user-data-dir={png.parent / f'chromium-profile-{attempt}'}",
            f"--virtual-time-budget={budget_ms}", f"--window-size={size[0]},{size[1]}",
            f"--screenshot={png}", html.resolve().as_uri(),
        ]
        process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                   start_new_session=True)
        try:
            process.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
            continue
        if process.returncode == 0 and png.is_file():
            return matplotlib.image.imread(png)
    raise RuntimeError(f"chromium could not render {html} in {attempts} attempts")


def fraction_of_hue(image: np.ndarray, channel: int, margin: float = 0.12) -> float:
    """Fraction of pixels whose ``channel`` (0 red, 1 green, 2 blue) exceeds both others
    by ``margin``: a robust "is there something of this colour" measure under lighting."""
    rgb = image[..., :3]
    others = np.delete(rgb, channel, axis=-1).max(axis=-1)
    return float(np.mean(rgb[..., channel] - others > margin))


def fraction_of_purple(image: np.ndarray, margin: float = 0.08) -> float:
    """Fraction of pixels where red and blue both exceed green by ``margin`` (the
    translucent purple of the safety shells)."""
    rgb = image[..., :3]
    return float(np.mean(np.minimum(rgb[..., 0], rgb[..., 2]) - rgb[..., 1] > margin))
