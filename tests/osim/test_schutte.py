"""OpenSim's Schutte1993 muscle stepped by o2m (o2m.osim.schutte) against OpenSim's own run."""

from __future__ import annotations

import numpy as np
import opensim as osim
import pytest

from o2m import models
from o2m.errors import O2MError
from o2m.osim.schutte import default_states, muscle_types, schutte_muscles
from o2m.osim.simulate import read_initial_state
from o2m.paper.dataset import load_dataset
from tests.helpers import require_models

osim.Logger.setLevelString("error")

#: Muscles that cross the elbow and pro_sup, flexors and extensors, passive and active.
MUSCLES = ["BIClong", "BRA", "TRIlong", "PT", "FCU", "DELT1"]


@pytest.fixture(scope="module")
def recorded():
    """OpenSim's first test set: its muscle-tendon lengths (T, len(MUSCLES)) m at the recorded
    poses, the excitations and the recorded tendon forces (N) and activations."""
    require_models()
    ds = load_dataset("data/mobl_arms")
    path = models.fetch(ds.meta["model"])
    model = osim.Model(str(path))
    state = model.initSystem()
    i = ds.test[0]
    lengths = np.zeros((len(ds.times), len(MUSCLES)))
    for k in range(len(ds.times)):
        for j, name in enumerate(ds.coordinate_names):
            model.getCoordinateSet().get(name).setValue(state, float(ds.coordinates[i, k, j]), False)
        model.realizePosition(state)
        lengths[k] = [model.getMuscles().get(m).getLength(state) for m in MUSCLES]
    cols = [ds.muscle_names.index(m) for m in MUSCLES]
    excitation = ds.activations.values[i][:, [list(ds.activations.muscles).index(m) for m in MUSCLES]]
    start = read_initial_state(models.fetch(ds.meta["initial_state"]))
    return (path, lengths, excitation, ds.tendon_forces[i][:, cols].astype(float),
            ds.opensim_activations[i][:, cols].astype(float), [start[f"{m}.fiber_length"] for m in MUSCLES])


def test_stepped_at_2_ms_the_muscle_pulls_as_opensims(recorded):
    """From OpenSim's initial state, 2-ms steps on OpenSim's own lengths and excitations give
    OpenSim's recorded tendon force within 0.3 % of the max isometric force (RMS, each muscle;
    float16 records) and its activation within 0.002."""
    path, lengths, excitation, forces, activations, fibre0 = recorded
    muscles = schutte_muscles(path, MUSCLES)
    h, moving = 0.002, 0
    for j, name in enumerate(MUSCLES):
        m, a, lf = muscles[name], activations[0, j], fibre0[j]
        out, acts = [], []
        for k in range(len(lengths) - 1):
            a, lf = m.step(a, lf, 0.5 * (excitation[k, j] + excitation[k + 1, j]), lengths[k + 1, j], h)
            out.append(float(m.tendon_force(lengths[k + 1, j], lf)))
            acts.append(a)
        rms = np.sqrt(np.mean((np.array(out) - forces[1:, j]) ** 2)) / m.max_isometric_force
        assert rms < 3e-3, (name, rms)
        assert np.abs(np.array(acts) - activations[1:, j]).max() < 2e-3, name
        moving += np.ptp(forces[:, j]) > 0.01 * m.max_isometric_force
    assert moving >= 4  # most of these forces move in this set (BIClong's tendon stays slack): a fair test


def test_only_schutte_muscles_are_read(tmp_path):
    require_models()
    path = models.fetch_model("opensim-models/Models/Arm26/arm26.osim", progress=False)
    with pytest.raises(O2MError, match="not a Schutte1993Muscle_Deprecated"):
        schutte_muscles(path, ["BIClong"])


def test_the_static_equilibrium_is_opensims():
    """Every MoBL-ARMS muscle's static equilibrium at the default pose is the fibre length OpenSim's
    ``equilibrateMuscles`` finds, to its own tolerance (``computeIsometricForce`` stops within
    0.01 N); a unit shorter than its tendon's slack length rests at the muscle's width."""
    require_models()
    path = models.fetch("mobl-arms/MoBL_ARMS_model_for_testing_opensim_no_wrap.osim")
    names = list(muscle_types(path))
    muscles = schutte_muscles(path, names)
    for name, (activation, fibre, length) in default_states(path, names).items():
        m = muscles[name]
        ours = m.equilibrium(activation, length)
        assert abs(ours - fibre) < 1e-5 * m.optimal_fiber_length, name
        assert abs(float(m.tendon_force(length, ours)) - float(m.tendon_force(length, fibre))) < 0.01, name
    m = muscles["DELT1"]
    width = m.optimal_fiber_length * np.sin(m.pennation_angle_at_optimal)
    assert m.equilibrium(0.5, 0.9 * m.tendon_slack_length) == pytest.approx(width)
