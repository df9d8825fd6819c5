"""The speed benchmark's MuJoCo part on a small pendulum (what it reports, not how fast)."""

from __future__ import annotations

import mujoco
import numpy as np

from o2m.paper.speed import BREAKDOWN, format_speed, measure_model

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
    assert set(m["step_us"]) == {name.lower() for name in BREAKDOWN}
    assert m["step_us"]["step"] > 0 and "1" in m["rollout_per_s"] and "1" in m["rollout_per_cpu_s"]
    m["ratio"] = 1000.0
    table = format_speed({"opensim_median_s": 1.0, "opensim_s": [1.0], "machine": "test", "mujoco_version": "4",
                          "models": {"converted": m}})
    assert "converted" in table and "1000" in table
