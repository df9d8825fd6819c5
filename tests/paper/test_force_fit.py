"""o2m.force_fit: the fitted force is the force MuJoCo applies, and the fit recovers known muscles."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from o2m.mj.muscle import integrate_activations
from o2m.paper.force_fit import (
    ForceFit,
    ForceSamples,
    MuscleForceFit,
    _bounds,
    _force,
    _start,
    fit_forces,
    pulling_force,
    sample_states,
)

#: A muscle on a fixed tendon of a slide joint, so that the actuator length is the joint position.
SLIDER = """
<mujoco>
  <option timestep="0.002" gravity="0 0 0"/>
  <worldbody>
    <body><joint name="x" type="slide" axis="1 0 0" range="0.1 0.4"/><geom size="0.02" mass="1"/></body>
  </worldbody>
  <tendon><fixed name="m"><joint joint="x" coef="1"/></fixed></tendon>
  <actuator><muscle name="m" tendon="m" lengthrange="0.15 0.35" range="0.6 1.3" force="500"
                    lmin="0.4" lmax="1.8" vmax="2" fpmax="1.2" fvmax="1.3"/></actuator>
</mujoco>
"""


def _model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(SLIDER)


def _known(dynprm: list[float] | None = None) -> MuscleForceFit:
    return MuscleForceFit("m", 500.0, [0.15, 0.35], [0.55, 1.35], 0.35, 1.7, 2.5, 1.4, 1.1, 0.26,
                          [800.0, 2e4, 5e5], 30.0, np.nan, np.nan, np.nan, np.nan, dynprm=dynprm)


def test_applied_model_produces_the_fitted_force():
    m = ForceFit({"m": _known()}).apply(_model())
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    for _ in range(50):
        q, v, a = rng.uniform(0.16, 0.34), rng.uniform(-0.5, 0.5), rng.uniform(0, 1)
        d.qpos[0], d.qvel[0], d.act[0] = q, v, a
        mujoco.mj_forward(m, d)
        pulling = -(d.qfrc_actuator[0] + d.qfrc_passive[0])  # the muscle pulls towards shorter lengths
        assert pulling == pytest.approx(float(_known().force_at(q, v, a)), rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("fitted", [False, True])
def test_pulling_force_is_what_mujoco_applies(fitted):
    m = ForceFit({"m": _known()}).apply(_model()) if fitted else _model()
    d = mujoco.MjData(m)
    rng = np.random.default_rng(1)
    for _ in range(50):
        q, v, a = rng.uniform(0.12, 0.38), rng.uniform(-0.5, 0.5), rng.uniform(0, 1)
        d.qpos[0], d.qvel[0], d.act[0] = q, v, a
        mujoco.mj_forward(m, d)
        assert -(d.qfrc_actuator[0] + d.qfrc_passive[0]) == pytest.approx(float(pulling_force(m, "m", q, v, a)),
                                                                          rel=1e-9, abs=1e-9)


def test_written_mjcf_matches_the_applied_model(tmp_path):
    src = tmp_path / "in.xml"
    src.write_text(SLIDER)
    fit = ForceFit({"m": _known([0.03, 0.09, 0.2])})
    written = mujoco.MjModel.from_xml_path(str(fit.write_mjcf(src, tmp_path / "out.xml")))
    applied = fit.apply(_model())
    for field in ("actuator_gainprm", "actuator_biasprm", "actuator_dynprm", "tendon_stiffness",
                  "tendon_stiffnesspoly", "tendon_lengthspring", "tendon_damping"):
        np.testing.assert_allclose(getattr(written, field), getattr(applied, field), rtol=1e-12, err_msg=field)


def test_the_spring_edge_of_a_short_muscle_stays_where_mujoco_compiles_it(tmp_path):
    """A muscle shorter than the edge's margin (PQ on MoBL-ARMS): the fit may not put the dead
    band's upper end below 0, which MuJoCo's compiler refuses ("invalid springlength")."""
    lo, hi = _bounds(np.array([0.03, 0.06]))
    assert lo[7] == 0.0 and hi[7] > 0.06
    src = tmp_path / "in.xml"
    src.write_text(SLIDER)
    fit = _known()
    fit.edge = lo[7]
    mujoco.MjModel.from_xml_path(str(ForceFit({"m": fit}).write_mjcf(src, tmp_path / "out.xml")))


def _samples(truth: MuscleForceFit, n: int, seed: int) -> ForceSamples:
    rng = np.random.default_rng(seed)
    L = rng.uniform(0.15, 0.35, n)
    V = rng.uniform(-0.6, 0.6, n)
    A = np.clip(rng.uniform(-0.3, 1.0, n), 0, 1)
    F = truth.force_at(L, V, A)
    return ForceSamples(["m"], L[:, None], V[:, None], A[:, None], F[:, None], np.arange(n) // 100)


def test_fit_recovers_a_known_muscle_from_the_converted_start():
    model = _model()
    truth = _known()
    train = _samples(truth, 1500, 1)
    fit = fit_forces(model, train, held_out=_samples(truth, 300, 2), processes=1, progress=False).muscles["m"]
    assert fit.kept
    assert fit.rms_start > 5.0  # the converted muscle is far from the truth (% of F0)
    assert fit.rms < 0.05 and fit.rms_held_out < 0.05
    test = _samples(truth, 500, 3)
    err = fit.force_at(test.length[:, 0], test.velocity[:, 0], test.activation[:, 0]) - test.force[:, 0]
    assert np.max(np.abs(err)) / truth.force < 2e-3


def test_a_fit_worse_on_held_out_states_keeps_its_start():
    model = _model()
    a = model.actuator("m").id
    x0 = _start(model, a, None)
    held = _samples(_known(), 300, 5)  # held-out forces that the start explains exactly
    held.force[:, 0] = _force(x0, 500.0, model.actuator_lengthrange[a], held.length[:, 0], held.velocity[:, 0],
                              held.activation[:, 0])
    fit = fit_forces(model, _samples(_known(), 600, 4), held_out=held, processes=1, progress=False).muscles["m"]
    assert not fit.kept
    assert fit.rms_held_out == pytest.approx(fit.rms_held_out_start, abs=1e-9) and fit.rms_held_out < 1e-6


def test_fit_needs_a_muscle_actuator():
    xml = SLIDER.replace('<muscle name="m" tendon="m" lengthrange="0.15 0.35" range="0.6 1.3" force="500"\n'
                         '                    lmin="0.4" lmax="1.8" vmax="2" fpmax="1.2" fvmax="1.3"/>',
                         '<motor name="m" tendon="m"/>')
    model = mujoco.MjModel.from_xml_string(xml)
    with pytest.raises(ValueError, match="not a muscle"):
        fit_forces(model, _samples(_known(), 100, 0), processes=1, progress=False)


@pytest.mark.parametrize("tausmooth", [0.0, 0.3])
def test_integrated_activations_are_what_mujoco_steps(tausmooth):
    model = _model()
    model.actuator_dynprm[0, :3] = [0.03, 0.09, tausmooth]
    data = mujoco.MjData(model)
    controls = np.random.default_rng(6).uniform(-0.2, 1.2, (300, 1))  # MuJoCo clamps them to [0, 1]
    data.act[0] = 0.2
    stepped = [data.act[0]]
    for c in controls:
        data.ctrl[0] = c[0]
        mujoco.mj_step(model, data)
        stepped.append(data.act[0])
    ours = integrate_activations(controls, np.array([0.2]), model.actuator_dynprm[:, :3], model.opt.timestep)
    np.testing.assert_allclose(ours[:, 0], stepped, rtol=0, atol=1e-12)


def _dynamic_samples(truth: MuscleForceFit, n_traj: int, seed: int, model: mujoco.MjModel) -> ForceSamples:
    """Trajectories of sine excitations; the force at each sample is the truth's at its own time constants,
    the activations given are the model's (what the fit starts from)."""
    rng = np.random.default_rng(seed)
    t = np.arange(400) * 0.002
    f, phase = rng.uniform(0.5, 4.0, (n_traj, 1)), rng.uniform(0, 2 * np.pi, (n_traj, 1))
    exc = (0.5 * (1 + np.sin(2 * np.pi * f * t + phase)))[..., None]
    controls = 0.5 * (exc[:, :-1] + exc[:, 1:])
    a0 = np.zeros((n_traj, 1))
    true_act = integrate_activations(controls, a0, truth.dynprm, 0.002)
    given_act = integrate_activations(controls, a0, model.actuator_dynprm[:, :3], 0.002)
    traj, step = np.divmod(np.arange(n_traj * 400), 400)
    L, V = rng.uniform(0.15, 0.35, traj.size), rng.uniform(-0.6, 0.6, traj.size)
    F = truth.force_at(L, V, true_act[traj, step, 0])
    return ForceSamples(["m"], L[:, None], V[:, None], given_act[traj, step], F[:, None], traj, step, controls, a0,
                        0.002)


