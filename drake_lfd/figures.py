"""Figures written on request (matplotlib, headless): training curves and more.

Not for: computing what is plotted.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def training_curve_figure(path, curve, *, steady_episode=None, title="Training (Fig. 7)") -> Path:
    """Average accumulated reward per episode over the training tasks, like Fig. 7."""
    curve = np.asarray(curve, dtype=float)
    figure, axes = plt.subplots(figsize=(6, 3.5))
    episodes = np.arange(1, len(curve) + 1)
    axes.plot(episodes, curve, lw=1, color="0.6", label="average over tasks")
    if len(curve) >= 10:
        moving = np.convolve(curve, np.ones(10) / 10, mode="valid")
        axes.plot(episodes[9:], moving, lw=2, color="C0", label="10-episode mean")
    if steady_episode is not None:
        axes.axvline(steady_episode, color="C3", ls="--", lw=1, label=f"steady from {steady_episode}")
    axes.set_xlabel("episode")
    axes.set_ylabel("accumulated reward")
    axes.set_title(title)
    axes.legend(loc="lower right", fontsize=8)
    figure.tight_layout()
    path = Path(path)
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path
