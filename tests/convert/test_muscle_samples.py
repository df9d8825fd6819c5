"""OpenSim's side of the muscle fit (o2m.convert.muscle_samples): the bench reproduces the full
model's static tendon forces."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from o2m.convert.muscle_samples import _Bench, _muscle_elements
from tests.helpers import model_file


@pytest.fixture(scope="module")
def arm26() -> Path:
    return model_file("opensim-models/Models/Arm26/arm26.osim")


def test_bench_equals_full_model(arm26):
    """OpenSim's static tendon force on the bench (a straight path of the same MTU length) equals
    the full model's at random poses, at activation 1 and 0."""
    import opensim

    from o2m.osim.document import load_document

    opensim.Logger.setLevelString("error")
    model = opensim.Model(str(arm26))
    state = model.initSystem()
    muscles = [model.getMuscles().get(i) for i in range(model.getMuscles().getSize())]
    names = [m.getName() for m in muscles]
    doc = load_document(arm26)
    elements = _muscle_elements(doc, names)
    bench = _Bench(doc, [elements[n] for n in names])
    cs = model.getCoordinateSet()
    coords = [cs.get(i) for i in range(cs.getSize())]
    rng = np.random.default_rng(7)
    for _ in range(4):
        st = opensim.State(state)
        for c in coords:
            c.setValue(st, float(rng.uniform(c.getRangeMin(), c.getRangeMax())), False)
            c.setSpeedValue(st, 0.0)
        model.assemble(st)
        for a in (1.0, 0.0):
            for m in muscles:
                m.setActivation(st, a)
            model.equilibrateMuscles(st)
            model.realizeDynamics(st)
            full = np.array([m.getTendonForce(st) for m in muscles])
            lengths = np.array([[m.getLength(st)] for m in muscles])
            on_bench, _ = bench.forces(lengths, a)
            np.testing.assert_allclose(on_bench[:, 0], full, rtol=1e-6, atol=1e-6)
