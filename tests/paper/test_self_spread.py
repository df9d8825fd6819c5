"""OpenSim against itself (o2m.paper.self_spread): the comparison and the perturbed-model writer."""

from __future__ import annotations

import numpy as np
import pytest

from o2m.paper.self_spread import compare_runs, scale_muscle_forces
from tests.helpers import MUSCLE_PENDULUM, model_file


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



def _pendulum_experiment():
    """A one-muscle pendulum laid out like :func:`o2m.paper.load_experiment`'s experiment."""
    from types import SimpleNamespace

    import mujoco

    from o2m.mj.simulate import initial_state

    model = mujoco.MjModel.from_xml_string(MUSCLE_PENDULUM)
    n_t = 201
    ds = SimpleNamespace(coordinate_names=["swing"], coordinates=np.full((1, n_t, 1), 0.3),
                         speeds=np.zeros((1, n_t, 1)), muscle_names=["lifter"],
                         opensim_activations=np.full((1, n_t, 1), 0.5))
    init = initial_state(model, {"swing": 0.3}, speeds={"swing": 0.0}, activations={"lifter": 0.5})[None]
    controls = (0.5 + 0.4 * np.sin(np.linspace(0, 6, n_t - 1)))[None, :, None]
    return SimpleNamespace(dataset=ds, dofs=["swing"], init=init, controls=controls), model


def test_mujoco_self_spread_of_a_pendulum():
    """Stronger muscles and a moved start move the pendulum; no change moves nothing; an
    integrator variant has no MuJoCo counterpart and is skipped."""
    from o2m.osim.simulate import IntegratorSettings
    from o2m.paper.self_spread import Variant, mujoco_self_spread

    exp, model = _pendulum_experiment()
    variants = (Variant("stronger", "forces x 1.01", muscle_edits=(("*", "max_isometric_force", 1.01, 0.0),)),
                Variant("moved", "start + 1e-3 rad", initial_offsets=(("swing", 1e-3),)),
                Variant("same", "start + 0", initial_offsets=(("swing", 0.0),)),
                Variant("tighter", "accuracy 1e-6", IntegratorSettings(accuracy=1e-6)))
    out = mujoco_self_spread(exp, model, [0], variants)
    assert list(out["mujoco_variants"]) == ["stronger", "moved", "same"]
    assert out["mujoco_spread"].shape == (3, 1, 1)
    stronger, moved, same = out["mujoco_spread"][:, 0, 0]
    assert stronger > 1e-4 and moved > 1e-5
    assert same == 0.0
    assert model.actuator_gainprm[0, 2] == 40.0  # the caller's model is left as it was
