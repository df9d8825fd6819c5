"""Shared test set-up: the local model mirror and a per-session cache."""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np
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


def approximation_budget(xml, approximations) -> dict[str, tuple[float, float]]:
    """Per body: (position, angle) error allowed by the recorded fits of the joints above it.

    A slide fit adds its error (m) to the position; a hinge fit adds its error (rad) to the
    angle and, times 1 m (longer than any limb segment chain here), to the position.
    """
    m = mujoco.MjModel.from_xml_path(str(xml))
    per_joint = {a.joint: a for a in approximations if a.joint}
    own = np.zeros((m.nbody, 2))
    for j in range(m.njnt):
        a = per_joint.get(m.joint(j).name)
        if a is None:
            continue
        b = m.jnt_bodyid[j]
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
            own[b, 0] += a.max_error
        else:
            own[b] += (a.max_error * 1.0, a.max_error)
    total = own.copy()
    for b in range(1, m.nbody):  # parents come before children in MuJoCo's body order
        total[b] += total[m.body_parentid[b]]
    return {m.body(b).name: (float(total[b, 0]), float(total[b, 1])) for b in range(1, m.nbody)}