def test_fit_recovers_known_activation_time_constants():
    model = _model()  # MuJoCo's default time constants, 0.01 / 0.04 s
    truth = _known()
    truth.dynprm = [0.03, 0.09, 0.0]
    train, held = _dynamic_samples(truth, 6, 7, model), _dynamic_samples(truth, 2, 8, model)
    static = fit_forces(model, train, held_out=held, processes=1, progress=False, fit_dynamics=False).muscles["m"]
    fit = fit_forces(model, train, held_out=held, processes=1, progress=False).muscles["m"]
    assert static.dynprm is None and static.rms > 1.0  # the curves alone cannot make up the lag (% of F0)
    assert fit.kept and fit.rms < 0.1 and fit.rms_held_out < 0.1
    np.testing.assert_allclose(fit.dynprm[:2], truth.dynprm[:2], rtol=0.05)
    applied = ForceFit({"m": fit}).apply(model)
    np.testing.assert_allclose(applied.actuator_dynprm[0, :3], fit.dynprm)


def test_samples_of_zero_weight_do_not_move_the_fit():
    truth = _known()
    train = _samples(truth, 1500, 9)
    corrupted = np.arange(1500) % 3 == 0
    train.force[corrupted, 0] *= 1.3
    train.weight = np.where(corrupted, 0.0, 1.0)[:, None]
    fit = fit_forces(_model(), train, held_out=_samples(truth, 300, 10), processes=1, progress=False).muscles["m"]
    assert fit.kept and fit.rms_held_out < 0.05


