"""CMA-ES parameter fitting and corrective controls, on small models (seconds)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from o2m.activations import generate_activations
from o2m.mj.simulate import controls_from_excitations, initial_state, rollout
from o2m.paper.corrections import bspline_basis, corrected_excitations, fit_corrections
from o2m.paper.fitting import (
    TrajectoryObjective,
    checkpoint_matches,
    fit_cma,
    free_coordinates,
    load_fit,
    parameter_space,
    save_fit,
)

PENDULUM = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="link" pos="0 0 1">
      <joint name="swing" type="hinge" axis="0 1 0" damping="{damping}"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.03" mass="1"/>
      <site name="tip" pos="0.5 0 0"/>
    </body>
    <body name="follower" pos="0 0 2">
      <joint name="follow" type="hinge" axis="0 1 0"/>
      <geom type="sphere" size="0.05" mass="0.1"/>
    </body>
    <site name="anchor" pos="0.3 0 1.4"/>
  </worldbody>
  <tendon><spatial name="lifter"><site site="anchor"/><site site="tip"/></spatial></tendon>
  <equality><joint joint1="follow" joint2="swing" polycoef="0 0.5 0 0 0"/></equality>
  <actuator><muscle name="lifter" tendon="lifter" force="40" lengthrange="0.3 0.9"/></actuator>
</mujoco>
"""


def pendulum(damping: float) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(PENDULUM.format(damping=damping))


def _setup(true_damping: float, start_damping: float, n: int = 4, steps: int = 250):
    truth, model = pendulum(true_damping), pendulum(start_damping)
    sets = generate_activations(["lifter"], n, seed=1, p_active=1.0)
    ctrl = controls_from_excitations(model, ["lifter"], sets.values[:, :steps])
    init = np.stack([initial_state(model, {"swing": a}) for a in np.linspace(-0.5, 0.5, n)])
    ref = rollout(truth, init, ctrl, joint_names=["swing"]).coordinates
    return model, init, ctrl, ref


def test_free_coordinates_skip_equality_driven_joints():
    assert free_coordinates(pendulum(0.1), ["swing", "follow", "missing"]) == ["swing"]


def test_parameter_space_has_the_papers_layout():
    space = parameter_space(pendulum(0.1), ["swing"], ["lifter"])
    assert space.names == ["damping:swing", "limit_timeconst:swing", "tendon_damping:lifter",
                           "tendon_stiffness:lifter", "muscle_scale:lifter"]
    assert np.all(space.lower <= space.x0) and np.all(space.x0 <= space.upper)
    m = space.apply(pendulum(0.1), space.x0 + np.array([0, 0, 0, 0, np.log10(2)]))
    assert m.actuator_gainprm[0, 2] == pytest.approx(80) and m.dof_damping[0] == pytest.approx(0.1)


def test_objective_is_zero_for_identical_trajectories():
    model, init, ctrl, ref = _setup(0.3, 0.3)
    space = parameter_space(model, ["swing"], ["lifter"])
    obj = TrajectoryObjective(model, space, init, ctrl, ref, ["swing"])
    assert obj(space.x0[None])[0] == 0.0
    other = space.x0.copy()
    other[0] += 0.5
    assert obj(other[None])[0] > 1e-6


