"""Shared test set-up: the local model mirror and a per-session cache (helpers in tests/helpers.py)."""

from __future__ import annotations

import os

import pytest

from tests.helpers import local_mirror


@pytest.fixture(autouse=True, scope="session")
def _model_mirror_and_cache(tmp_path_factory):
    """Point o2m at a local mirror when there is one (else the models are downloaded) and, unless
    set, at a cache private to this test session."""
    m = local_mirror()
    saved = {k: os.environ.get(k) for k in ("O2M_MODEL_MIRROR", "O2M_CACHE")}
    if m is not None:
        os.environ["O2M_MODEL_MIRROR"] = str(m)
    if not os.environ.get("O2M_CACHE"):
        os.environ["O2M_CACHE"] = str(tmp_path_factory.mktemp("o2m-cache"))
    yield
    for k, v in saved.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v
