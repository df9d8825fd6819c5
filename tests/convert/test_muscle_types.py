"""OpenSim muscle types (o2m.convert.muscle_types): activation laws that are not MuJoCo's mapped to it."""

from __future__ import annotations

import numpy as np

from o2m.convert.muscle_types import _activation_rate, _fitted_time_constants, _schutte_time_constants


def test_schutte_activation_mapping_follows_schutte_better_than_step_matching():
    t_act, t_deact, rms, rms_step = _schutte_time_constants(0.1, 7.667, 1.459854)  # MoBL-ARMS' values
    assert rms < 0.75 * rms_step  # measured 0.024 against 0.037
    # Schutte rises with time constant ts / (a1 u + a2): 11 ms at u = 1, 27 ms at u = 0.3; falls with 68 ms
    assert 0.01 < t_act < 0.03 and 0.05 < t_deact < 0.09


def test_other_activation_laws_fitted_no_worse_than_their_own_time_constants():
    """Thelen2003Muscle_Deprecated (constant time constants) and MeyerFregly2016Muscle (the two
    rates blended by a tanh of steepness 0.1, almost their mean): MuJoCo's time constants fitted
    to follow each law under random excitations beat taking the muscle's own."""
    ta, td, rms, rms_own = _fitted_time_constants("constant", (0.01, 0.04), (0.01, 0.04))
    assert rms <= rms_own  # measured 0.0143 against 0.0150
    ta, td, rms, rms_own = _fitted_time_constants("tanh_blend", (0.015, 0.06, 0.1), (0.015, 0.06))
    assert rms < 0.5 * rms_own  # measured 0.0146 against 0.0492
    # OpenSim's near-even blend rises slower and falls faster than its constants say
    assert ta > 0.015 and td < 0.06


def test_activation_rate_laws():
    u, a = np.array([1.0, 0.0]), np.array([0.5, 0.5])
    np.testing.assert_allclose(_activation_rate("schutte", (0.1, 7.667, 1.459854), u, a),
                               [0.5 * (7.667 + 1.459854) / 0.1, -0.5 * 1.459854 / 0.1])
    np.testing.assert_allclose(_activation_rate("constant", (0.01, 0.04), u, a), [50.0, -12.5])
    # a steep tanh gives MuJoCo's (Thelen's) law: (u - a)/(ta z) rising, (u - a) z/td falling
    z = 0.5 + 1.5 * 0.5
    np.testing.assert_allclose(_activation_rate("tanh_blend", (0.01, 0.04, 1e4), u, a),
                               [0.5 / (0.01 * z), -0.5 * z / 0.04])


def test_thelen_deprecated_force_velocity_is_opensims(tmp_path):
    """Thelen2003Muscle_Deprecated's force-velocity (its calcFiberVelocity inverted): at optimal
    fiber length and full activation, the fiber velocity OpenSim's dynamics give for a tendon
    force F is the velocity at which the mapped curve gives F minus the passive force."""
    import opensim

    from o2m.convert.muscle_samples import _Bench, _muscle_elements
    from o2m.convert.muscle_types import _force_velocity
    from o2m.osim.document import load_document
    from tests.helpers import model_file

    opensim.Logger.setLevelString("error")
    tag = "Thelen2003Muscle_Deprecated"
    text = model_file("opensim-models/Models/Tug_of_War/Tug_of_War.osim").read_text()
    text = text.replace("<optimal_force>1</optimal_force>", "").replace("<Thelen2003Muscle ", f"<{tag} ")
    (tmp_path / "tug.osim").write_text(text.replace("</Thelen2003Muscle>", f"</{tag}>"))
    doc = load_document(tmp_path / "tug.osim")
    bench = _Bench(doc, [_muscle_elements(doc, ["muscle1"])["muscle1"]])
    model, m, s = bench.model, bench.muscles[0], bench.state
    lopt, lts, fmax = m.getOptimalFiberLength(), m.getTendonSlackLength(), m.getMaxIsometricForce()
    u, f = [], []
    for strain in np.linspace(0.01, 0.045, 8):  # tendon forces from 0.04 to 1.6 Fmax
        bench.coords[0].setValue(s, lopt + lts * (1 + strain), False)
        m.setActivation(s, 1.0)
        model.setStateVariableValue(s, "/forceset/muscle1/fiber_length", lopt)
        model.realizeVelocity(s)
        controls = model.updControls(s)
        m.setControls(opensim.Vector(1, 1.0), controls)
        model.setControls(s, controls)
        model.realizeAcceleration(s)
        u.append(model.getStateVariableDerivativeValue(s, "/forceset/muscle1/fiber_length") / (10.0 * lopt))  # Vmax 10
        f.append((m.getTendonForce(s) - m.getPassiveFiberForce(s)) / fmax)
    fv, vmax, _ = _force_velocity(m, tag, np.array(u))
    assert vmax == 10.0 and min(u) < -0.3 and max(u) > 0.1  # shortening and lengthening
    np.testing.assert_allclose(fv, f, atol=1e-3)


def test_degroote_activation_law_is_opensims():
    """DeGrooteFregly2016Muscle's activation derivative in OpenSim is the tanh blend o2m maps
    (:func:`_activation_rate`), at rising and falling excitations."""
    import opensim

    opensim.Logger.setLevelString("error")
    model = opensim.Model()
    body = opensim.Body("b", 1.0, opensim.Vec3(0), opensim.Inertia(0.01))
    model.addBody(body)
    model.addJoint(opensim.SliderJoint("s", model.getGround(), body))
    muscle = opensim.DeGrooteFregly2016Muscle()
    muscle.setName("m")
    muscle.set_activation_time_constant(0.02)
    muscle.set_deactivation_time_constant(0.07)
    muscle.addNewPathPoint("p1", model.getGround(), opensim.Vec3(-0.3, 0, 0))
    muscle.addNewPathPoint("p2", body, opensim.Vec3(0))
    model.addForce(muscle)
    state = model.initSystem()
    b = muscle.get_activation_dynamics_smoothing()
    for u, a in ((0.9, 0.2), (0.3, 0.25), (0.1, 0.6), (0.55, 0.6)):
        model.setStateVariableValue(state, "/forceset/m/activation", a)
        controls = model.updControls(state)
        muscle.setControls(opensim.Vector(1, u), controls)
        model.setControls(state, controls)
        model.realizeAcceleration(state)
        rate = model.getStateVariableDerivativeValue(state, "/forceset/m/activation")
        ours = _activation_rate("tanh_blend", (0.02, 0.07, b), np.array([u]), np.array([a]))[0]
        np.testing.assert_allclose(rate, ours, rtol=1e-9)
