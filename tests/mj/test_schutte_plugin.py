"""The o2m.schutte plugin (o2m.mj.schutte_plugin) against the same muscle stepped in Python."""

from __future__ import annotations

import shutil

import mujoco
import numpy as np
import pytest

from o2m.errors import O2MError
from o2m.mj import schutte_plugin
from o2m.osim.schutte import FIBRE_GRID, STRAIN_GRID, CurveTable, SchutteMuscle
from tests.helpers import MUSCLE_PENDULUM

pytestmark = pytest.mark.skipif(not (shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")),
                                reason="no C compiler to build the plugin")


def _table(grid, fn) -> CurveTable:
    xs = np.linspace(*grid)
    return CurveTable(float(xs[0]), float(xs[1] - xs[0]), fn(xs))


#: The pendulum's "lifter" as a Schutte muscle: 0.2 m of fibre, 0.26 m of tendon (taut over the
#: swing), pennated, with a toe region in its tendon curve.
LIFTER = SchutteMuscle(
    "lifter", 300.0, 0.2, 0.26, 0.2, 0.1, 7.667, 1.459854, 0.017,
    _table(STRAIN_GRID, lambda s: np.where(s < 0.01, 1200 * s**2, 0.12 + 24 * (s - 0.01)) * 1.4),
    _table(FIBRE_GRID, lambda x: np.exp(-((x - 1.0) / 0.45) ** 2)),
    _table(FIBRE_GRID, lambda x: np.exp(8.0 * (x - 1.0)) / np.exp(4.0)))


@pytest.fixture(scope="module")
def pendulum(tmp_path_factory):
    folder = tmp_path_factory.mktemp("schutte")
    schutte_plugin.load(folder)
    xml = folder / "pendulum.xml"
    xml.write_text(MUSCLE_PENDULUM)
    out = schutte_plugin.with_schutte_muscles(xml, folder / "pendulum_schutte.xml", {"lifter": LIFTER})
    plain, model = mujoco.MjModel.from_xml_path(str(xml)), mujoco.MjModel.from_xml_path(str(out))
    data = mujoco.MjData(plain)
    data.qpos[0], data.act[0] = 0.3, 0.05
    state = np.zeros(mujoco.mj_stateSize(plain, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(plain, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return plain, model, schutte_plugin.schutte_state(model, plain, state, {"lifter": 0.21})


def _excitation(steps: int) -> np.ndarray:
    t = np.arange(steps) * 0.002
    return np.clip(0.6 * np.sin(2 * np.pi * 2 * t) ** 2 - 0.1, 0, 1)[:, None]


def test_the_plugin_steps_the_muscle_as_python_does(pendulum):
    """Activation and fibre length after every step equal SchutteMuscle.step's, fed the same
    control and the same end-of-step length; the force is the tendon's at the state."""
    _, model, init = pendulum
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, init, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    a, lf = data.plugin_state
    assert (a, lf) == (pytest.approx(0.05), pytest.approx(0.21))
    jac = np.zeros((1, model.nv))
    lengths, fibres = [], []
    for u in _excitation(300)[:, 0]:
        data.ctrl[0] = u
        mujoco.mj_step(model, data)
        mujoco.mju_sparse2dense(jac, data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind)
        end = data.ten_length[0] + model.opt.timestep * float(jac[0] @ data.qvel)
        a, lf = LIFTER.step(a, lf, u, end, model.opt.timestep)
        np.testing.assert_allclose(data.plugin_state, [a, lf], rtol=0, atol=1e-11)
        mujoco.mj_forward(model, data)
        assert data.actuator_force[0] == pytest.approx(-float(LIFTER.tendon_force(data.ten_length[0], lf)), abs=1e-8)
        lengths.append(data.ten_length[0])
        fibres.append(lf)
    assert np.ptp(lengths) > 0.05 and np.ptp(fibres) > 0.01  # the muscle moved the pendulum, its fibre moved


def test_the_state_is_what_rollout_carries(pendulum):
    """mujoco.rollout from the state gives the mj_step loop's trajectory exactly."""
    from mujoco import rollout

    _, model, init = pendulum
    ctrl = _excitation(200)
    states, _ = rollout.rollout(model, mujoco.MjData(model), init[None], ctrl[None])
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, init, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    for u in ctrl[:, 0]:
        data.ctrl[0] = u
        mujoco.mj_step(model, data)
    last = np.zeros(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, data, last, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    np.testing.assert_array_equal(states[0, -1], last)


def test_a_tendon_with_its_own_spring_is_refused(tmp_path):
    schutte_plugin.load(tmp_path)
    xml = tmp_path / "sprung.xml"
    xml.write_text(MUSCLE_PENDULUM.replace('<spatial name="lifter">', '<spatial name="lifter" stiffness="100">'))
    with pytest.raises(O2MError, match="spring or damper"):
        schutte_plugin.with_schutte_muscles(xml, tmp_path / "out.xml", {"lifter": LIFTER})
    with pytest.raises(O2MError, match="no actuators named"):
        schutte_plugin.with_schutte_muscles(tmp_path / "sprung.xml", tmp_path / "out.xml", {"other": LIFTER})
