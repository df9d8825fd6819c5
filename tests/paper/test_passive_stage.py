"""The passive-fibre stage (o2m.paper.passive_stage) on a one-muscle pendulum."""

from __future__ import annotations

import shutil
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

from o2m.paper.passive_stage import passive_muscles, with_passive_fibres
from o2m.paper.pipeline import Experiment
from tests.helpers import MUSCLE_PENDULUM, pendulum_fibre


def test_passive_muscles_are_those_never_excited():
    acts = SimpleNamespace(muscles=["a", "b", "c"], values=np.zeros((1, 5, 3)))
    acts.values[0, 2, 1] = 0.3
    exp = SimpleNamespace(dataset=SimpleNamespace(activations=acts), muscles=["c", "b", "a"])
    assert passive_muscles(exp, 0) == ["c", "a"]
    assert passive_muscles(exp, 0, among=["a"]) == ["a"]


@pytest.mark.skipif(not (shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")),
                    reason="no C compiler to build the plugin")
def test_each_set_starts_with_the_fibres_of_its_never_excited_muscles(tmp_path):
    """Set 0 never excites the muscle: its fibre is on and pulls; set 1 excites it: off, and the set
    runs as on the model without the plugin."""
    from mujoco import rollout

    from o2m.mj import fibre_plugin

    fibre_plugin.load(tmp_path)
    xml = tmp_path / "pendulum.xml"
    xml.write_text(MUSCLE_PENDULUM.replace('lengthrange="0.3 0.9"', 'lengthrange="0.45 0.75"'))
    plain = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(plain)
    data.qpos[0] = 0.3
    state = np.zeros(mujoco.mj_stateSize(plain, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(plain, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    excitation = np.zeros((2, 301, 1))
    excitation[1, 100:150] = 0.5
    exp = Experiment(plain, xml, SimpleNamespace(activations=SimpleNamespace(muscles=["lifter"], values=excitation)),
                     ["swing"], ["lifter"], np.stack([state, state]), excitation[:, 1:], np.zeros((2, 301, 1)))
    fexp = with_passive_fibres(exp, xml, {"lifter": pendulum_fibre(slack=0.4, force=400.0)}, {"lifter": 0.2})
    assert fexp.xml.name == "pendulum_fibres.xml" and fexp.model.nplugin == 1
    assert fexp.init[0, -1] == pytest.approx(0.2) and fexp.init[1, -1] == fibre_plugin.OFF
    with_fibres, _ = rollout.rollout(fexp.model, mujoco.MjData(fexp.model), fexp.init, fexp.controls)
    without, _ = rollout.rollout(plain, mujoco.MjData(plain), exp.init, exp.controls)
    np.testing.assert_allclose(with_fibres[1, :, 1], without[1, :, 1], atol=1e-12)
    assert np.abs(with_fibres[0, :, 1] - without[0, :, 1]).max() > 0.01