def test_sampled_weights_are_the_moment_arms_scaled_to_rms_one():
    model = _model()  # the muscle's tendon is the slide joint itself: moment arm 1 at every pose
    q = np.linspace(0.16, 0.34, 8)[None, :, None]
    zeros = np.zeros_like(q)
    s = sample_states(model, q, zeros, zeros, zeros, ["x"], ["m"], stride=1, weight_coordinates=["x"])
    np.testing.assert_allclose(s.weight, 1.0)
    np.testing.assert_allclose(s.length[:, 0], q[0, :, 0])


def test_acceleration_weights_are_what_a_unit_pull_does_to_the_joint():
    from o2m.mj.simulate import STATE_SPEC, initial_state
    from tests.paper.test_fitting import pendulum

    model = pendulum(0.1)  # a hinge lifted by a muscle, and a joint an equality couples to it (coef 0.5)
    q = np.linspace(-0.6, 0.6, 7)[None, :, None]
    zeros = np.zeros_like(q)
    s = sample_states(model, q, zeros, zeros, zeros, ["swing"], ["lifter"], stride=1, weight_coordinates=["swing"],
                      weighting="acceleration")
    data, pulled = mujoco.MjData(model), []
    for angle in q[0, :, 0]:  # MuJoCo's own answer: the swing's acceleration per newton on the tendon
        acc = []
        for force in (0.0, 1.0):
            mujoco.mj_setState(model, data, initial_state(model, {"swing": angle}), STATE_SPEC)
            mujoco.mj_fwdPosition(model, data)
            data.qfrc_applied[:] = force * data.ten_J[0]
            mujoco.mj_forward(model, data)
            acc.append(data.qacc[0])
        pulled.append(abs(acc[1] - acc[0]))
    pulled = np.array(pulled)
    assert np.ptp(pulled) > 0.2 * pulled.mean()  # the arm changes with the angle: the test can fail
    np.testing.assert_allclose(s.weight[:, 0], pulled / np.sqrt(np.mean(pulled**2)), rtol=0.02)
    with pytest.raises(ValueError, match="weighting"):
        sample_states(model, q, zeros, zeros, zeros, ["swing"], ["lifter"], weight_coordinates=["swing"],
                      weighting="torque")