def test_fit_recovers_a_known_damping(tmp_path):
    model, init, ctrl, ref = _setup(0.5, 0.05)
    space = parameter_space(model, ["swing"], [])
    obj = TrajectoryObjective(model, space, init, ctrl, ref, ["swing"], penalty=0.0)
    fit = fit_cma(obj, seed=0, sigma0=0.2, generations=40, checkpoint=tmp_path / "ckpt.pkl", progress=False)
    assert fit.cost < 1e-3 * fit.cost0
    assert fit.values(space)["damping:swing"] == pytest.approx(0.5, rel=0.05)
    assert np.all(np.diff(fit.history) <= 0)
    # resuming from the checkpoint continues, not restarts
    more = fit_cma(obj, seed=0, sigma0=0.2, generations=45, checkpoint=tmp_path / "ckpt.pkl", progress=False)
    assert len(more.history) == 45 and more.cost <= fit.cost and more.cost0 == fit.cost0
    saved = load_fit(save_fit(tmp_path / "fit.json", more))
    assert np.array_equal(saved.x, more.x) and saved.names == more.names
    # a checkpoint from a fit that started elsewhere is refused, not silently resumed
    other, o_init, o_ctrl, o_ref = _setup(0.5, 0.2)
    o_space = parameter_space(other, ["swing"], [])
    o_obj = TrajectoryObjective(other, o_space, o_init, o_ctrl, o_ref, ["swing"], penalty=0.0)
    assert checkpoint_matches(tmp_path / "ckpt.pkl", obj.space, 0)
    assert not checkpoint_matches(tmp_path / "ckpt.pkl", o_space, 0)
    assert not checkpoint_matches(tmp_path / "ckpt.pkl", obj.space, 1)
    # nor is one of another model file with the same parameters and start
    assert not checkpoint_matches(tmp_path / "ckpt.pkl", obj.space, 0, "other.xml")
    named = fit_cma(obj, seed=0, sigma0=0.2, generations=1, checkpoint=tmp_path / "named.pkl", progress=False,
                    settings={"xml": "pendulum.xml"})
    assert checkpoint_matches(tmp_path / "named.pkl", obj.space, 0, "pendulum.xml")
    assert not checkpoint_matches(tmp_path / "named.pkl", obj.space, 0, "pendulum_fibres.xml")
    assert len(named.history) == 1
    with pytest.raises(ValueError, match="another fit"):
        fit_cma(o_obj, seed=0, sigma0=0.2, generations=45, checkpoint=tmp_path / "ckpt.pkl", progress=False)


def test_validation_stops_a_fit_that_only_helps_the_training_sets(tmp_path):
    """Training sets from a damping of 0.5, validation sets from the start's 0.05: the start is kept."""
    model, init, ctrl, ref = _setup(0.5, 0.05)
    _, v_init, v_ctrl, v_ref = _setup(0.05, 0.05, n=2)
    space = parameter_space(model, ["swing"], [])
    train = TrajectoryObjective(model, space, init, ctrl, ref, ["swing"], penalty=0.0)
    held = TrajectoryObjective(model, space, v_init, v_ctrl, v_ref, ["swing"], penalty=0.0)
    fit = fit_cma(train, seed=0, sigma0=0.2, generations=10, progress=False, validation=held)
    assert fit.settings["best_training_cost"] < 0.1 * fit.cost0  # training alone would move far
    assert fit.validation_cost == fit.validation_cost0 < 1e-20 and np.array_equal(fit.x, space.x0)
    saved = load_fit(save_fit(tmp_path / "fit.json", fit))
    assert saved.validation_cost == fit.validation_cost


def test_bspline_basis_is_a_partition_of_unity_with_10_hz_knots():
    t = np.arange(500) * 0.002
    b = bspline_basis(t)
    assert b.shape == (500, 13)
    assert np.allclose(b.sum(axis=1), 1.0)
    assert np.all((b > 0).sum(axis=1) <= 4)


def test_corrections_against_the_model_itself_stay_zero():
    model, init, ctrl, _ = _setup(0.3, 0.3, n=1)
    sets = generate_activations(["lifter"], 1, seed=1, p_active=1.0)
    exc = sets.values[0, :250]
    ref = rollout(model, init, controls_from_excitations(model, ["lifter"], exc)[None],
                  joint_names=["swing"]).coordinates[0]
    res = fit_corrections(model, init[0], exc, ["lifter"], ref, ["swing"], generations=3, seed=0)
    assert res.cost0 == 0.0 and np.abs(res.correction).max() < 1e-3


