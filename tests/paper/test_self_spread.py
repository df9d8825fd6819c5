"""OpenSim against itself (o2m.paper.self_spread): the comparison and the perturbed-model writer."""

from __future__ import annotations

import numpy as np
import pytest

from o2m.paper.self_spread import compare_runs, scale_muscle_forces
from tests.helpers import model_file


def test_compare_runs_mean_and_max_per_joint():
    """A constant offset per joint comes back as that offset; a missing run as NaN."""
    t = np.linspace(0, 1, 50)
    reference = np.stack([np.sin(t), np.cos(t)], axis=-1)[None].repeat(3, axis=0)  # (3 sets, 50, 2 joints)
    other = reference + np.array([0.01, -0.002])
    other[1, 10, 0] += 0.5  # one spike in set 1, joint 0
    other[2] = np.nan  # set 2 failed
    mean, peak = compare_runs(reference, other)
    assert mean.shape == peak.shape == (3, 2)
    np.testing.assert_allclose(mean[0], [0.01, 0.002])
    np.testing.assert_allclose(peak[1], [0.51, 0.002])
    assert mean[1, 0] > mean[0, 0]
    assert np.isnan(mean[2]).all() and np.isnan(peak[2]).all()


def test_scaled_model_loads_in_opensim_with_stronger_muscles(tmp_path):
    """Every muscle's max isometric force is scaled, and OpenSim reads the written file."""
    from o2m.osim.runtime import load_model

    src = model_file("opensim-models/Models/Arm26/arm26.osim")
    dst = tmp_path / "arm26_stronger.osim"
    changed = scale_muscle_forces(src, dst, 1.001)
    before, _ = load_model(src)
    after, _ = load_model(dst)
    muscles_before, muscles_after = before.getMuscles(), after.getMuscles()
    assert changed >= muscles_after.getSize() == muscles_before.getSize() > 0
    for i in range(muscles_after.getSize()):
        f0 = muscles_before.get(i).getMaxIsometricForce()
        assert muscles_after.get(i).getMaxIsometricForce() == np.float64(f0 * 1.001)


def test_edit_one_muscle_leaves_the_others(tmp_path):
    """An offset on one muscle's optimal fibre length changes that muscle only; a wrong name raises."""
    from o2m.osim.runtime import load_model
    from o2m.paper.self_spread import edit_muscles

    src = model_file("opensim-models/Models/Arm26/arm26.osim")
    dst = tmp_path / "arm26_longer_fibre.osim"
    assert edit_muscles(src, dst, (("BRA", "optimal_fiber_length", 1.0, 1e-4),)) == 1
    before, _ = load_model(src)
    after, _ = load_model(dst)
    for i in range(after.getMuscles().getSize()):
        m0, m1 = before.getMuscles().get(i), after.getMuscles().get(i)
        added = 1e-4 if m1.getName() == "BRA" else 0.0
        assert m1.getOptimalFiberLength() - m0.getOptimalFiberLength() == pytest.approx(added, abs=1e-15)
    with pytest.raises(KeyError):
        edit_muscles(src, dst, (("NOPE", "optimal_fiber_length", 1.0, 1e-4),))
