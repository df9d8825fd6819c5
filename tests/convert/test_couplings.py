"""Couplings beyond a quartic: a spline as a sum of MuJoCo joints along one axis.

o2m.convert.couplings.fit_couplings writes each coupled axis as a main quartic plus outer joints
(quartics of inner joints, themselves quartics of the coordinate). Checked here: the fit
recovers polynomials the structure represents (degree 8 and 12) to round-off, never gets
worse with more joints, is exact at the reference and keeps its joints' motions small; a
hand-built .osim with a spline knee converts to a model within the coupling target of
OpenSim 4.6; chained equalities are resolved in order, positions and speeds alike.
"""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from o2m.convert import couplings
from o2m.convert.builder import COUPLING_TARGET
from o2m.convert.couplings import COUPLING_AMPLITUDE, fit_coupling, fit_couplings
from o2m.convert.polyfit import FitError, fit_polynomial
from o2m.mj.posing import joint_equality_plan, pose_mujoco
from o2m.mj.simulate import initial_state, state_layout
from o2m.osim.functions import SimmSpline
from o2m.validate.kinematics import compare_kinematics
from tests.convert.test_joint_types import (
    IDENTITY,
    KNEE_RANGE,
    KNEE_TX,
    KNEE_X,
    OFFSETS,
    ZERO,
    Axis,
    Coord,
    JointSpec,
    build_model,
    typed_joint,
    xy_function,
)
from tests.helpers import convert_options

P = np.polynomial.polynomial
LO, HI, X0 = -2.0, 0.5, 0.0
D = np.array([0.0, 0.4, 1.0, -0.3, 0.2])  # an inner quartic
MAIN = np.array([0.0, 0.01, 0.03, -0.02, 0.01])
#: A knee translation (m) against the knee angle (rad), as in the gait models.
KNEE = SimmSpline(np.array(KNEE_X), np.array(KNEE_TX))


def degree8(x):
    return P.polyval(x, MAIN) + 0.05 * P.polyval(x, D) ** 2


def degree12(x):
    return P.polyval(x, MAIN) + 0.05 * P.polyval(x, D) ** 2 + 0.01 * P.polyval(x, D) ** 3


def knee(x):
    return KNEE(x) - KNEE(0.0)


def scale(fn, lo=LO, hi=HI, x0=X0) -> float:
    x = np.linspace(lo, hi, 10001)
    return float(np.max(np.abs(fn(x) - fn(np.array([x0]))[0])))


@pytest.mark.parametrize("fn", [degree8, degree12], ids=["degree 8", "degree 12"])
def test_recovers_a_polynomial_the_structure_represents(fn):
    """quartic + Q(D(x)), D a quartic, Q a quadratic or cubic: one inner/outer pair, to round-off."""
    s = scale(fn)
    fit = fit_coupling(fn, LO, HI, X0, target=1e-13 * s, max_inner=1)
    assert fit.n_inner == 1
    assert fit.axes[0].quartic_error > 1e-3 * s  # a quartic alone is far off
    assert fit.axes[0].max_error < 1e-13 * s
    x = np.random.default_rng(0).uniform(LO, HI, 5000)
    assert np.max(np.abs(fit.axis_value(0, x) - fn(x))) < 1e-13 * s


def test_error_never_grows_with_more_joints():
    errors = [fit_coupling(knee, *KNEE_RANGE, 0.0, target=0.0, max_inner=k).axes[0].max_error for k in range(4)]
    assert errors[0] == pytest.approx(2.42e-4, rel=0.02)  # the plain quartic (as the gait models' knee)
    assert all(b <= a for a, b in zip(errors, errors[1:], strict=False)), errors
    assert errors[1] < 0.5 * errors[0] and errors[2] < 0.5 * errors[1], errors
    assert errors[2] < COUPLING_TARGET["m"]


def test_exact_at_the_reference_and_extra_joints_vanish_there():
    x0 = -0.3
    fit = fit_coupling(knee, *KNEE_RANGE, x0, target=0.0, max_inner=2)
    assert fit.n_inner == 2
    main, hosted, outers = fit.joint_values(0, np.array([x0]))
    assert main[0] == knee(np.array([x0]))[0]
    assert all(v[0] == 0.0 for v in hosted + outers)
    assert np.all(fit.inners[:, 0] == 0.0) and all(np.all(c[:2] == 0.0) for _, c in fit.axes[0].outers)


