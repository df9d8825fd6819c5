"""Helpers the viz tests share: a converted model and an arm motion."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from tests.helpers import convert_options, require_models


def convert_model(name: str, out: Path):
    """(osim path, MJCF path, MjModel) of the bundled model ``name`` converted into ``out``."""
    require_models()
    from o2m.convert.converter import convert
    from o2m.models import fetch_model_with_geometry

    f = fetch_model_with_geometry(name, progress=False)
    res = convert(f.osim, out, convert_options(fit_mechanics=False), geometry_dirs=[f.geometry_dir])
    return f.osim, res.xml, mujoco.MjModel.from_xml_path(str(res.xml))


def arm_motion(model: mujoco.MjModel, n: int) -> tuple[np.ndarray, np.ndarray]:
    """qpos (n, nq) flexing the elbow and raising the shoulder, and activations (n, nu) 0 -> 1."""
    q = np.tile(model.qpos0, (n, 1))
    q[:, model.joint("r_shoulder_elev").qposadr[0]] = np.linspace(0.0, 0.8, n)
    q[:, model.joint("r_elbow_flex").qposadr[0]] = np.linspace(0.2, 2.0, n)
    return q, np.tile(np.linspace(0.0, 1.0, n)[:, None], (1, model.nu))
