"""The step settings the converter chooses: a sparse Jacobian only where the Hessian's factor is
sparse (and MuJoCo's sparse factorization is sound), collision detection off only where nothing
can collide."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from o2m.convert.step_options import (
    SPARSE_FILL,
    SPARSE_MIN_MUJOCO,
    _version,
    can_collide,
    choose_step_options,
    factor_fill,
    sparse_pays,
)

GEOM = '<geom size="0.05" mass="0.1" contype="0" conaffinity="0"/>'


def chain(n: int) -> str:
    """A chain of ``n`` hinges, each body a child of the previous one."""
    bodies = "".join(f'<body pos="0 0 0.1"><joint name="c{i}"/>{GEOM}' for i in range(n)) + "</body>" * n
    return f"<mujoco><worldbody>{bodies}</worldbody></mujoco>"


def star(leaves: int, equalities: str = "") -> str:
    """One hinge ("root") carrying ``leaves`` slides, each a leaf (the carriers' layout)."""
    kids = "".join(f'<body pos="0 {0.1 * i} 0"><joint name="s{i}" type="slide" armature="0.1"/>{GEOM}</body>'
                   for i in range(leaves))
    return (f'<mujoco><worldbody><body><joint name="root" damping="0.1"/>{GEOM}{kids}</body></worldbody>'
            f"<equality>{equalities}</equality></mujoco>")


def test_a_chain_factors_dense_and_a_star_of_leaves_sparse():
    assert factor_fill(mujoco.MjModel.from_xml_string(chain(6))) == 1.0
    k = 10  # root + k leaves, each leaf tied to the root only: 2 k + 1 of (k + 1)(k + 2) / 2
    fill = factor_fill(mujoco.MjModel.from_xml_string(star(k)))
    assert fill == pytest.approx((2 * k + 1) / ((k + 1) * (k + 2) / 2))
    assert fill < SPARSE_FILL
    assert not sparse_pays(mujoco.MjModel.from_xml_string(chain(6)))
    assert sparse_pays(mujoco.MjModel.from_xml_string(star(k)))


def test_equalities_between_leaves_fill_the_factor():
    tied = "".join(f'<joint joint1="s{i}" joint2="s{i + 1}"/>' for i in range(9))
    free, coupled = (factor_fill(mujoco.MjModel.from_xml_string(star(10, e))) for e in ("", tied))
    assert coupled > free
    inactive = tied.replace("/>", ' active="false"/>')
    assert factor_fill(mujoco.MjModel.from_xml_string(star(10, inactive))) == free


@pytest.mark.parametrize(("geoms", "pairs", "collide"), [
    ('<geom size="0.1" contype="0" conaffinity="0"/>', "", False),
    ('<geom size="0.1"/>', "", True),  # MuJoCo's defaults: contype = conaffinity = 1
    ('<geom size="0.1" contype="1" conaffinity="0"/><geom size="0.1" contype="0" conaffinity="1"/>', "", True),
    ('<geom size="0.1" contype="2" conaffinity="1"/>', "", False),  # no bit in common
    ('<geom name="a" size="0.1" contype="0" conaffinity="0"/><geom name="b" size="0.1" contype="0" '
     'conaffinity="0"/>', '<contact><pair geom1="a" geom2="b"/></contact>', True),
])
def test_collision_is_possible_only_with_matching_bits_or_pairs(geoms, pairs, collide):
    xml = f'<mujoco><worldbody><body><joint/>{geoms}</body></worldbody>{pairs}</mujoco>'
    assert can_collide(mujoco.MjModel.from_xml_string(xml)) is collide


def test_sparse_only_with_a_sound_mujoco_and_contact_off_only_without_collisions():
    for version, sparse in (("4.0.0", False), (".".join(map(str, SPARSE_MIN_MUJOCO)), True), ("4.1.0", True)):
        spec = mujoco.MjSpec.from_string(star(10))
        notes = choose_step_options(spec, spec.compile(), version)
        model = mujoco.MjModel.from_xml_string(spec.to_xml())
        assert (model.opt.jacobian == mujoco.mjtJacobian.mjJAC_SPARSE) is sparse
        assert model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
        assert len(notes) == 1 + sparse
    spec = mujoco.MjSpec.from_string(chain(3).replace('contype="0" conaffinity="0"', ""))
    assert choose_step_options(spec, spec.compile(), "4.0.1") == []
    model = mujoco.MjModel.from_xml_string(spec.to_xml())
    assert model.opt.jacobian == mujoco.mjtJacobian.mjJAC_AUTO
    assert not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT


def test_versions_compare_as_numbers():
    assert _version("4.0.10") > _version("4.0.9") >= SPARSE_MIN_MUJOCO[:2] + (0,)
    assert _version("4.1.0rc1") == (4, 1, 0)


@pytest.mark.skipif(_version(mujoco.__version__) < SPARSE_MIN_MUJOCO,
                    reason="MuJoCo 4.0.0's sparse factorization is the bug the version check avoids")
def test_the_chosen_settings_step_the_same_trajectory():
    tied = "".join(f'<joint joint1="s{i}" joint2="root" polycoef="0 {0.1 * (i + 1)} 0.05 0 0"/>' for i in range(10))
    spec = mujoco.MjSpec.from_string(star(10, tied))
    choose_step_options(spec, spec.compile(), mujoco.__version__)
    chosen = mujoco.MjModel.from_xml_string(spec.to_xml())
    plain = mujoco.MjModel.from_xml_string(star(10, tied))
    assert chosen.opt.jacobian == mujoco.mjtJacobian.mjJAC_SPARSE
    runs = []
    for model in (plain, chosen):
        data = mujoco.MjData(model)
        data.qvel[0] = 2.0
        for _ in range(500):
            mujoco.mj_step(model, data)
        runs.append(data.qpos.copy())
    assert np.max(np.abs(runs[0] - runs[1])) < 1e-9
    assert np.max(np.abs(runs[0])) > 0.1  # it moved


def test_the_conversion_key_changes_with_the_mujoco_version(tmp_path, monkeypatch):
    from o2m.convert import ConvertOptions
    from o2m.convert.converter import conversion_key

    osim = tmp_path / "m.osim"
    osim.write_text("<OpenSimDocument/>")
    now = conversion_key(osim, ConvertOptions())
    monkeypatch.setattr(mujoco, "__version__", mujoco.__version__ + ".1")
    assert conversion_key(osim, ConvertOptions()) != now
