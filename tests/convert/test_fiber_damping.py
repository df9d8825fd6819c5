"""OpenSim's fiber damping (Millard2012EquilibriumMuscle's default 0.1) as MuJoCo tendon damping."""

from __future__ import annotations

import math

import mujoco
import opensim as osim
import pytest

from o2m.convert.converter import convert
from tests.helpers import convert_options, slider_model

FORCE, LOPT, SLACK, ALPHA, DAMPING = 500.0, 0.1, 0.2, 0.3, 0.1


def _damped_muscle_model(path, kind: str) -> None:
    """A 1-kg slider pulled along ground X by one rigid-tendon muscle of type ``kind`` with fiber
    damping, its fiber at the optimal length (and pennation) at the slider's zero."""
    m, b = slider_model("damped", gravity=False)
    mus = getattr(osim, kind)()
    mus.setName("mus")
    mus.set_max_isometric_force(FORCE)
    mus.set_optimal_fiber_length(LOPT)
    mus.set_tendon_slack_length(SLACK)
    mus.set_pennation_angle_at_optimal(ALPHA)
    mus.set_fiber_damping(DAMPING)
    mus.set_ignore_tendon_compliance(True)
    if kind == "Millard2012EquilibriumMuscle":
        mus.set_minimum_activation(0.0)
    length = SLACK + LOPT * math.cos(ALPHA)
    mus.addNewPathPoint("p1", m.getGround(), osim.Vec3(-length, 0, 0))
    mus.addNewPathPoint("p2", b, osim.Vec3(0, 0, 0))
    m.addForce(mus)
    m.finalizeConnections()
    m.printToXML(str(path))


def _opensim_acceleration(path, speed: float) -> float:
    model = osim.Model(str(path))
    state = model.initSystem()
    coord = model.getCoordinateSet().get("s_coord_0")
    coord.setSpeedValue(state, speed)
    model.getMuscles().get(0).setActivation(state, 0.0)  # unexcited: only the passive forces
    model.equilibrateMuscles(state)
    model.realizeAcceleration(state)
    return coord.getAccelerationValue(state)


# DeGrooteFregly2016Muscle has the same term (the same acceleration to 1e-12 by hand), but in this
# process converting one with fiber damping after an OpenSim run of it makes a later DeGroote
# muscle's activation derivative use OpenSim's default time constants (test_muscle_types fails);
# the cause is inside OpenSim 4.6 and was not found, so DeGroote stays out of this test.
@pytest.mark.parametrize("kind", ["Millard2012EquilibriumMuscle", "MeyerFregly2016Muscle"])
def test_fiber_damping_resists_motion_unexcited_as_in_opensim(kind, tmp_path):
    """Unexcited, the muscle's only velocity-dependent force is its fiber damping: the change in
    acceleration between rest and 0.3 m/s is OpenSim's (about 13.7 m/s², F cos²α β v /
    (vmax lopt)) in MuJoCo too, and the report's notes say so."""
    src = tmp_path / "damped.osim"
    _damped_muscle_model(src, kind)
    theirs = _opensim_acceleration(src, 0.3) - _opensim_acceleration(src, 0.0)
    assert theirs < -10.0
    conv = convert(src, tmp_path / "out", convert_options())
    assert any("fiber damping" in n and "tendons' damping" in n for n in conv.report.notes)
    model = mujoco.MjModel.from_xml_path(str(conv.xml))
    data = mujoco.MjData(model)
    ours = []
    for speed in (0.3, 0.0):
        data.qvel[0] = speed
        data.act[:] = 0.0
        mujoco.mj_forward(model, data)
        ours.append(float(data.qacc[0]))
    assert ours[0] - ours[1] == pytest.approx(theirs, rel=1e-6)
