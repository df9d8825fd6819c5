"""The speed benchmark's MuJoCo part on a small pendulum (what it reports, not how fast)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from o2m.paper.speed import BREAKDOWN, format_speed, interleaved_loops, measure_model

PENDULUM = """<mujoco><option timestep="0.002"/><worldbody><body><joint name="q" type="hinge" axis="0 1 0"/>
<geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.02"/></body></worldbody>
<actuator><motor joint="q"/></actuator></mujoco>"""


def test_measure_model_reports_every_run_timer_and_thread_count():
    model = mujoco.MjModel.from_xml_string(PENDULUM)
    data = mujoco.MjData(model)
    state = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    init = np.repeat(state[None], 3, axis=0)
    controls = np.random.default_rng(0).uniform(-1, 1, (3, 50, 1))
    m = measure_model(model, init, controls, repeats=2, batch=4)
    assert m["runs"] == 6 and m["nv"] == 1 and m["equalities"] == 0
    assert m["p10_s"] <= m["median_s"] <= m["p90_s"]
    assert m["c_loop_median_s"] > 0 and m["c_loop_cpu_median_s"] > 0
    assert set(m["step_us"]) == {name.lower() for name in BREAKDOWN}
    assert m["step_us"]["step"] > 0 and "1" in m["rollout_per_s"] and "1" in m["rollout_per_cpu_s"]
    m["ratio"] = 1000.0
    table = format_speed({"opensim_median_s": 1.0, "opensim_s": [1.0], "machine": "test", "mujoco_version": "4",
                          "models": {"converted": m}})
    assert "converted" in table and "1000" in table


def test_interleaved_loops_time_every_set_of_every_model_and_refuse_unequal_sets():
    pendulum = mujoco.MjModel.from_xml_string(PENDULUM)
    heavier = mujoco.MjModel.from_xml_string(PENDULUM.replace('size="0.02"', 'size="0.05"'))
    size = mujoco.mj_stateSize(pendulum, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    init = np.zeros((2, size))  # time 0, at rest, upright
    controls = np.random.default_rng(1).uniform(-1, 1, (2, 20, 1))
    runs = interleaved_loops({"a": (pendulum, init, controls), "b": (heavier, init, controls)}, repeats=3)
    assert set(runs) == {"a", "b"}
    assert all(r.shape == (6, 4) and np.all(r > 0) for r in runs.values())
    m = measure_model(pendulum, init, controls, batch=2, runs=runs["a"])
    assert m["runs"] == 6
    with pytest.raises(ValueError, match="same number of sets"):
        interleaved_loops({"a": (pendulum, init, controls), "b": (heavier, init[:1], controls[:1])}, repeats=1)
