"""The documentation: it builds without a single warning, and it stands on its own.

* The Sphinx build (``docs/``: the pages and the API reference generated from the
  package) runs offline with warnings as errors, as a contributor runs it:
  ``sphinx-build -W --keep-going -b html docs OUT``. The docs are copied to a temporary
  folder first, so the generated API stubs never land in the checkout.
* No file of the repository refers to a document that is not in it: the project's
  documentation is ``README.md`` and ``docs/``, and a reference to a design note kept
  elsewhere would send a reader nowhere.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parent.parent
DOCS = REPOSITORY / "docs"


@pytest.mark.slow
def test_sphinx_build_has_no_warnings(tmp_path):
    pytest.importorskip("sphinx", reason="the docs need Sphinx (the test extra installs it)")
    source = tmp_path / "docs"
    shutil.copytree(DOCS, source, ignore=shutil.ignore_patterns("_autosummary", "_build", "__pycache__"))
    out = tmp_path / "html"
    completed = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(source), str(out)],
        capture_output=True, text=True, timeout=300, cwd=tmp_path,
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
    assert "WARNING" not in completed.stderr, completed.stderr
    for page in ("index", "method", "task_files", "guidance_scripts", "libraries", "cli", "api"):
        assert (out / f"{page}.html").is_file(), page
    # The API reference is generated from the package: a page per exported name, at the
    # path users import it from, and a page per module.
    assert (out / "_autosummary" / "drake_lfd.planning.PlanningOptions.html").is_file()
    similarity = out / "_autosummary" / "drake_lfd.core.similarity.html"
    assert similarity.is_file()
    assert "allocate" in similarity.read_text(encoding="utf-8")
    method = (out / "method.html").read_text(encoding="utf-8")
    for section in ("Conventions", "Demonstrations and features", "Tasks", "Similarity", "Mapping",
                    "Planning", "Timing", "Closed loop and success", "Departures from the paper"):
        assert f">{section}<" in method, section


# The names of documents that live outside the repository, spelled in pieces so that
# this file does not match itself. Whole words only: "SPECIFIC" or "TaskSpec" are fine.
_OUTSIDE_DOCUMENTS = re.compile(
    "|".join([
        r"\b" + "SP" + r"EC\b",          # the method note, with a section number or not
        r"\b" + "INTER" + r"FACES\b",    # the interface note
        "DRAKE" + "_NOTES",              # the Drake notes
        r"\.\./" + "shared",             # the folder they live in
        r"\b" + "shared" + "/",
    ])
)


def _repository_files():
    try:
        listed = subprocess.run(
            ["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"],
            cwd=REPOSITORY, capture_output=True, check=True, timeout=60,
        ).stdout
    except (OSError, subprocess.CalledProcessError, subprocess.TimeoutExpired):
        pytest.skip("not a git checkout")
    return [REPOSITORY / name for name in listed.decode("utf-8").split("\0") if name]


def _text_of(path):
    """The file's text, or None for binary files (and files that went away)."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    if b"\0" in data[:8192]:
        return None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return None


def test_the_pattern_tells_references_from_ordinary_words():
    references = ["see SP" "EC 7", "(SP" "EC)", "SP" "EC.md", "INTER" "FACES.md",
                  "DRAKE" "_NOTES.md", "../" "sha" "red/x", "/work/" "sha" "red/paper"]
    ordinary = ["SPECIFIC", "TaskSpec", "spec.p", "CriticalConfigurationSpec", "a specification",
                "INTERFACE", "interfaces", "shared_kinematics", "shared library", "sharedX/"]
    for text in references:
        assert _OUTSIDE_DOCUMENTS.search(text), text
    for text in ordinary:
        assert not _OUTSIDE_DOCUMENTS.search(text), text


def test_no_file_refers_to_documents_outside_the_repository():
    found = []
    for path in _repository_files():
        text = _text_of(path)
        if text is None:
            continue
        for number, line in enumerate(text.splitlines(), start=1):
            if _OUTSIDE_DOCUMENTS.search(line):
                found.append(f"{path.relative_to(REPOSITORY)}:{number}: {line.strip()}")
    assert not found, (
        "these lines refer to documents that are not in the repository; point to the docs "
        "(for example docs/method.rst, a section) or state the fact in place:\n" + "\n".join(found))
