"""The passive-fibre runs (o2m.paper.passive) on a one-muscle pendulum."""

from __future__ import annotations

from types import SimpleNamespace

import mujoco
import numpy as np

from o2m.paper.passive import fibre_run
from tests.helpers import MUSCLE_PENDULUM, pendulum_fibre


def _pendulum(tmp_path, steps: int = 200):
    xml = tmp_path / "pendulum.xml"
    xml.write_text(MUSCLE_PENDULUM)
    model = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(model)
    data.qpos[0] = 0.3
    init = np.zeros((1, mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)))
    mujoco.mj_getState(model, data, init[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    exp = SimpleNamespace(dofs=["swing"], init=init, controls=np.zeros((1, steps, 1)),
                          reference=np.zeros((1, steps + 1, 1)))
    return exp, model


def test_a_slack_fibre_leaves_the_model_as_it_steps(tmp_path):
    exp, model = _pendulum(tmp_path)
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, exp.init[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    plain = [data.qpos[0]]
    for _ in range(exp.controls.shape[1]):
        mujoco.mj_step(model, data)
        plain.append(data.qpos[0])
    q = fibre_run(exp, model, {"lifter": pendulum_fibre(slack=5.0, force=40.0)}, 0, {"lifter": 0.2})
    np.testing.assert_allclose(q[:, 0], plain, atol=1e-12)


def test_a_taut_fibre_pulls_and_the_ratchet_is_not_the_equilibrium(tmp_path):
    """A fibre whose tendon is taut over the swing moves the pendulum, and keeping the fibre's longest
    length (the ratchet) moves it otherwise than the memoryless equilibrium."""
    exp, model = _pendulum(tmp_path, steps=400)
    free = fibre_run(exp, model, {"lifter": pendulum_fibre(slack=5.0, force=40.0)}, 0, {"lifter": 0.2})
    fibre = pendulum_fibre(slack=0.4, force=40.0)
    ratchet = fibre_run(exp, model, {"lifter": fibre}, 0, {"lifter": 0.2})
    memoryless = fibre_run(exp, model, {"lifter": fibre}, 0, {"lifter": 0.2}, ratchet=False)
    assert np.abs(ratchet - free).max() > 0.01
    assert np.abs(ratchet - memoryless).max() > 1e-3


def test_along_a_swing_the_ratchet_never_pulls_harder_than_the_equilibrium(tmp_path):
    """Along a recorded swing that stretches the tendon and lets it back, the ratchet's fibre is never
    shorter than the equilibrium's, so its tendon pulls no harder, and less once the swing returns."""
    from o2m.paper.passive import fibre_forces_along

    exp, model = _pendulum(tmp_path)
    t = np.linspace(0.0, 1.0, 101)
    q = (0.3 * np.sin(2 * np.pi * t))[None, :, None]
    exp.dataset = SimpleNamespace(coordinate_names=["swing"], coordinates=q, speeds=np.zeros_like(q))
    fibre = {"lifter": pendulum_fibre(slack=0.4, force=400.0)}
    ratchet = fibre_forces_along(exp, model, fibre, 0, {"lifter": 0.2})[:, 0]
    memoryless = fibre_forces_along(exp, model, fibre, 0, {"lifter": 0.2}, ratchet=False)[:, 0]
    assert memoryless.max() > 2.0
    assert np.all(ratchet <= memoryless + 1e-9)
    assert (memoryless - ratchet).max() > 0.2 * memoryless.max()