def test_extra_joints_move_little():
    """Each outer joint's terms are bounded by COUPLING_AMPLITUDE times the axis's own motion, and
    each inner joint moves no more than the corrections it drives: no large cancelling motions."""
    s = scale(knee, *KNEE_RANGE, 0.0)
    fit = fit_coupling(knee, *KNEE_RANGE, 0.0, target=0.0, max_inner=3)
    assert fit.n_inner >= 2
    assert fit.axes[0].amplitude <= 2 * COUPLING_AMPLITUDE * s, (fit.axes[0].amplitude, s)
    assert fit.condition < 1e8


def test_errors_are_measured_densely():
    """The recorded worst error is the error between the fitting grid's points too."""
    fit = fit_coupling(knee, *KNEE_RANGE, 0.0, target=0.0, max_inner=2)
    x = np.linspace(*KNEE_RANGE, 200001)
    dense = float(np.max(np.abs(fit.axis_value(0, x) - knee(x))))
    assert fit.axes[0].max_error == pytest.approx(dense, rel=0.01)


def test_one_inner_joint_serves_two_axes():
    """Two functions of one coordinate share an inner joint (on axis 0): both improve on their
    quartics; axis 1 has only an outer joint."""
    other = SimmSpline(np.array(KNEE_X), 0.01 * np.cos(2.0 * np.array(KNEE_X)) + 0.002 * np.array(KNEE_X) ** 3)
    fns = [knee, lambda x: other(x) - other(0.0)]
    fit = fit_couplings(fns, *KNEE_RANGE, 0.0, targets=[1e-6, 1e-6], uses=[[0], [0]], hosts=[0])
    assert fit.extra_joints(0) == 2 and fit.extra_joints(1) == 1
    for ax in fit.axes:
        assert ax.max_error < 0.5 * ax.quartic_error, ax


def test_margin_keeps_the_fit_just_beyond_the_range():
    lo, hi = KNEE_RANGE
    x = np.linspace(hi, hi + 0.02 * (hi - lo), 200)
    plain = fit_coupling(knee, lo, hi, 0.0, target=0.0, max_inner=2)
    wide = fit_coupling(knee, lo, hi, 0.0, target=0.0, max_inner=2, margin=0.02)
    beyond = [float(np.max(np.abs(f.axis_value(0, x) - knee(x)))) for f in (plain, wide)]
    assert beyond[1] <= wide.axes[0].margin_error * 1.01
    assert beyond[1] < 0.5 * beyond[0], beyond
    assert wide.axes[0].margin_error <= couplings.COUPLING_MARGIN_SLACK * wide.axes[0].max_error * 1.01


def test_guard_caps_the_chained_fit_beyond_the_range():
    """A knee translation (the gait models' spline, m against rad) as one inner/outer pair: fitted
    on its range alone it leaves the spline like a degree-16 polynomial a quarter of the range
    beyond it; with a guard its error there stays within the stated cap (0.1 x the travel x
    (distance / range)² + the plain quartic's error + COUPLING_MARGIN_SLACK x the error inside),
    finite, and inside the range still better than the plain quartic."""
    lo, hi = KNEE_RANGE
    width = hi - lo
    kw = dict(targets=[1e-6], uses=[[0]], hosts=[0], margin=0.02)
    plain = fit_couplings([knee], lo, hi, 0.0, **kw)
    guarded = fit_couplings([knee], lo, hi, 0.0, guard=0.25, **kw)
    assert guarded.guard == pytest.approx(0.25 * width)
    d = np.linspace(0.02, 0.25, 2001) * width  # beyond the margins, out to the guard
    x = np.concatenate([lo - d, hi + d])
    x_in = np.linspace(lo, hi, 2001)
    travel = float(np.ptp(knee(x_in)))
    ax = guarded.axes[0]
    cap = (couplings.COUPLING_GUARD_TRAVEL * travel * (np.concatenate([d, d]) / width) ** 2
           + ax.quartic_error + couplings.COUPLING_MARGIN_SLACK * ax.max_error)
    err = {name: np.abs(f.axis_value(0, x) - knee(x)) for name, f in (("plain", plain), ("guarded", guarded))}
    assert np.all(np.isfinite(err["guarded"]))
    assert np.all(err["guarded"] <= 1.01 * cap), float(np.max(err["guarded"] / cap))
    assert float(np.max(err["guarded"])) <= 1.01 * ax.guard_error
    assert np.any(err["plain"] > 10 * cap)  # the test has bite: the range's fit alone leaves the cap
    assert ax.max_error < ax.quartic_error


