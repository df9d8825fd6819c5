"""The o2m.fibre plugin (o2m.mj.fibre_plugin) against the same fibre stepped in Python."""

from __future__ import annotations

import shutil
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

from o2m.mj import fibre_plugin
from o2m.paper.passive import fibre_run
from tests.helpers import MUSCLE_PENDULUM, pendulum_fibre

#: The pendulum's muscle as a fibre whose tendon is taut over the swing.
FIBRES = {"lifter": pendulum_fibre(slack=0.4, force=400.0)}

pytestmark = pytest.mark.skipif(not (shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")),
                                reason="no C compiler to build the plugin")


@pytest.fixture(scope="module")
def pendulum(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fibre")
    fibre_plugin.load(folder)
    xml = folder / "pendulum.xml"
    xml.write_text(MUSCLE_PENDULUM.replace('lengthrange="0.3 0.9"', 'lengthrange="0.45 0.75"'))
    out = fibre_plugin.with_fibres(xml, folder / "pendulum_fibre.xml", FIBRES, {"lifter": 0.2})
    return mujoco.MjModel.from_xml_path(str(xml)), mujoco.MjModel.from_xml_path(str(out))


def _swing(model: mujoco.MjModel, steps: int = 400) -> tuple[np.ndarray, np.ndarray]:
    data = mujoco.MjData(model)
    data.qpos[0] = 0.3
    mujoco.mj_forward(model, data)
    state = np.zeros(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    q = [data.qpos[0]]
    for _ in range(steps):
        mujoco.mj_step(model, data)
        q.append(data.qpos[0])
    return np.array(q), state


def test_the_plugin_steps_the_fibre_as_python_does(pendulum):
    plain, with_plugin = pendulum
    q, _ = _swing(with_plugin)
    free, init = _swing(plain)
    exp = SimpleNamespace(dofs=["swing"], init=init[None], controls=np.zeros((1, 400, 1)),
                          reference=np.zeros((1, 401, 1)))
    python = fibre_run(exp, plain, FIBRES, 0, {"lifter": 0.2})[:, 0]
    assert np.abs(q - free).max() > 0.01  # the fibre pulls
    # as the same fibre stepped in Python: 4.4e-6 rad apart at most, the equilibrium table's linear interpolation
    np.testing.assert_allclose(q, python, atol=1e-5)


def test_the_fibre_length_is_state_that_rollout_carries(pendulum):
    _, model = pendulum
    q, init = _swing(model)
    assert model.npluginstate == 1 and init[-1] == pytest.approx(0.2)
    from mujoco import rollout

    states, _ = rollout.rollout(model, mujoco.MjData(model), init[None], np.zeros((1, 400, 1)))
    np.testing.assert_allclose(states[0, :, 1], q[1:], atol=1e-12)
    long = init.copy()
    long[-1] = 0.5  # a fibre this long leaves the tendon slack: the pendulum swings free
    slack, _ = rollout.rollout(model, mujoco.MjData(model), long[None], np.zeros((1, 400, 1)))
    assert np.abs(slack[0, :, 1] - q[1:]).max() > 0.01
    assert slack[0, -1, -1] == pytest.approx(0.5)  # and the fibre never shortens


def test_plugin_run_is_fibre_run_inside_mujoco(tmp_path):
    """o2m.paper.passive.plugin_run (the plugin written into the model, stepped by mujoco.rollout)
    follows o2m.paper.passive.fibre_run (the fibre stepped in Python beside mj_step)."""
    from o2m.paper.passive import plugin_run

    fibre_plugin.load(tmp_path)
    xml = tmp_path / "pendulum.xml"
    xml.write_text(MUSCLE_PENDULUM.replace('lengthrange="0.3 0.9"', 'lengthrange="0.45 0.75"'))
    plain = mujoco.MjModel.from_xml_path(str(xml))
    _, init = _swing(plain, steps=0)
    exp = SimpleNamespace(dofs=["swing"], init=init[None], controls=np.zeros((1, 300, 1)),
                          reference=np.zeros((1, 301, 1)))
    inside = plugin_run(exp, xml, FIBRES, 0, {"lifter": 0.2})
    beside = fibre_run(exp, plain, FIBRES, 0, {"lifter": 0.2})
    assert inside.shape == beside.shape == (301, 1)
    np.testing.assert_allclose(inside, beside, atol=1e-5)


def test_an_instance_off_leaves_the_model_and_one_on_replaces_its_tendon_spring(tmp_path):
    """Off (fibre length -1), the instance changes nothing; on, with a fibre whose tendon stays
    slack, the model moves as if its tendon had no spring and damper (the plugin cancels them)."""
    from mujoco import rollout

    fibre_plugin.load(tmp_path)
    bare = MUSCLE_PENDULUM.replace('lengthrange="0.3 0.9"', 'lengthrange="0.45 0.75"')
    sprung = bare.replace('<spatial name="lifter">', '<spatial name="lifter" stiffness="300" springlength="0.5" '
                                                     'damping="2">')
    for name, text in (("bare.xml", bare), ("sprung.xml", sprung)):
        (tmp_path / name).write_text(text)
    slack = {"lifter": pendulum_fibre(slack=5.0, force=400.0)}
    model = mujoco.MjModel.from_xml_path(str(fibre_plugin.with_fibres(tmp_path / "sprung.xml",
                                                                      tmp_path / "fibre.xml", slack)))
    q_bare, state = _swing(mujoco.MjModel.from_xml_path(str(tmp_path / "bare.xml")))
    q_sprung, _ = _swing(mujoco.MjModel.from_xml_path(str(tmp_path / "sprung.xml")))
    assert np.abs(q_bare - q_sprung).max() > 0.01  # the spring matters
    off = fibre_plugin.fibre_state(model, state, {})
    on = fibre_plugin.fibre_state(model, state, {"lifter": 0.2})
    assert off[-1] == fibre_plugin.OFF and on[-1] == pytest.approx(0.2)
    states, _ = rollout.rollout(model, mujoco.MjData(model), np.stack([off, on]), np.zeros((2, 400, 1)))
    np.testing.assert_allclose(states[0, :, 1], q_sprung[1:], atol=1e-12)
    np.testing.assert_allclose(states[1, :, 1], q_bare[1:], atol=1e-9)
