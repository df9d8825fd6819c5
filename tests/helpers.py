"""Helpers the tests share: the model mirror, conversion options, approximation budgets.

The tests are an edge of o2m, so they read the environment here: ``O2M_MODEL_MIRROR`` (a local
copy of the models) and ``O2M_QUICK`` (CI's quick wrap fits).
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np
import pytest

from o2m.convert import ConvertOptions

#: CI's quick mode: the converter's quick wrap-fit sizes, the notebooks' small budgets.
QUICK = os.environ.get("O2M_QUICK", "") not in ("", "0")


def convert_options(**kw) -> ConvertOptions:
    """:class:`ConvertOptions` with ``quick`` as this test run's mode, and ``kw`` on top."""
    return ConvertOptions(**{"quick": QUICK, **kw})


#: Where the third-party models are mirrored: $O2M_MODEL_MIRROR, else shared/models beside the clone.
MIRROR_CANDIDATES = [Path(__file__).resolve().parents[2] / "shared" / "models"]


def mirror() -> Path | None:
    env = os.environ.get("O2M_MODEL_MIRROR")
    if env:
        return Path(env)
    return next((p for p in MIRROR_CANDIDATES if (p / "registry.tsv").exists()), None)


def require_mirror() -> None:
    if mirror() is None:
        pytest.skip("no local model mirror (set O2M_MODEL_MIRROR)")


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