def _weaker_model_problem():
    """A pendulum whose muscle is 30 % weaker than the one that made the reference: the weak
    model, its initial state, the excitations (T, 1) and the reference swing (T, 1)."""
    truth = pendulum(0.3)
    weak = pendulum(0.3)
    weak.actuator_gainprm[0, 2] *= 0.7
    weak.actuator_biasprm[0, 2] *= 0.7
    sets = generate_activations(["lifter"], 1, seed=2, p_active=1.0)
    exc = 0.6 * sets.values[0, :250]
    init = initial_state(truth, {"swing": 0.2})
    ref = rollout(truth, init, controls_from_excitations(truth, ["lifter"], exc)[None],
                  joint_names=["swing"]).coordinates[0]
    return weak, init, exc, ref


def test_corrections_reduce_the_error_of_a_weaker_model():
    weak, init, exc, ref = _weaker_model_problem()
    res = fit_corrections(weak, init, exc, ["lifter"], ref, ["swing"], generations=8, seed=0, penalty=1e-3)
    assert res.cost < 0.3 * res.cost0
    assert res.joint_mae[0] < res.joint_mae0[0]
    assert np.all(res.excitations >= 0) and np.all(res.excitations <= 1)
    # a second pass over the blocks starts where the first ended and keeps only improvements
    two = fit_corrections(weak, init, exc, ["lifter"], ref, ["swing"], generations=8, seed=0, penalty=1e-3,
                          sweeps=2)
    assert two.cost <= res.cost and two.evaluations > res.evaluations


def test_levenberg_marquardt_corrections_reduce_the_error_of_a_weaker_model():
    """Per block, the window cost is a sum of squares: a few Gauss-Newton steps take it most of
    the way, deterministically, and never above the cost without correction."""
    weak, init, exc, ref = _weaker_model_problem()
    lm = fit_corrections(weak, init, exc, ["lifter"], ref, ["swing"], method="lm", iterations=2, penalty=1e-3)
    assert lm.cost < 0.01 * lm.cost0
    assert lm.joint_mae[0] < 0.1 * lm.joint_mae0[0]
    assert np.all(lm.excitations >= 0) and np.all(lm.excitations <= 1)
    again = fit_corrections(weak, init, exc, ["lifter"], ref, ["swing"], method="lm", iterations=2, penalty=1e-3)
    np.testing.assert_array_equal(again.coef, lm.coef)  # deterministic: no seed
    with pytest.raises(ValueError, match="method"):
        fit_corrections(weak, init, exc, ["lifter"], ref, ["swing"], method="adam")


def test_a_tendon_with_a_spring_gets_a_spring_scale():
    """A muscle tendon whose spring holds the passive force (o2m.force_fit) is scaled, not replaced."""
    model = pendulum(0.1)
    t = model.tendon("lifter").id
    model.tendon_stiffness[t] = 50.0
    model.tendon_stiffnesspoly[t] = [200.0, 1000.0]
    space = parameter_space(model, ["swing"], ["lifter"])
    assert "spring_scale:lifter" in space.names and "tendon_stiffness:lifter" not in space.names
    assert len(space) == 5  # damping, limit, tendon damping, spring scale, muscle scale
    x = space.x0.copy()
    x[space.names.index("spring_scale:lifter")] = np.log10(3.0)
    m = space.apply(model, x)
    np.testing.assert_allclose(m.tendon_stiffness[t], 150.0)
    np.testing.assert_allclose(m.tendon_stiffnesspoly[t], [600.0, 3000.0])
    plain = parameter_space(pendulum(0.1), ["swing"], ["lifter"])
    assert "tendon_stiffness:lifter" in plain.names