def test_fits_are_reproducible():
    """The same input gives the same coefficients, bit for bit (the search has many local minima;
    scipy's MINPACK differs in the last bit from run to run, which would change the fit)."""
    runs = []
    for _ in range(2):
        fit = fit_coupling(knee, *KNEE_RANGE, 0.0, target=0.0, max_inner=2)
        runs.append((fit.inners.tobytes(), fit.axes[0].main.tobytes(), fit.shapes.tobytes()))
    assert runs[0] == runs[1]


def test_cache_is_the_callers():
    """Fits are kept only in the cache a caller passes (no module state): a repeat with it returns
    the fit made first, a repeat without it makes the same fit again."""
    cache = {}
    first = fit_coupling(knee, *KNEE_RANGE, 0.0, target=0.0, max_inner=1, cache=cache)
    assert any(f is first for f in cache.values())
    assert fit_coupling(knee, *KNEE_RANGE, 0.0, target=0.0, max_inner=1, cache=cache) is first
    again = fit_coupling(knee, *KNEE_RANGE, 0.0, target=0.0, max_inner=1)
    assert again is not first and again.inners.tobytes() == first.inners.tobytes()
    assert again.axes[0].main.tobytes() == first.axes[0].main.tobytes()


def test_slope_is_the_derivative_of_the_sum_of_joints():
    """CouplingFit.axis_slope (the chain rule through the outer joints) is d axis_value / dx, and
    the reported derivative errors are the ones measured against the function's derivative."""
    fit = fit_coupling(knee, *KNEE_RANGE, 0.0, target=0.0, max_inner=2)
    x = np.linspace(*KNEE_RANGE, 20001)
    h = 1e-6
    numeric = (fit.axis_value(0, x + h) - fit.axis_value(0, x - h)) / (2 * h)
    np.testing.assert_allclose(fit.axis_slope(0, x), numeric, atol=1e-8)
    err = fit.axis_slope(0, x) - KNEE.derivative(x)
    assert fit.axes[0].slope_error == pytest.approx(float(np.max(np.abs(err))), rel=0.02)
    assert fit.axes[0].slope_rms == pytest.approx(float(np.sqrt(np.mean(err ** 2))), rel=0.02)
    quartic = fit_polynomial(knee, *KNEE_RANGE, 0.0, degree=4, exact_at_x0=True)
    q_max, q_rms = couplings.polynomial_slope_errors(knee, quartic.coef, *KNEE_RANGE, 0.0)
    assert fit.axes[0].quartic_slope_error == pytest.approx(q_max, rel=0.02)
    assert fit.axes[0].quartic_slope_rms == pytest.approx(q_rms, rel=0.02)
    assert q_max == pytest.approx(3.75e-3, rel=0.02)  # m/rad: the gait knee translation's plain quartic


def test_slope_targets_bound_the_derivative():
    """With a slope target the linear programs bound the derivative's error with the value's: on
    the gait knee translation (two inner/outer pairs) the worst derivative error falls from
    1.5 to 0.41 mm/rad for a value error of 0.0066 -> 0.0092 mm (measured); the value-only fit
    reports its own derivative error, and a slope target met stops fit_coupling early."""
    plain = fit_coupling(knee, *KNEE_RANGE, 0.0, target=1e-5, max_inner=2)
    aware = fit_couplings([knee], *KNEE_RANGE, 0.0, targets=[1e-5], uses=[[0, 1]], hosts=[0, 0],
                          slope_targets=[5e-4])
    assert plain.n_inner == 2 and np.isinf(plain.axes[0].slope_target)
    a, p = aware.axes[0], plain.axes[0]
    assert a.slope_target == 5e-4
    assert a.slope_error < 0.5 * p.slope_error, (a.slope_error, p.slope_error)
    assert a.slope_error <= 5e-4 and a.max_error <= 1e-5, (a.slope_error, a.max_error)
    assert a.max_error < 2 * p.max_error
    loose = fit_coupling(knee, *KNEE_RANGE, 0.0, target=1.0, max_inner=2, slope_target=1.0)
    assert loose.n_inner == 0  # the plain quartic meets both
    with pytest.raises(ValueError):
        fit_couplings([knee], *KNEE_RANGE, 0.0, targets=[1e-5], uses=[[]], hosts=[], slope_targets=[1e-3, 1e-3])


