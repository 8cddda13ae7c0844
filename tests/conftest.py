"""Shared test fixtures: offline Drake, seeded generators."""

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest
import pydrake

import drake_lfd


@pytest.fixture
def rng():
    return np.random.default_rng(20261121)


@pytest.fixture
def offline_env(tmp_path):
    """Environment for a subprocess in which Drake may not touch the network.

    With ``DRAKE_ALLOW_NETWORK=none`` Drake refuses to even build a Parser unless its
    default remote package ``drake_models`` is in the download cache, so the cache
    (``XDG_CACHE_HOME``) gets an *empty* stand-in for it: any model that reached for
    ``package://drake_models`` (or anything remote) would fail loudly.
    """
    params_file = (
        Path(pydrake.__file__).parent / "share/drake/multibody/parsing/drake_models.json"
    )
    params = json.loads(params_file.read_text())
    strip_hash = hashlib.sha256(params["strip_prefix"].encode()).hexdigest()
    cache = tmp_path / "cache"
    (cache / "drake" / "package_map" / f"{params['sha256']}-{strip_hash}").mkdir(parents=True)
    env = dict(os.environ)
    env["DRAKE_ALLOW_NETWORK"] = "none"
    env["XDG_CACHE_HOME"] = str(cache)
    # The subprocess must import the same drake_lfd as this test (installed or checkout).
    package_parent = str(Path(drake_lfd.__file__).resolve().parent.parent)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (package_parent, env.get("PYTHONPATH")) if p)
    return env
