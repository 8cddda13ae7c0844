"""A Meshcat for recordings only: made without announcing a viewer nobody will open.

Drake's ``Meshcat`` starts its web server when it is constructed and logs ``Meshcat
listening for connections at http://localhost:7000`` at the info level, through the
``drake`` Python logger. A recording (``simulate --html``, ``drake-lfd paper``) needs
the object (``StaticHtml`` after ``PublishRecording``) but nobody connects to it, so in a
batch job that line is noise, once per recorded pipeline. :func:`recording_meshcat`
raises the ``drake`` logger to warnings for the construction only; the live viewer
(``simulate --meshcat``) is made with the plain constructor and keeps the line.

Not for: drawing into Meshcat (``plan_markers.py``), or checking that Meshcat may run
at all (``core/network_policy.py``).
"""

from __future__ import annotations

import logging

from pydrake.geometry import Meshcat

__all__ = ["recording_meshcat"]


def recording_meshcat() -> Meshcat:
    """A new ``Meshcat`` (its server started as usual), without the listening line."""
    logger = logging.getLogger("drake")
    level = logger.level
    logger.setLevel(max(level, logging.WARNING))
    try:
        return Meshcat()
    finally:
        logger.setLevel(level)
