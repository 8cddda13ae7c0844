"""A minimal text progress bar on stderr (no dependency), quiet when not a terminal."""

from __future__ import annotations

import sys
import time

__all__ = ['ProgressBar']


class ProgressBar:
    """``bar = ProgressBar("training", total)``; ``bar.update(done)``; ``bar.close()``.

    On a terminal it redraws one line; otherwise it prints at most ~10 lines, or none
    with ``quiet_unless_terminal`` (for a command whose stderr is one line per problem).
    """

    def __init__(self, label: str, total: int, stream=None, width: int = 30, *, quiet_unless_terminal=False):
        self.label, self.total, self.width = label, max(int(total), 1), width
        self.stream = stream or sys.stderr
        self.interactive = getattr(self.stream, "isatty", lambda: False)()
        self.quiet = quiet_unless_terminal and not self.interactive
        self.start = time.perf_counter()
        self._last_tenth = -1
        self._last_draw = -1.0

    def update(self, done: int, note: str = "") -> None:
        if self.quiet:
            return
        fraction = min(max(done / self.total, 0.0), 1.0)
        elapsed = time.perf_counter() - self.start
        filled = int(round(fraction * self.width))
        line = f"{self.label} [{'#' * filled}{'.' * (self.width - filled)}] {done}/{self.total} {elapsed:5.1f} s {note}"
        if self.interactive:
            if done < self.total and elapsed - self._last_draw < 0.1:
                return  # redraw at most ten times a second
            self._last_draw = elapsed
            self.stream.write("\r" + line)
            self.stream.flush()
        elif int(fraction * 10) > self._last_tenth:
            self._last_tenth = int(fraction * 10)
            self.stream.write(line.rstrip() + "\n")

    def close(self) -> None:
        if self.interactive:
            self.stream.write("\n")
            self.stream.flush()