def test_rejects_bad_arguments():
    with pytest.raises(ValueError):
        fit_couplings([knee], 1.0, 1.0, 1.0, targets=[1e-5], uses=[[]], hosts=[])
    with pytest.raises(ValueError):
        fit_couplings([knee], -1.0, 1.0, 2.0, targets=[1e-5], uses=[[]], hosts=[])
    with pytest.raises(ValueError):
        fit_couplings([knee], -1.0, 1.0, 0.0, targets=[1e-5], uses=[[1]], hosts=[0])
    with pytest.raises(ValueError):
        fit_couplings([knee], -1.0, 1.0, 0.0, targets=[1e-5], uses=[[0]], hosts=[1])


# ---------------------------------------------------------------------------------------------
# A hand-built model
# ---------------------------------------------------------------------------------------------


def knee_model(tmp_path, which: str) -> str:
    """hip pin, a knee (identity rotation about z plus one spline axis: a translation, or a
    rotation about x) and an ankle pin."""
    spline = xy_function("SimmSpline", KNEE_X, KNEE_TX if which == "translation" else 5 * np.array(KNEE_TX))
    axes = [Axis("rotation1", (0.0, 0.0, 1.0), "knee", IDENTITY),
            Axis("rotation2", (1.0, 0.0, 0.0), "knee" if which == "rotation" else None,
                 spline if which == "rotation" else ZERO),
            Axis("rotation3", (0.0, 1.0, 0.0), None, ZERO),
            Axis("translation1", (1.0, 0.0, 0.0), "knee" if which == "translation" else None,
                 spline if which == "translation" else ZERO),
            Axis("translation2", (0.0, 1.0, 0.0), None, ZERO),
            Axis("translation3", (0.0, 0.0, 1.0), None, ZERO)]
    joints = [typed_joint("PinJoint", "hip", "ground", "b1", OFFSETS[0]),
              JointSpec("knee", "CustomJoint", "b1", "b2", OFFSETS[1], [Coord("knee", KNEE_RANGE)], axes),
              typed_joint("PinJoint", "ankle", "b2", "b3", OFFSETS[2])]
    return build_model(tmp_path / f"knee_{which}.osim", joints)


@pytest.mark.parametrize("which", ["translation", "rotation"])
def test_hand_built_spline_knee_matches_opensim_within_the_target(which, tmp_path):
    """The spline axis (on a body with room for two inner/outer pairs) becomes its main joint and
    four extra joints; every body is then within COUPLING_TARGET of OpenSim (the rotation's
    error times the lever arm for positions, below 0.1 mm), where the plain quartic is not."""
    from o2m.convert.converter import convert

    osim = knee_model(tmp_path, which)
    conv = convert(osim, tmp_path / "out", convert_options())
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    axis = f"knee_{which}{'1' if which == 'translation' else '2'}"
    names = {m.joint(i).name for i in range(m.njnt)}
    assert {f"{axis}_inner1", f"{axis}_outer1", f"{axis}_inner2", f"{axis}_outer2"} <= names
    (approx,) = [a for a in conv.report.approximations if a.joint == axis]
    unit = "m" if which == "translation" else "rad"
    assert approx.units == unit and approx.max_error <= COUPLING_TARGET[unit]
    plain = float(approx.detail.split("a plain quartic: ")[1].split()[0])
    assert plain > 10 * COUPLING_TARGET[unit]  # the test has bite: a quartic misses the target
    rep = compare_kinematics(osim, conv.xml, n_poses=200, seed=0)
    assert rep.skipped_poses == 0 and not rep.missing_bodies and not rep.extra_bodies
    if which == "translation":
        assert rep.max_pos_error <= COUPLING_TARGET["m"], rep.summary()
        assert rep.max_ang_error < 1e-9, rep.summary()
    else:
        assert rep.max_ang_error <= COUPLING_TARGET["rad"], rep.summary()
        assert rep.max_pos_error <= 1e-4, rep.summary()
    exact = compare_kinematics(osim, conv.xml, n_poses=50, seed=1, dependents="opensim")
    assert exact.max_pos_error < 1e-9 and exact.max_ang_error < 1e-9, exact.summary()


