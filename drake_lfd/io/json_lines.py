"""Results written as they come: a JSON-lines file, one record per line, each on disk
before the next.

``simulate --json OUT.json`` and ``paper --out DIR`` append every finished trial to a
JSON-lines file (:func:`json_lines_path_for`: ``OUT.jsonl`` beside ``OUT.json``;
``DIR/trials.jsonl`` for ``paper``), so an interrupt, a crash or a late error keeps every
trial that finished. Each :meth:`JsonLinesFile.append` writes one line of strict JSON
(:func:`~drake_lfd.io.strict_json.strict_json_text`), flushes it and fsyncs the file: a
reader sees whole lines only, except at worst a last line cut by a power loss, which a
reader should skip. The file is started afresh (truncated) when opened.

Not for: the final documents (:func:`~drake_lfd.io.strict_json.write_json`, atomic).
"""

from __future__ import annotations

import os
from pathlib import Path

from drake_lfd.io.atomic_files import fsync_directory
from drake_lfd.io.strict_json import strict_json_text

__all__ = ["json_lines_path_for", "JsonLinesFile", "read_json_lines"]


def json_lines_path_for(json_path: str | Path) -> Path:
    """The JSON-lines file beside a final JSON: ``OUT.jsonl`` for ``OUT.json``, otherwise
    the name with ``.jsonl`` added (``results`` -> ``results.jsonl``)."""
    json_path = Path(json_path)
    if json_path.suffix.lower() == ".json":
        return json_path.with_suffix(".jsonl")
    return json_path.with_name(json_path.name + ".jsonl")


class JsonLinesFile:
    """``with JsonLinesFile(path) as lines: lines.append(record)``; each record is on
    disk (flushed and fsynced) when ``append`` returns."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.count = 0
        self._file = open(self.path, "w", encoding="utf-8")
        fsync_directory(self.path.parent)

    def append(self, record) -> None:
        """Writes ``record`` as one line of strict JSON and forces it to disk."""
        try:
            self._file.write(strict_json_text(record, indent=None) + "\n")
            self._file.flush()
            os.fsync(self._file.fileno())
        except OSError as error:  # a full disk: name the file
            raise OSError(error.errno, error.strerror or str(error), str(self.path)) from None
        self.count += 1

    def records_on_disk(self) -> int:
        """How many whole records the file holds now (an interrupt may fall between a
        line reaching the file and :attr:`count` counting it, and signals reach any
        thread, so this is what an interrupted run reports)."""
        try:
            self._file.flush()
        except (OSError, ValueError):
            pass
        return len(read_json_lines(self.path))

    def close(self) -> None:
        if not self._file.closed:
            try:
                self._file.close()
            except OSError:  # already reported by append, or nothing left to write
                pass

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()
        return False


def read_json_lines(path: str | Path) -> list:
    """The records of a JSON-lines file; a last line cut short (no newline, not JSON)
    is skipped."""
    import json

    records = []
    text = Path(path).read_text(encoding="utf-8")
    lines = text.split("\n")
    for index, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError:
            if index == len(lines) - 1:  # the last line, cut short
                break
            raise
    return records
