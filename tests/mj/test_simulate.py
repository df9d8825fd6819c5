"""Forward simulation in OpenSim and MuJoCo: agreement, batching, and failure records."""

from __future__ import annotations

import concurrent.futures as cf
import copy

import mujoco
import numpy as np
import pytest

from o2m import models
from o2m.activations import generate_activations
from o2m.convert.converter import convert
from o2m.mj.simulate import (
    controls_from_excitations,
    controls_from_forces,
    force_driven,
    initial_state,
    muscle_activations,
    rollout,
    state_layout,
    step_loop,
)
from o2m.osim.simulate import OpenSimRun, run_isolated, run_many, simulate
from tests.helpers import convert_options, require_models

LIFTER = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="link" pos="0 0 1">
      <joint name="swing" type="hinge" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.03" mass="1"/>
      <site name="tip" pos="0.5 0 0"/>
    </body>
    <site name="anchor" pos="0.3 0 1.4"/>
  </worldbody>
  <tendon>
    <spatial name="lifter" stiffness="20" springlength="0 0.6"><site site="anchor"/><site site="tip"/></spatial>
  </tendon>
  <actuator>
    <muscle name="lifter" tendon="lifter" force="40" lengthrange="0.3 0.9"/>
    <motor name="push" joint="swing" gear="1"/>
  </actuator>