def test_chained_equalities_resolve_positions_and_speeds(tmp_path):
    """joint_equality_plan puts each outer joint after the inner joint that drives it (also when
    the equalities come in the opposite order), pose_mujoco then resolves the chain, and
    initial_state's chain-rule speeds match finite differences."""
    from o2m.convert.converter import convert

    conv = convert(knee_model(tmp_path, "translation"), tmp_path / "out", convert_options())
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    plan = joint_equality_plan(m)
    at = {e.joint1: i for i, e in enumerate(plan)}
    outers = [e for e in plan if "_outer" in e.joint1]
    assert outers and all(at[e.joint2] < at[e.joint1] for e in outers)
    # the same model with its equalities in reverse order
    spec = mujoco.MjSpec.from_file(str(conv.xml))
    eqs = [(e.name, e.name1, e.name2, np.array(e.data)) for e in spec.equalities]
    for e in list(spec.equalities):
        spec.delete(e)
    for name, j1, j2, data in reversed(eqs):
        spec.add_equality(name=name, type=mujoco.mjtEq.mjEQ_JOINT, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                          name1=j1, name2=j2, data=data)
    rev = spec.compile()
    d1, d2 = mujoco.MjData(m), mujoco.MjData(rev)
    for q in (-1.7, -0.4, 0.1):
        pose_mujoco(m, d1, {"knee": q, "hip_r0": 0.2})
        pose_mujoco(rev, d2, {"knee": q, "hip_r0": 0.2})
        np.testing.assert_array_equal(d1.xpos, d2.xpos)
    # speeds
    q, w, h = -0.8, 1.3, 1e-6
    state = initial_state(m, {"knee": q, "hip_r0": 0.1}, speeds={"knee": w})
    qvel = state[state_layout(m)["qvel"]]

    def values(qk: float) -> np.ndarray:
        d = mujoco.MjData(m)
        pose_mujoco(m, d, {"knee": qk, "hip_r0": 0.1})
        return d.qpos.copy()

    fd = (values(q + h) - values(q - h)) / (2 * h) * w
    for i in range(m.njnt):
        name = m.joint(i).name
        if name.startswith("knee_translation1"):
            assert qvel[m.jnt_dofadr[i]] == pytest.approx(fd[m.jnt_qposadr[i]], rel=1e-6, abs=1e-12), name


def test_fit_couplings_refuses_a_fit_that_is_not_finite():
    """A function with one huge value gives FitError, never joint equalities of NaN or inf; so does
    a fit whose coefficients are not finite."""
    huge = SimmSpline(np.array([-2.0, -1.0, 0.0, 0.5]), np.array([0.001, 1e300, -0.002, -0.005]))
    with pytest.raises(FitError, match="not finite"):
        fit_couplings([huge], -2.0, 0.5, 0.0, targets=[1e-4], uses=[[0]], hosts=[0])
    spline = SimmSpline(np.array([-2.0, -1.0, 0.0, 0.5]), np.array([0.001, 0.004, -0.002, -0.005]))
    fit = fit_couplings([spline], -2.0, 0.5, 0.0, targets=[1e-4], uses=[[0]], hosts=[0])
    couplings._check_finite(fit)
    with pytest.raises(FitError, match="not finite"):
        couplings._check_finite(replace(fit, inners=fit.inners * np.nan))


