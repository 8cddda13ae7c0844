"""A minimal text progress bar on stderr (no dependency), quiet when not a terminal."""

from __future__ import annotations

import sys
import time

__all__ = ['ProgressBar']


class ProgressBar:
    """``bar = ProgressBar("training", total)``; ``bar.update(done)``; ``bar.close()``.

    On a terminal it redraws one line; otherwise it prints at most ~10 lines.
    """

    def __init__(self, label: str, total: int, stream=None, width: int = 30):
        self.label, self.total, self.width = label, max(int(total), 1), width
        self.stream = stream or sys.stderr
        self.interactive = getattr(self.stream, "isatty", lambda: False)()
        self.start = time.perf_counter()
        self._last_tenth = -1

    def update(self, done: int, note: str = "") -> None:
        fraction = min(max(done / self.total, 0.0), 1.0)
        elapsed = time.perf_counter() - self.start
        filled = int(round(fraction * self.width))
        line = f"{self.label} [{'#' * filled}{'.' * (self.width - filled)}] {done}/{self.total} {elapsed:5.1f} s {note}"
        if self.interactive:
            self.stream.write("\r" + line)
            self.stream.flush()
        elif int(fraction * 10) > self._last_tenth:
            self._last_tenth = int(fraction * 10)
            self.stream.write(line.rstrip() + "\n")

    def close(self) -> None:
        if self.interactive:
            self.stream.write("\n")
            self.stream.flush()
