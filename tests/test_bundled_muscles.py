"""Muscle paths of the bundled models in MuJoCo, measured against OpenSim 4.6.

What is asserted here is what the converter reproduces exactly today: every path force becomes
a tendon (muscles also an actuator) of the same name; a path of fixed points without wrapping
has OpenSim's length to 1e-9 m in every pose; every model simulates 1 s of random muscle
excitation without NaN. Moving and conditional points and wrapping are approximations whose
errors `o2m.validate_muscles.compare_muscles` measures (see the conversion report).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from o2m import models
from o2m.convert import convert
from o2m.document import load_document
from o2m.mjcf import MjcfBuilder
from o2m.paths import read_paths
from o2m.skeleton import SkeletonReader, read_skeleton
from o2m.validate_muscles import compare_muscles

from .conftest import approximation_budget, require_mirror

NAMES = ["tug_of_war", "arm26", "leg6dof9musc", "gait10dof18musc", "gait2354", "mobl_arms_no_wrap"]


@pytest.fixture(scope="module", params=NAMES)
def converted(request, tmp_path_factory):
    require_mirror()
    fetched = models.fetch_model_with_geometry(request.param, progress=False)
    conv = convert(fetched.osim, tmp_path_factory.mktemp(request.param), geometry_dirs=[fetched.geometry_dir])
    return request.param, fetched.osim, conv


def _plain_paths(osim) -> dict[str, set[str]]:
    """Paths with only fixed PathPoints and no wrap objects: name -> the bodies of their points."""
    doc = load_document(osim)
    skel = read_skeleton(doc)
    ref = MjcfBuilder(skel).ref
    return {p.owner: {pt.body for pt in p.points} for p in read_paths(SkeletonReader(doc), ref)
            if not p.wraps and all(not pt.moving and pt.condition is None for pt in p.points)}


def test_every_path_is_a_named_tendon_and_plain_paths_are_exact(converted):
    name, osim, conv = converted
    rep = compare_muscles(osim, conv.xml, n_poses=40, seed=3, ma_poses=0)
    assert not rep.missing_tendons, rep.missing_tendons
    assert not rep.actuator_issues, rep.actuator_issues
    plain = _plain_paths(osim)
    assert plain or name == "mobl_arms_no_wrap"
    budget = approximation_budget(conv.xml, conv.report.approximations)
    for muscle, bodies in plain.items():
        # exact, up to the recorded joint fits above the bodies its points are on (e.g. a knee)
        allowed = 1e-9 + 2 * sum(budget[b][0] for b in bodies if b in budget)
        row = rep.muscles[muscle]
        assert row.max_len <= allowed, f"{name}/{muscle}: {row.max_len * 1e3:.4f} mm > {allowed * 1e3:.4f} mm"


def test_simulates_one_second_of_random_excitation(converted):
    name, osim, conv = converted
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("default-pose").id)
    rng = np.random.default_rng(0)
    excitation = rng.uniform(0, 1, size=m.nu)
    for _ in range(int(round(1.0 / m.opt.timestep))):
        d.ctrl[:] = excitation
        mujoco.mj_step(m, d)
    assert np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel)), name
    assert np.all(np.isfinite(d.ten_length))