#: A knee whose tibia and patella follow the knee angle through five coupler splines (x: knee
#: angle, rad; y: m or rad), as in Leg39, the Jumper and the soccer kick: tibia translations
#: (tx, ty), patella translations (tx, ty) and patella rotation.
COUPLER_KNEE_X = {
    "tib_tx": [-2.0944, -1.74533, -1.39626, -1.0472, -0.698132, -0.349066, -0.174533, 0.197344, 0.337395, 0.490178,
               1.52146, 2.0944],
    "tib_ty": [-2.0944, -1.22173, -0.523599, -0.349066, -0.174533, 0.159149, 2.0944],
    "pat_tx": [-2.0944, -1.39626, -1.0472, -0.698132, -0.349066, -0.174533, 0, 0.00017453, 0.00034907, 0.0872665,
               2.0944],
    "pat_ty": [-2.0944, -1.5708, -1.39626, -1.0472, -0.698132, -0.349066, -0.174533, 0, 0.00017453, 0.00034907,
               0.0872665, 2.0944],
    "pat_angle": [-2.0944, -1.99997, -1.45752, -0.526391, 0.0279253, 0.174533],
}
COUPLER_KNEE_Y = {
    "tib_tx": [-0.0037561, 0.00210107, 0.00482424, 0.00481249, 0.00248841, -0.00117378, -0.00363871, -0.00613534,
               -0.00637949, -0.00654265, -0.00637949, -0.00616234],
    "tib_ty": [-0.496039, -0.479137, -0.468338, -0.466695, -0.465521, -0.463953, -0.464817],
    "pat_tx": [0.0194405, 0.0364088, 0.042814, 0.0483203, 0.0527029, 0.0543884, 0.0557369, 0.0557369, 0.0557369,
               0.0557369, 0.0557369],
    "pat_ty": [-0.0246096, -0.0226993, -0.0224746, -0.0229241, -0.0237107, -0.0246096, -0.0250591, -0.0255086,
               -0.0255086, -0.0255086, -0.0255086, -0.0255086],
    "pat_angle": [0.308051, 0.308051, 0.306305, 0.270177, -0.037001, -0.279951],
}


@pytest.mark.parametrize("x0", [
    pytest.param(0.0, id="reference 0 (Leg39)"),
    pytest.param(-1.91986209, id="reference -110 deg (soccer kick)")])
def test_five_coupled_axes_of_two_bodies_reach_the_skeleton_budget(x0):
    """Five coupler splines of one knee on two bodies (each a hinge and two slides) fill both bodies
    with one shared inner joint; planned with their translations on bodies of their own, an axis
    given up while no inner joint served it (the tibia's tx) takes one added later, the split
    plan is kept, and the patella (its error adds the tibia's) is within the skeleton's
    0.1 mm / 0.05 deg, whichever knee angle is the reference pose (where the fits are exact)."""
    from o2m.convert.coupling_plan import CoupledAxis, plan_skeleton

    lo, hi = -2.0943951, 0.17453293
    body = {"tib_tx": "tibia", "tib_ty": "tibia", "pat_tx": "patella", "pat_ty": "patella", "pat_angle": "patella"}
    mass = {"tibia": 6.15, "patella": 0.0919}  # each body's main joints' own inertia (kg, kg m² for the hinge)
    axes = []
    for name in COUPLER_KNEE_X:
        spline = SimmSpline(np.array(COUPLER_KNEE_X[name]), np.array(COUPLER_KNEE_Y[name]))
        axes.append(CoupledAxis(name, body[name], "hinge" if name == "pat_angle" else "slide", "knee",
                                lambda x, s=spline: s(x) - s(x0)))
    weights = {a.name: mass[a.body] * (0.012 if a.kind == "hinge" else 1.0) for a in axes}
    dofs = {("tibia", "slide"): 2, ("tibia", "hinge"): 1, ("patella", "slide"): 2, ("patella", "hinge"): 1}
    planned, split = plan_skeleton(axes, dofs, weights, {"knee": (lo, hi)}, {"knee": x0}, targets=COUPLING_TARGET,
                                   slope_targets={"m": None, "rad": None})
    assert set(split) == {"tibia", "patella"}
    fit = planned["tib_tx"].fit
    err = {a.name: fit.axes[i].max_error for i, a in enumerate(axes)}
    assert len(fit.axes[0].outers) >= 2, fit.structure(0)
    assert err["tib_tx"] + max(err["pat_tx"], err["pat_ty"]) < 1e-4, err
    assert err["pat_angle"] < np.deg2rad(0.05), err


