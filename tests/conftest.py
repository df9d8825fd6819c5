"""Shared test set-up: the local model mirror and a per-session cache."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

#: Where the third-party models are mirrored: $O2M_MODEL_MIRROR, else shared/models beside the clone.
MIRROR_CANDIDATES = [Path(__file__).resolve().parents[2] / "shared" / "models", Path("/work/shared/models")]


def mirror() -> Path | None:
    env = os.environ.get("O2M_MODEL_MIRROR")
    if env:
        return Path(env)
    return next((p for p in MIRROR_CANDIDATES if (p / "registry.tsv").exists()), None)


def require_mirror() -> None:
    if mirror() is None:
        pytest.skip("no local model mirror (set O2M_MODEL_MIRROR)")


@pytest.fixture(autouse=True, scope="session")
def _model_mirror_and_cache(tmp_path_factory):
    """Point o2m at the local mirror and, unless set, at a cache private to this test session."""
    m = mirror()
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