</mujoco>
"""

ARM26_MUSCLES = ["TRIlong", "TRIlat", "TRImed", "BIClong", "BICshort", "BRA"]


@pytest.fixture(scope="module")
def arm26(tmp_path_factory):
    require_models()
    fetched = models.fetch_model_with_geometry("arm26", progress=False)
    # the wrap fit at its full size (as without O2M_QUICK): the quick fit leaves BIClong about 1 mm off
    conv = convert(fetched.osim, tmp_path_factory.mktemp("arm26"), convert_options(quick=False, workers=2),
                   geometry_dirs=[fetched.geometry_dir])
    return fetched.osim, mujoco.MjModel.from_xml_path(str(conv.xml))


def test_opensim_and_mujoco_agree_on_a_simple_excitation(arm26):
    """The triceps excited at 0.5 for 0.3 s, from rest with the muscles in equilibrium.

    OpenSim moves the shoulder 0.58 rad and the elbow 0.34 rad; MuJoCo stays within 0.12 rad
    (measured: 0.093 rad shoulder, 0.097 rad elbow). What is left is the muscle model (MuJoCo's
    rigid tendon against Thelen's elastic one); flexor or co-contraction excitations leave more
    (0.2 to 0.5 rad), which is what :mod:`o2m.force_fit` and the parameter fit address.
    """
    osim, model = arm26
    t = np.arange(151) * 0.002
    exc = np.zeros((len(t), 6))
    exc[:, :3] = 0.5  # TRIlong, TRIlat, TRImed
    run = simulate(osim, t, exc, ARM26_MUSCLES)
    assert run.ok and np.isfinite(run.coordinates).all()
    # tendon forces (N) from equilibrium: no start at many times the max isometric force (800 N)
    assert np.isfinite(run.tendon_forces).all() and (run.tendon_forces >= 0).all()
    assert run.tendon_forces[0].max() < 200
    init = initial_state(model, dict(zip(run.coordinate_names, run.coordinates[0], strict=False)),
                         activations=dict(zip(run.muscle_names, run.activations[0], strict=False)))
    tr = rollout(model, init, controls_from_excitations(model, ARM26_MUSCLES, exc)[None],
                 joint_names=run.coordinate_names)
    assert not tr.diverged[0]
    assert np.array_equal(tr.coordinates[0, 0], run.coordinates[0])  # same initial state
    moved = np.abs(run.coordinates[-1] - run.coordinates[0])
    assert moved.min() > 0.3
    err = np.abs(tr.coordinates[0] - run.coordinates)
    assert err.max() < 0.12, err.max(axis=0)


def test_batched_rollout_equals_a_plain_step_loop(arm26):
    _, model = arm26
    sets = generate_activations(ARM26_MUSCLES, 4, seed=3)
    ctrl = controls_from_excitations(model, ARM26_MUSCLES, sets.values[:, :200])
    rng = np.random.default_rng(0)
    init = np.stack([initial_state(model, {"r_shoulder_elev": rng.uniform(0, 1), "r_elbow_flex": rng.uniform(0, 2)})
                     for _ in range(4)])
    batched = rollout(model, init, ctrl, nthread=2)
    looped = step_loop(model, init, ctrl)
    assert batched.qpos.shape == (4, 200, model.nq)
    assert np.array_equal(batched.states, looped.states)
    assert not batched.diverged.any()
    assert np.allclose(batched.times, np.arange(200) * model.opt.timestep)


def test_controls_are_step_means_of_linear_excitations(arm26):
    _, model = arm26
    exc = np.linspace(0, 1, 11)[:, None] * np.ones((1, 6))
    ctrl = controls_from_excitations(model, ARM26_MUSCLES, exc)
    assert ctrl.shape == (10, model.nu)
    ids = [model.actuator(m).id for m in ARM26_MUSCLES]
    assert np.allclose(ctrl[:, ids], (np.arange(10)[:, None] + 0.5) / 10)


def test_muscle_activations_are_what_mujoco_steps(arm26):
    _, model = arm26
    sets = generate_activations(ARM26_MUSCLES, 2, seed=5, p_active=1.0)
    exc = sets.values[:, :150]
    a0 = np.array([[0.05] * 6, [0.3, 0.0, 0.2, 0.9, 0.1, 0.5]])
    init = np.stack([initial_state(model, {}, activations=dict(zip(ARM26_MUSCLES, a, strict=True))) for a in a0])
    tr = rollout(model, init, controls_from_excitations(model, ARM26_MUSCLES, exc))
    ids = [model.actuator_actadr[model.actuator(m).id] for m in ARM26_MUSCLES]
    np.testing.assert_allclose(muscle_activations(model, ARM26_MUSCLES, exc, a0), tr.act[:, :, ids], atol=1e-12)
    smoothed = copy.deepcopy(model)
    smoothed.actuator_dynprm[:, 2] = 0.05  # tausmooth, s (a force fit may set it)
    tr = rollout(smoothed, init, controls_from_excitations(smoothed, ARM26_MUSCLES, exc))
    np.testing.assert_allclose(muscle_activations(smoothed, ARM26_MUSCLES, exc, a0), tr.act[:, :, ids], atol=1e-12)


def test_initial_state_sets_named_values(arm26):
    _, model = arm26
    s = initial_state(model, {"r_elbow_flex": 1.0, "not_a_joint": 3.0}, speeds={"r_elbow_flex": -2.0},
                      activations={"BIClong": 0.3}, time=0.5)
    lay = state_layout(model)
    adr = model.joint("r_elbow_flex").qposadr[0]
    assert s[lay["time"]][0] == 0.5
    assert s[lay["qpos"]][adr] == 1.0 and s[lay["qvel"]][model.joint("r_elbow_flex").dofadr[0]] == -2.0
    assert s[lay["act"]][model.actuator_actadr[model.actuator("BIClong").id]] == 0.3


def test_divergence_is_flagged(arm26):
    _, model = arm26
    bad = initial_state(model, {"r_elbow_flex": 1.0})
    lay = state_layout(model)
    bad[lay["qvel"]] = 1e12  # MuJoCo resets such a state and says so only in a warning
    tr = rollout(model, np.stack([initial_state(model, {}), bad]), np.zeros((2, 20, model.nu)))
    assert tr.diverged.tolist() == [False, True]


def test_failures_are_recorded_not_raised(arm26, tmp_path):
    osim, _ = arm26
    t = np.arange(101) * 0.002
    missing = run_isolated(tmp_path / "missing.osim", t, np.zeros((len(t), 6)), ARM26_MUSCLES, timeout=60)
    assert missing.status == "failed" and "Cannot open file" in missing.reason
    long_t = np.arange(30001) * 0.002  # 60 s of motion: far more than 1 s of wall clock
    slow = run_isolated(osim, long_t, np.full((len(long_t), 6), 0.5), ARM26_MUSCLES, timeout=1.0)
    assert slow.status == "timeout" and slow.t_reached < long_t[-1]
    nan = np.zeros((len(t), 6))
    nan[50:, 3] = np.nan
    run = simulate(osim, t, nan, ARM26_MUSCLES)
    assert run.status == "nan" and not np.isfinite(run.coordinates).all()


def test_run_many_keeps_going_past_a_failure_on_a_dask_cluster(arm26):
    distributed = pytest.importorskip("distributed")
    osim, _ = arm26
    t = np.arange(101) * 0.002
    sets = np.zeros((3, len(t), 6))
    sets[1, :, 3] = np.nan  # this set goes non-finite
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as c, \
            distributed.Client(c) as client:
        runs = run_many(osim, t, sets, ARM26_MUSCLES, executor=client.get_executor(), progress=False)
    assert [r.status for r in runs] == ["ok", "nan", "ok"]
    assert all(isinstance(r, OpenSimRun) for r in runs)
    with cf.ThreadPoolExecutor(2) as pool:
        again = run_many(osim, t, sets[[0, 2]], ARM26_MUSCLES, executor=pool, progress=False)
    assert np.array_equal(again[0].coordinates, runs[0].coordinates)


def test_run_many_resumes_from_its_runs_folder(arm26, tmp_path):
    """Finished sets are read back, not rerun; new ones are written as they finish; results come
    in the order asked for."""
    osim, _ = arm26
    t = np.arange(51) * 0.002
    sets = np.stack([np.full((len(t), 6), a) for a in (0.1, 0.3, 0.6)])
    first = run_many(osim, t, sets, ARM26_MUSCLES, sets=[2, 0], runs_dir=tmp_path, max_workers=1, progress=False)
    assert sorted(p.name for p in tmp_path.glob("set_*.npz")) == ["set_000.npz", "set_002.npz"]
    marker = OpenSimRun.empty("failed", "written by the test, not by OpenSim", t)
    marker.to_npz(tmp_path / "set_002.npz")  # a rerun would overwrite it
    second = run_many(osim, t, sets, ARM26_MUSCLES, sets=[1, 2, 0], runs_dir=tmp_path, max_workers=1,
                      progress=False)
    assert [r.status for r in second] == ["ok", "failed", "ok"]
    assert second[1].reason == marker.reason
    assert np.array_equal(second[2].coordinates, first[1].coordinates)
    assert (tmp_path / "set_001.npz").exists()


def test_a_force_driven_model_replays_the_muscle_forces_exactly():
    """Fed the forces its muscle applied, the force-driven twin moves as the muscle model did
    (tendon spring, joint damping and the other actuator kept); a 1 % stronger force does not."""
    spec = mujoco.MjSpec.from_string(LIFTER)
    model = spec.compile()
    driven = force_driven(spec, ["lifter"])
    assert driven.na == 0 and model.na == 1 and driven.actuator_ctrllimited[0] == 0
    data = mujoco.MjData(model)
    data.qpos[0] = 0.3
    steps = 300
    ctrl = np.zeros((steps, 2))
    ctrl[:, 0] = 0.5 + 0.5 * np.sin(np.linspace(0, 6, steps))
    ctrl[:, 1] = 0.2
    q, pull = [data.qpos[0]], []
    for k in range(steps):
        data.ctrl[:] = ctrl[k]
        mujoco.mj_step(model, data)
        pull.append(-data.actuator_force[0])
        q.append(data.qpos[0])
    assert max(pull) > 1.0
    forces = np.array(pull + pull[-1:])[:, None]  # (T, 1), sample k = the force during step k
    controls = controls_from_forces(driven, ["lifter"], forces, hold=True)
    controls[:, 1] = ctrl[:, 1]
    init = initial_state(driven, {"swing": 0.3})
    replay = rollout(driven, init, controls, joint_names=["swing"]).coordinates[0, :, 0]
    assert np.max(np.abs(replay - np.array(q))) < 1e-9
    stronger = controls.copy()
    stronger[:, 0] *= 1.01
    moved = rollout(driven, init, stronger, joint_names=["swing"]).coordinates[0, :, 0]
    assert np.max(np.abs(moved - np.array(q))) > 1e-4
    # the mean of neighbouring samples, for forces that change linearly between them
    ramp = controls_from_forces(driven, ["lifter"], np.array([[0.0], [2.0], [4.0]]))
    assert np.allclose(ramp[:, 0], [-1.0, -3.0]) and np.allclose(ramp[:, 1], 0.0)