def test_carrier_groups_are_planned_in_chunks_that_keep_a_body_together():
    from o2m.convert.coupling_plan import CARRIER_CHUNK, CARRIER_SPLIT_CHUNK, chunks_by_key

    assert chunks_by_key(["a", "b", "a"], size=8) == [[0, 1, 2]]  # small groups: one chunk, as before
    assert chunks_by_key(list(range(CARRIER_CHUNK))) == [list(range(CARRIER_CHUNK))]
    keys = [k // 2 for k in range(2 * CARRIER_CHUNK + 3)]  # two axes per carrier body
    chunks = chunks_by_key(keys)
    assert sorted(i for c in chunks for i in c) == list(range(len(keys)))
    assert all(len(c) <= CARRIER_SPLIT_CHUNK for c in chunks)
    assert len(chunks) == -(-(len(keys) + 1) // CARRIER_SPLIT_CHUNK)  # full chunks of whole bodies
    assert all(len({keys[i] for i in c} & {keys[i] for i in d}) == 0 for c in chunks for d in chunks if c is not d)


def _missing_fit(fns, lo, hi, x0, *, targets, uses, hosts, **_):
    """A stand-in for fit_couplings: every axis misses its target by 2 whatever its joints (so
    plan_group tries every move), the joints as asked."""
    from o2m.convert.couplings import AxisFit, CouplingFit

    axes = tuple(AxisFit(np.zeros(5), tuple((k, np.zeros(5)) for k in u), 2.0 * tg, tg, 2.0 * tg, tg, 0.0)
                 for u, tg in zip(uses, targets, strict=True))
    return CouplingFit(np.zeros((len(hosts), 5)), tuple(hosts), np.zeros((len(hosts), 4)), axes, 1.0, lo, hi, x0)


def _axis_fits_per_axis(monkeypatch, carriers: int) -> tuple[float, int]:
    """Plan ``carriers`` two-slide carriers of one coordinate as the builder does (chunks_by_key,
    then plan_group per chunk, fit_couplings replaced by :func:`_missing_fit`): the axes fitted
    per axis (a fit's work grows with its axes), and the most axes of one fit."""
    from o2m.convert import coupling_plan
    from o2m.convert.coupling_plan import CoupledAxis, chunks_by_key, plan_group

    fitted_axes: list[int] = []
    monkeypatch.setattr(coupling_plan, "fit_couplings",
                        lambda fns, *a, **k: fitted_axes.append(len(fns)) or _missing_fit(fns, *a, **k))
    group = [CoupledAxis(f"c{k // 2}_{'xy'[k % 2]}", f"c{k // 2}", "slide", "knee", np.sin)
             for k in range(2 * carriers)]
    keys = [a.body for a in group]
    for chunk in chunks_by_key(keys):
        plan_group([group[i] for i in chunk], [keys[i] for i in chunk], {key: 4 for key in keys}, -1.0, 1.0, 0.0,
                   [1.0] * len(chunk), [1e-5] * len(chunk), cheaper_too=True)
    return sum(fitted_axes) / len(group), max(fitted_axes)


def test_carrier_fitting_work_per_axis_does_not_grow_with_the_group(monkeypatch):
    """However many carriers share a coordinate, each carrier axis costs the same number of fitted
    axes: the chunks stay small (each axis that misses tries up to two moves, each a fit of its
    whole chunk), so conversion time grows linearly with the number of paths."""
    from o2m.convert.coupling_plan import CARRIER_SPLIT_CHUNK

    work = {n: _axis_fits_per_axis(monkeypatch, n) for n in (8, 32, 128)}
    assert all(largest <= CARRIER_SPLIT_CHUNK for _, largest in work.values()), work
    assert work[8][0] == work[32][0] == work[128][0], work
    assert work[128][0] <= 2 + 2 * CARRIER_SPLIT_CHUNK, work  # the quartics, the first inner, two tries per axis
