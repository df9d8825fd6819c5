"""OpenSim's own muscles in a converted model (o2m.convert.opensim_muscles), on MoBL-ARMS and Arm26."""

from __future__ import annotations

import dataclasses
import shutil

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m.convert.opensim_muscles import write_opensim_muscles
from o2m.errors import O2MError
from o2m.mj import schutte_plugin

pytestmark = pytest.mark.skipif(not (shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")),
                                reason="no C compiler to build the plugin")


def test_mobl_arms_starts_at_opensims_equilibrium(bundled_conversion, tmp_path):
    """Every muscle becomes an o2m.schutte actuator whose reset state is OpenSim's equilibrated
    default state, so the first step's forces are OpenSim's tendon forces there; a tendon that is
    not OpenSim's length there starts in equilibrium on its own length (reported), pulling as
    OpenSim's does."""
    fetched, conv = bundled_conversion("mobl_arms_no_wrap")
    folder = tmp_path / "model"
    shutil.copytree(conv.xml.parent, folder)  # the conversion's folder is shared: write into a copy
    schutte_plugin.load(tmp_path)
    own = write_opensim_muscles(fetched.osim, folder / conv.xml.name)
    assert own.xml.name.endswith("_opensim_muscles.xml") and len(own.muscles) == 50 and not own.kept
    model = mujoco.MjModel.from_xml_path(str(own.xml))
    assert model.na == 0 and len(schutte_plugin.schutte_actuators(model)) == 50
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("default-pose").id)  # OpenSim's default pose
    mujoco.mj_forward(model, data)

    om = osim.Model(str(fetched.osim))
    state = om.initSystem()
    om.equilibrateMuscles(state)
    om.realizeDynamics(state)
    error, same_length = [], []
    for name in own.muscles:
        m = om.getMuscles().get(name)
        a = model.actuator(name).id
        adr = model.plugin_stateadr[model.actuator_plugin[a]]
        error.append(abs(-data.actuator_force[a] - m.getTendonForce(state)) / m.getMaxIsometricForce())
        same_length.append(abs(data.actuator_length[a] - m.getLength(state)) < 1e-6)
        assert data.plugin_state[adr] == pytest.approx(m.getActivation(state))
        if same_length[-1]:
            assert data.plugin_state[adr + 1] == pytest.approx(m.getFiberLength(state), abs=1e-6)
        else:
            assert own.offsets[name] == pytest.approx(data.actuator_length[a] - m.getLength(state), abs=1e-9)
    # where MuJoCo's tendon is OpenSim's length, OpenSim's force to the curve tables' interpolation;
    # the others (carrier paths that follow OpenSim's force transmission rather than its length,
    # 1-2 mm off at this pose) in equilibrium on their own length, near OpenSim's force
    assert sum(same_length) >= 40 and len(own.offsets) == 50 - sum(same_length)
    assert max(e for e, same in zip(error, same_length, strict=True) if same) < 1e-4
    assert max(error) < 0.02


def test_a_model_without_schutte_muscles_is_an_error(bundled_conversion):
    fetched, conv = bundled_conversion("arm26")
    with pytest.raises(O2MError, match="no muscle is one o2m runs as OpenSim's own"):
        write_opensim_muscles(fetched.osim, conv.xml)


def test_a_disabled_muscle_stays_a_disabled_mujoco_muscle(bundled_conversion, tmp_path):
    """A muscle in an actuator group the model disables (where the converter puts a muscle OpenSim
    disables) is no plugin: MuJoCo 4.0 applies a plugin actuator's force whatever its group, and
    OpenSim leaves a disabled muscle's state unequilibrated (fibre length 0), where the plugin's
    tendon would pull with tens of max isometric forces."""
    fetched, conv = bundled_conversion("mobl_arms_no_wrap")
    folder = tmp_path / "model"
    shutil.copytree(conv.xml.parent, folder)
    xml = folder / conv.xml.name
    text = xml.read_text().replace('<general name="DELT2" ', '<general name="DELT2" group="5" ', 1)
    xml.write_text(text.replace("<option ", '<option actuatorgroupdisable="5" ', 1))
    schutte_plugin.load(tmp_path)
    own = write_opensim_muscles(fetched.osim, xml)
    assert own.disabled == ["DELT2"] and "DELT2" not in own.muscles and len(own.muscles) == 49
    model = mujoco.MjModel.from_xml_path(str(own.xml))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("default-pose").id)
    data.ctrl[:] = 1.0
    mujoco.mj_forward(model, data)
    assert data.actuator_force[model.actuator("DELT2").id] == 0.0


def test_validate_dynamics_runs_opensims_own_muscles_from_opensims_start(bundled_conversion, tmp_path):
    """``compare_dynamics`` (``o2m validate --dynamics``) loads the plugin a model names and starts
    each o2m.schutte muscle at OpenSim's first sample, activation and fibre length, which OpenSim's
    run records; 0.1 s of one random set then follows OpenSim closely (measured over 0.2 s of this
    set: 0.0068 rad mean; started at the plugin's default state, optimal fibre lengths, 0.15)."""
    from o2m.osim.simulate import OpenSimRun
    from o2m.validate.dynamics import compare_dynamics

    fetched, conv = bundled_conversion("mobl_arms_no_wrap")
    folder = tmp_path / "model"
    shutil.copytree(conv.xml.parent, folder)
    schutte_plugin.load(folder)
    own = write_opensim_muscles(fetched.osim, folder / conv.xml.name)
    rep = compare_dynamics(fetched.osim, own.xml, n_sets=1, duration=0.1, max_workers=1, progress=False)
    assert rep.status == ["ok"] and not rep.mujoco_diverged.any()
    assert rep.mean_rotational_error() < 0.005, rep.summary()
    run = dataclasses.replace(OpenSimRun.empty("ok", "", np.zeros(2), 1, 2), initial_fibre_lengths=np.array([0.1, 0.2]))
    run.to_npz(tmp_path / "run.npz")  # run_many's runs come back through such files
    assert OpenSimRun.from_npz(tmp_path / "run.npz").initial_fibre_lengths.tolist() == [0.1, 0.2]
