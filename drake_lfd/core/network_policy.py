"""Drake's network switch, ``DRAKE_ALLOW_NETWORK``, read the way Drake reads it.

Drake (1.51) consults the environment variable ``DRAKE_ALLOW_NETWORK`` before anything
that may use the network: unset or empty allows everything; ``none`` allows nothing;
otherwise it is a ``:``-separated list of what is allowed, ``package_map`` (downloads of
remote model packages such as ``drake_models``) and ``meshcat`` (Meshcat's local web
server). drake-lfd needs neither to plan or simulate:

* its UR5e model is shipped with it, so it never resolves ``package://drake_models``;
  but Drake refuses to construct any ``Parser`` while downloads are disallowed and
  ``drake_models`` is not in its download cache. ``robot/kinematics.make_parser`` lifts
  the switch only while the Parser is constructed (nothing is downloaded then: Drake
  fetches a package only when one of its files is asked for) and then removes
  ``drake_models`` from that Parser, so no file of it can be asked for;
* a Meshcat recording (``simulate --html``, ``show-model``, the recordings of
  ``paper``) needs Meshcat, which Drake refuses when ``meshcat`` is not allowed: the
  command line says so in one line (:func:`meshcat_refusal`) before doing any work, and
  ``paper`` skips its recordings with a note.

Not for: anything else about the environment.
"""

from __future__ import annotations

import os
from typing import Mapping

__all__ = ["NETWORK_VARIABLE", "drake_allows", "meshcat_refusal"]

NETWORK_VARIABLE = "DRAKE_ALLOW_NETWORK"


def drake_allows(component: str, environ: Mapping[str, str] | None = None) -> bool:
    """Whether Drake allows ``component`` (``"package_map"``, ``"meshcat"``) under the
    current ``DRAKE_ALLOW_NETWORK`` (or that of ``environ``)."""
    value = (os.environ if environ is None else environ).get(NETWORK_VARIABLE, "")
    if not value:
        return True
    tokens = value.split(":")
    if "none" in tokens:
        return False
    return component in tokens


def meshcat_refusal(what: str, *, optional: bool = True, environ: Mapping[str, str] | None = None) -> str | None:
    """The one-line reason ``what`` (``"--html"``) cannot be done under the current
    ``DRAKE_ALLOW_NETWORK``, or None when Meshcat is allowed. ``optional``: ``what`` is
    an option the user may leave out."""
    if drake_allows("meshcat", environ):
        return None
    value = (os.environ if environ is None else environ).get(NETWORK_VARIABLE, "")
    remedy = f"add meshcat to {NETWORK_VARIABLE} (for example {NETWORK_VARIABLE}=meshcat)"
    if optional:
        remedy += f" or leave out {what}"
    return (
        f"{what} needs a Meshcat recording, and {NETWORK_VARIABLE}={value} disables Drake's "
        f"Meshcat (a web server on this machine; nothing is downloaded): {remedy}"
    )