#: A hinge and a follower an equality couples to it (MuJoCo's default soft equality, so the follower
#: lags in a rollout), and a muscle whose tendon crosses both.
COUPLED = """
<mujoco>
  <option timestep="0.002" gravity="0 0 0"/>
  <worldbody>
    <body><joint name="swing" type="hinge" axis="0 1 0" damping="0.2"/><geom size="0.05" pos="0.3 0 0" mass="1"/>
      <body><joint name="follow" type="hinge" axis="0 1 0"/><geom size="0.05" pos="0.2 0 0" mass="0.5"/></body>
    </body>
  </worldbody>
  <tendon><fixed name="m"><joint joint="swing" coef="0.03"/><joint joint="follow" coef="0.03"/></fixed></tendon>
  <equality><joint joint1="follow" joint2="swing" polycoef="0 0.5 0 0 0"/></equality>
  <actuator><muscle name="m" tendon="m" force="400" lengthrange="-0.1 0.1"/></actuator>
</mujoco>
"""


def test_a_run_up_samples_the_lengths_and_velocities_a_rollout_gives():
    from o2m.activations import generate_activations
    from o2m.mj.simulate import STATE_SPEC, controls_from_excitations, initial_state, rollout

    model = mujoco.MjModel.from_xml_string(COUPLED)
    excitations = generate_activations(["m"], 2, seed=3, p_active=1.0).values[:, :200]
    init = np.stack([initial_state(model, {"swing": a}) for a in (-0.3, 0.3)])
    tr = rollout(model, init, controls_from_excitations(model, ["m"], excitations), joint_names=["swing", "follow"])
    data, own = mujoco.MjData(model), []
    for state in tr.states[:, ::5].reshape(-1, tr.states.shape[-1]):  # the rollout's own muscle velocities
        mujoco.mj_setState(model, data, state, STATE_SPEC)
        mujoco.mj_forward(model, data)
        own.append(data.actuator_velocity[0])
    gaps = {}
    for settle in (0, 100):
        s = sample_states(model, tr.coordinates[..., :1], tr.qvel[..., :1], tr.act, np.zeros_like(tr.act), ["swing"],
                          ["m"], stride=5, excitations=excitations, settle=settle)
        gaps[settle] = np.abs(s.velocity[:, 0] - own)[s.step > 100].max()
    assert gaps[0] > 5e-5  # m/s: rebuilt on its equality, the follower has lost its lag
    assert gaps[100] < 0.01 * gaps[0]  # after 0.2 s of run-up it lags as in the rollout
    with pytest.raises(ValueError, match="excitations"):
        sample_states(model, tr.coordinates[..., :1], tr.qvel[..., :1], tr.act, np.zeros_like(tr.act), ["swing"],
                      ["m"], settle=5)
