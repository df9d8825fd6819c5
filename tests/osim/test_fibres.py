"""OpenSim's Schutte1993 fibre at zero activation (o2m.osim.fibres), against OpenSim itself."""

from __future__ import annotations

import numpy as np
import opensim as osim
import pytest

from o2m import models
from o2m.errors import O2MError
from o2m.osim.fibres import passive_fibres
from tests.helpers import require_models

osim.Logger.setLevelString("error")

MOBL = "mobl-arms/MoBL_ARMS_model_for_testing_opensim_no_wrap.osim"


@pytest.fixture(scope="module")
def mobl():
    require_models()
    path = models.fetch_model(MOBL, progress=False)
    model = osim.Model(str(path))
    return path, model, model.initSystem()


def _at_elbow(model, state, elbow: float) -> float:
    """BIClong's muscle-tendon length (m) with the elbow at ``elbow`` rad, the rest at defaults."""
    model.getCoordinateSet().get("elbow_flexion").setValue(state, elbow)
    model.realizePosition(state)
    return model.getMuscles().get("BIClong").getLength(state)


def test_the_equilibrium_is_opensims_at_zero_activation(mobl):
    path, model, state = mobl
    fibre = passive_fibres(path, ["BIClong"])["BIClong"]
    muscle = model.getMuscles().get("BIClong")
    for elbow in (0.0, 0.3, 0.8):
        length = _at_elbow(model, state, elbow)
        for m in model.getMuscles():
            m.setActivation(state, 0.0)
        model.equilibrateMuscles(state)
        model.realizeDynamics(state)
        ours = fibre.tendon_force(length, fibre.equilibrium(length))
        assert ours == pytest.approx(muscle.getTendonForce(state), rel=0.01, abs=0.5), elbow


def test_the_fibre_lengthens_but_never_shortens(mobl):
    """Stretched from elbow 0.8 to 0 rad and back to 0.3: the fibre keeps its length and the tendon
    goes slack, where the static equilibrium would still pull tens of newtons."""
    path, model, state = mobl
    fibre = passive_fibres(path, ["BIClong"])["BIClong"]
    lengths = [_at_elbow(model, state, e) for e in np.linspace(0.8, 0.0, 20).tolist() + [0.1, 0.2, 0.3]]
    lf = fibre.equilibrium(lengths[0])
    fibres = []
    for length in lengths:
        lf = fibre.ratchet(length, lf)
        fibres.append(float(lf))
    assert np.all(np.diff(fibres) >= 0)
    static = fibre.tendon_force(lengths[-1], fibre.equilibrium(lengths[-1]))
    assert static > 20.0
    assert fibre.tendon_force(lengths[-1], lf) < 0.05 * static


def test_the_ratchet_follows_opensims_recorded_biceps_force(mobl):
    """Along a fresh dataset set where the elbow extends to its limit and flexes back (BIClong never
    excited), the ratchet from the run's initial fibre length, on OpenSim's own muscle-tendon
    lengths, follows OpenSim's recorded tendon force within 2 N RMS (0.65 measured); the memoryless
    equilibrium is 44 N RMS off."""
    from pathlib import Path

    from o2m.osim.simulate import read_initial_state

    path, model, state = mobl
    data = np.load(Path(__file__).resolve().parents[2] / "data/mobl_arms/fresh_seed2026/opensim.npz", allow_pickle=True)
    names, muscles = list(data["coordinate_names"]), list(data["muscle_names"])
    i, j = 4, muscles.index("BIClong")
    assert np.all(data["activations"][i, :, j] == 0)
    fibre = passive_fibres(path, ["BIClong"])["BIClong"]
    lf = read_initial_state(models.fetch("mobl-arms/initial_states.sto"))["BIClong.fiber_length"]
    coords = model.getCoordinateSet()
    ratchet, static = [], []
    for q in data["coordinates"][i]:
        for name, value in zip(names, q, strict=True):
            coords.get(name).setValue(state, float(value), False)
        model.realizePosition(state)
        length = model.getMuscles().get("BIClong").getLength(state)
        lf = fibre.ratchet(length, lf)
        ratchet.append(fibre.tendon_force(length, lf))
        static.append(fibre.tendon_force(length, fibre.equilibrium(length)))
    recorded = data["tendon_forces"][i, :, j].astype(float)
    rms = [float(np.sqrt(np.mean((np.array(x) - recorded) ** 2))) for x in (ratchet, static)]
    assert rms[0] < 2.0 and rms[1] > 40.0, rms


def test_other_muscle_types_are_refused():
    require_models()
    arm26 = models.fetch_model("opensim-models/Models/Arm26/arm26.osim", progress=False)
    with pytest.raises(O2MError, match="not a Schutte1993Muscle_Deprecated"):
        passive_fibres(arm26, ["BIClong"])
