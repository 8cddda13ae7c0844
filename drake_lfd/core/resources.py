"""Where drake-lfd's shipped data lives: the UR5e model and the paper scenarios.

An installed drake-lfd carries them inside the package (``drake_lfd/models``,
``drake_lfd/sims``); a source checkout has them at the top of the repository
(``models/``, ``sims/``). Nothing here reads or writes them. Plain Python (no Drake,
no numpy), so the command line can name the bundled libraries in its help at once.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["package_directory", "models_directory", "scenarios_directory", "bundled_library_directories",
           "bundled_library_names", "bundled_library_paths", "MANIFEST_NAME"]

#: The file that makes a folder a library (its manifest, ``io/library_manifest.py``).
MANIFEST_NAME = "library.json"


def package_directory() -> Path:
    """The ``drake_lfd`` package folder."""
    return Path(__file__).resolve().parent.parent


def _first_with(relative: str, marker: str) -> Path | None:
    for base in (package_directory(), package_directory().parent):
        candidate = base / relative
        if (candidate / marker).is_file():
            return candidate
    return None


def models_directory() -> Path:
    """The folder holding ``package.xml`` and the models (installed or checkout)."""
    found = _first_with("models", "package.xml")
    if found is None:
        raise FileNotFoundError(
            f"drake-lfd's models are missing: looked for models/package.xml in "
            f"{package_directory()} and {package_directory().parent}")
    return found


def scenarios_directory() -> Path:
    """The paper scenarios: installed with the package, or the checkout's ``sims/``."""
    found = _first_with("sims", "transferring.yaml")
    if found is None:
        raise FileNotFoundError("drake-lfd's scenarios (sims/*.yaml) are missing")
    return found


def bundled_library_directories() -> tuple[Path, Path]:
    """Folders searched for bundled libraries, in order: installed, then checkout."""
    return (package_directory() / "sims" / "libraries", package_directory().parent / "sims" / "libraries")


def bundled_library_names() -> list[str]:
    """Names of the libraries bundled with drake-lfd (sorted; may be empty)."""
    names: set[str] = set()
    for directory in bundled_library_directories():
        if directory.is_dir():
            names.update(p.name for p in directory.iterdir() if (p / MANIFEST_NAME).is_file())
    return sorted(names)


def bundled_library_paths() -> dict[str, Path]:
    """Name -> directory of each bundled library, where ``Library.open(name)`` finds it
    (the first of :func:`bundled_library_directories` that has it), sorted by name."""
    paths = {}
    for directory in bundled_library_directories():
        if directory.is_dir():
            for candidate in sorted(directory.iterdir()):
                if (candidate / MANIFEST_NAME).is_file() and candidate.name not in paths:
                    paths[candidate.name] = candidate.resolve()
    return dict(sorted(paths.items()))