def test_force_matching_start_recovers_the_excitation_that_made_the_forces():
    """Forces recorded from the true excitation, references from a weaker one: the start brings it back."""
    from o2m.paper.corrections import force_matching_start
    from o2m.paper.force_fit import pulling_force

    model = pendulum(0.3)
    sets = generate_activations(["lifter"], 1, seed=2, p_active=1.0)
    true_exc = 0.2 + 0.6 * sets.values[0, :250]  # (250, 1)
    init = initial_state(model, {"swing": 0.2})
    tr = rollout(model, init, controls_from_excitations(model, ["lifter"], true_exc)[None])
    a = model.actuator("lifter").id
    lengths, velocities, forces = np.zeros((250, 1)), np.zeros((250, 1)), np.zeros((250, 1))
    d = mujoco.MjData(model)
    for k in range(250):
        d.qpos[:], d.qvel[:] = tr.qpos[0, k], tr.qvel[0, k]
        mujoco.mj_forward(model, d)
        lengths[k], velocities[k] = d.actuator_length[a], d.actuator_velocity[a]
        forces[k] = pulling_force(model, "lifter", lengths[k], velocities[k], tr.act[0, k])
    reference = 0.5 * true_exc
    coef = force_matching_start(model, reference, ["lifter"], lengths, velocities, forces)
    recovered = corrected_excitations(reference, bspline_basis(0.002 * np.arange(250)), coef)
    assert np.mean(np.abs(recovered - true_exc)) < 0.1 * np.mean(np.abs(reference - true_exc))


def test_written_mjcf_is_the_applied_model(tmp_path):
    src = tmp_path / "pendulum.xml"
    spring = '<spatial name="lifter" stiffness="5 20 100" springlength="0 0.5">'
    src.write_text(PENDULUM.format(damping=0.1).replace('<spatial name="lifter">', spring))
    model = mujoco.MjModel.from_xml_path(str(src))
    space = parameter_space(model, ["swing"], ["lifter"])
    x = space.x0 + np.random.default_rng(0).uniform(-0.5, 0.5, len(space))
    written = mujoco.MjModel.from_xml_path(str(space.write_mjcf(model, x, src, tmp_path / "fitted.xml")))
    applied = space.apply(model, x)
    for f in ("dof_damping", "jnt_solref", "tendon_damping", "tendon_stiffness", "tendon_stiffnesspoly",
              "actuator_gainprm", "actuator_biasprm"):
        np.testing.assert_allclose(getattr(written, f), getattr(applied, f), rtol=1e-12, err_msg=f)


def test_objective_through_an_executor_equals_the_local_one():
    distributed = pytest.importorskip("distributed")
    model, init, ctrl, ref = _setup(0.5, 0.05)
    space = parameter_space(model, ["swing"], [])
    xs = space.x0 + np.array([[0.0, 0.0], [0.3, 0.0], [-0.2, 0.1]])
    local = TrajectoryObjective(model, space, init, ctrl, ref, ["swing"])(xs)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as c, \
            distributed.Client(c) as client:
        remote = TrajectoryObjective(model, space, init, ctrl, ref, ["swing"], executor=client.get_executor())
        np.testing.assert_array_equal(remote(xs), local)
        assert remote.evaluations == 3


def test_without_early_stopping_the_best_training_candidate_is_kept_and_scored(tmp_path):
    """The paper's way: the same fit as above, not early-stopped, moves to the training sets'
    damping, and its validation cost says how much that costs the held-out sets."""
    model, init, ctrl, ref = _setup(0.5, 0.05)
    _, v_init, v_ctrl, v_ref = _setup(0.05, 0.05, n=2)
    space = parameter_space(model, ["swing"], [])
    train = TrajectoryObjective(model, space, init, ctrl, ref, ["swing"], penalty=0.0)
    held = TrajectoryObjective(model, space, v_init, v_ctrl, v_ref, ["swing"], penalty=0.0)
    fit = fit_cma(train, seed=0, sigma0=0.2, generations=10, progress=False, validation=held, early_stopping=False)
    assert fit.cost == fit.settings["best_training_cost"] < 0.1 * fit.cost0
    assert fit.validation_cost == pytest.approx(float(held(fit.x[None])[0]))
    assert fit.validation_cost > 1e3 * max(fit.validation_cost0, 1e-20)
    assert fit.settings["early_stopping"] is False
