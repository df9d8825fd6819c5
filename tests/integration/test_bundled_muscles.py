"""Muscle paths of the seven bundled models in MuJoCo, measured against OpenSim 4.6.

Asserted: every path force becomes a tendon (muscles also an actuator) of the same name; a path of
fixed points without wrapping has OpenSim's length to 1e-9 m (up to the recorded knee fits); every
model simulates 1 s of random muscle excitation without NaN; and the path targets over 200
random poses (length error <= 1 %, moment-arm RMS per pair median <= 0.5 mm, 95th percentile
<= 2 mm, max <= 5 mm, no MuJoCo length jump in a 1-degree sweep beyond OpenSim's own).

Where a target is not met, the test asserts what the conversion achieves (a bound a little above
the quick-mode measurement) and names the cause in GAPS; the thresholds themselves stay.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from o2m.convert.builder import MjcfBuilder
from o2m.convert.carriers import CARRIER_ARMATURE, CARRIER_SLOPE_GATE
from o2m.osim.document import load_document
from o2m.osim.paths import read_paths
from o2m.osim.skeleton import SkeletonReader, read_skeleton
from o2m.osim.spikes import BAND_FRACTION, DETOUR_FRACTION, FULL_TURN, LOOP_KINDS
from o2m.validate.floors import target_misses
from o2m.validate.jumps import continuous_tendon_front, opensim_length_steps, sweep_jumps, trajectory_jumps
from o2m.validate.muscles import LEN_PCT, MA_MAX_MM, MA_MEDIAN_MM, MA_P95_MM, compare_muscles
from tests.helpers import approximation_budget

NAMES = ["tug_of_war", "arm26", "leg6dof9musc", "gait10dof18musc", "gait2354", "gait2392", "mobl_arms_no_wrap"]

#: Measured gaps (quick mode, seed 0, 200 poses): model -> {"len": {muscle: % achieved}, MA fields}.
#: TRIlong (Arm26): OpenSim's own length steps by -8.05 mm at shoulder elevation 2.524 rad (its
#: wraps switching), so no continuous tendon can be within 1.22 % of it on both sides there
#: (asserted in test_length_gaps_are_opensim_steps; 1.06 % at full elbow flexion, where the path
#: is longest). Its two wraps on one segment (TRIlonghh, TRIlongglen) become a length via point
#: (o2m.lengthvia) whose designed length keeps within 1.31 % (the floor plus 0.1 %) with a moment
#: arm 1.91 mm RMS from computeMomentArm (OpenSim's own -dL/dq is 3.2 mm RMS from it there); the
#: fitted TRIlongglen alone gave 2.70 % and 3.44 mm. MoBL-ARMS against computeMomentArm (p95 3.90, max
#: 14.6 mm): PECM1-3 and LAT1-3 keep their same-body MovingPathPoint segments (path_forces "auto":
#: holding them would change their length by 7.6-16.8 %), so they follow OpenSim's -dL/dq, which is
#: not computeMomentArm there (asserted in test_path_forces_follow_their_choice). No tendon could
#: do both: within 1 % of OpenSim's length, PECM2/PECM3/LAT2/LAT3 are at least 8.4/10.5/12.4/10.5 mm
#: RMS from computeMomentArm about shoulder_elv (swept, the rest at defaults; ma_floor, asserted in
#: test_moment_arm_gaps_are_opensim_inconsistency). (Leg6Dof9Musc and
#: Gait10dof18musc met their targets once their knee extensors' path-point carriers got extra
#: joints: moment-arm p95 3.42 -> 0.50 mm and 3.09 -> 0.51 mm.)
GAPS = {
    "arm26": {"len": {"TRIlong": 1.4}},
    "mobl_arms_no_wrap": {"ma_p95": 4.2, "ma_max": 15.0,
                          "ma_floor": {m: "shoulder_elv" for m in ("PECM2", "PECM3", "LAT2", "LAT3")}},
}
#: The quick wrap fit (its poses drawn apart from these, o2m.convert.wrapfit.FIT_POSE_SEED) has no
#: gaps of its own: Arm26, whose quick fit missed BIClong's moment-arm p95 by a processor-dependent
#: amount, is converted at full size (tests/conftest.py's FULL_SIZE).
#: Measured MuJoCo sweep jumps not met (tendon -> mm): none. (MuJoCo's psoas/iliacus step at hip
#: flexion -90 and +45 degrees is OpenSim's own, 19.5-22.8 mm, at the same place.)
JUMP_GAPS: dict[str, dict[str, float]] = {}


@pytest.fixture(scope="module", params=NAMES)
def converted(request, bundled_conversion):
    fetched, conv = bundled_conversion(request.param)
    return request.param, fetched.osim, conv


def _plain_paths(osim) -> dict[str, set[str]]:
    """Paths with only fixed PathPoints and no wrap objects: name -> the bodies of their points."""
    doc = load_document(osim)
    skel = read_skeleton(doc)
    ref = MjcfBuilder(skel).ref
    return {p.owner: {pt.body for pt in p.points} for p in read_paths(SkeletonReader(doc), ref)
            if not p.wraps and all(not pt.moving and pt.condition is None for pt in p.points)}


def test_every_path_is_a_named_tendon_and_plain_paths_are_exact(converted):
    name, osim, conv = converted
    rep = compare_muscles(osim, conv.xml, n_poses=40, seed=3, ma_poses=0)
    assert not rep.missing_tendons, rep.missing_tendons
    assert not rep.actuator_issues, rep.actuator_issues
    plain = _plain_paths(osim)
    assert plain or name == "mobl_arms_no_wrap"
    budget = approximation_budget(conv.xml, conv.report.approximations)
    for muscle, bodies in plain.items():
        # exact, up to the recorded joint fits above the bodies its points are on (e.g. a knee)
        allowed = 1e-9 + 2 * sum(budget[b][0] for b in bodies if b in budget)
        row = rep.muscles[muscle]
        assert row.max_len <= allowed, f"{name}/{muscle}: {row.max_len * 1e3:.4f} mm > {allowed * 1e3:.4f} mm"


def test_issue_targets_over_200_poses(converted):
    name, osim, conv = converted
    rep = compare_muscles(osim, conv.xml, n_poses=200, seed=0, ma_poses=50)
    gap = GAPS.get(name, {})
    for muscle, e in rep.muscles.items():
        allowed = gap.get("len", {}).get(muscle, LEN_PCT)
        assert e.max_len_pct <= allowed, f"{name}/{muscle}: length error {e.max_len_pct:.3g} % > {allowed} %"
    median, p95, worst = rep.ma_median, rep.ma_p95, rep.ma_max  # against computeMomentArm
    assert median * 1e3 <= MA_MEDIAN_MM, (name, median)
    assert p95 * 1e3 <= gap.get("ma_p95", MA_P95_MM), (name, p95)
    assert worst * 1e3 <= gap.get("ma_max", MA_MAX_MM), (name, worst)
    # fitted tendons: never worse than their start on the fitting poses
    for f in conv.report.path_fits:
        assert f["after"]["objective"] <= f["before"]["objective"]


def test_length_gaps_are_opensim_steps(converted):
    """Every muscle whose length target is given up in GAPS has a step in OpenSim's own length
    that keeps any continuous tendon further than the target from it (so the 1 % cannot be met)."""
    name, osim, conv = converted
    gapped = GAPS.get(name, {}).get("len", {})
    if not gapped:
        pytest.skip("no length gap")
    steps = opensim_length_steps(osim, conv.xml)
    for muscle in gapped:
        floor = max((s["floor_pct"] for s in steps if s["path"] == muscle), default=0.0)
        assert floor > LEN_PCT, (muscle, floor)


def test_moment_arm_gaps_are_opensim_inconsistency(converted):
    """Every (muscle, coordinate) in a model's ``ma_floor`` gap is one where no continuous tendon
    within the 1 % length target of OpenSim can be within the 5 mm moment-arm target of its
    computeMomentArm (OpenSim's dynamic moment arm is not the derivative of its length there)."""
    name, osim, conv = converted
    floors = GAPS.get(name, {}).get("ma_floor", {})
    if not floors:
        pytest.skip("no moment-arm gap from OpenSim's own path")
    for muscle, coordinate in floors.items():
        front = continuous_tendon_front(osim, conv.xml, muscle, coordinate, pcts=(LEN_PCT,), n=301)
        best = front["front"][LEN_PCT]
        assert best is not None and best["rms"] * 1e3 > MA_MAX_MM, (muscle, coordinate, best)


def test_arm26_biclong_moment_arm_steps_where_its_wrap_takes_the_path_on(bundled_conversion):
    """Why Arm26 is converted at full size in quick runs (tests/conftest.py's FULL_SIZE): OpenSim's
    BIClong moment arm about r_shoulder_elev (-dL/dq, the rest at defaults) steps by over 15 mm
    within 0.001 rad near -1.37 rad, where its wrap takes the path on; MuJoCo's sphere takes it on
    smoothly, so no stand-in matches both sides at once, and the quick fit's 40 poses place the
    onset where the processor's floating point takes them."""
    from o2m.osim.pair import ModelPair

    fetched, conv = bundled_conversion("arm26")
    pair = ModelPair(fetched.osim, conv.xml)
    col = [n for n, _, _ in pair.matched].index("BIClong")
    base = pair.os_indep_values(pair.os_state(None))
    qs = np.linspace(-1.40, -1.15, 251)
    length = np.array([pair.os_lengths(pair.os_state({**base, "r_shoulder_elev": q}))[col] for q in qs])
    arm = -np.gradient(length, qs)
    steps = np.abs(np.diff(arm))
    k = int(np.argmax(steps))
    assert arm[: k + 1].max() < -5e-3 and arm[k + 1:].min() > 10e-3, (qs[k], arm[k], arm[k + 1])
    assert -1.40 < qs[k] < -1.34, qs[k]


def test_carrier_slides_meet_the_derivative_gate(converted):
    """Every path-point carrier slide of a non-linear location has a derivative error (a moment-arm
    error along it) within CARRIER_SLOPE_GATE RMS: a plain quartic where it already is (MoBL-ARMS:
    DELT2 1.13 mm/rad, BIC 0.57), else extra joints (the knee extensors of the leg and gait
    models: 2.4-4.1 mm/rad with plain quartics, 0.28-0.48 measured with them), which keep the
    location within 0.06 mm (plain quartics: 0.46-0.85 mm; measured 0.02-0.05 mm)."""
    name, osim, conv = converted
    slides = [a for a in conv.report.approximations if a.element == "MovingPathPoint" and a.slope_rms is not None]
    for a in slides:
        assert a.slope_rms <= CARRIER_SLOPE_GATE, (a.joint, a.slope_rms)
        if "extra joints" in a.what:
            assert a.slope_rms <= 0.6e-3 and a.max_error <= 6e-5, (a.joint, a.slope_rms, a.max_error)


def test_path_forces_follow_their_choice(converted):
    """A path with a same-body MovingPathPoint segment held ("opensim") has OpenSim's
    computeMomentArm, one that keeps it ("kinematic") OpenSim's -dL/dq (to 2.6 mm RMS, the
    other approximations of those paths: measured 0.36 and 2.51 mm on MoBL-ARMS)."""
    name, osim, conv = converted
    if not conv.report.path_forces:
        pytest.skip("no same-body MovingPathPoint segment")
    rep = compare_muscles(osim, conv.xml, n_poses=40, seed=1, ma_poses=20)
    for rec in conv.report.path_forces:
        arms = rep.muscles[rec["path"]].moment_arms
        worst = max(e.rms if rec["mode"] == "opensim" else e.rms_vs_dldq for e in arms.values())
        assert worst * 1e3 <= 2.6, (rec["path"], rec["mode"], worst)
        assert rep.muscles[rec["path"]].max_len_pct <= max(rec["length_error_pct"], 0.0) + 0.5, rec["path"]


def test_no_length_jumps_in_a_one_degree_sweep(converted):
    name, osim, conv = converted
    sw = sweep_jumps(osim, conv.xml)
    paths = {n for n, _ in sw["worst"].items()} & set(compare_muscles(osim, conv.xml, n_poses=1, ma_poses=0).muscles)
    jumps = [j for j in sw["jumps"] if j["tendon"] in paths
             and j["mujoco"] * 1e3 > JUMP_GAPS.get(name, {}).get(j["tendon"], 0.0)]
    assert not jumps, jumps[:3]


def test_simulates_one_second_of_random_excitation(converted):
    """No NaN, and every path-point carrier on a world-welded body follows its coordinate: MuJoCo
    sees its inertia (``dof_invweight0`` at most 1/armature; it took 1e12 from a 1e-12 kg body
    there) and its joint equalities stay within 0.5 mm (MoBL-ARMS's PECM/LAT carriers were left
    behind by up to 51 mm before their mass)."""
    name, osim, conv = converted
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("default-pose").id)
    carriers = [b for b in range(m.nbody) if m.body(b).name.endswith("_carrier")]
    static = {b for b in carriers if m.body_weldid[m.body_parentid[b]] == 0}
    dofs = [m.jnt_dofadr[j] for j in range(m.njnt) if m.jnt_bodyid[j] in carriers]
    assert np.all(m.dof_invweight0[dofs] <= 1.0 / CARRIER_ARMATURE * (1 + 1e-6)), name
    eqs = [e for e in range(m.neq) if m.eq_type[e] == mujoco.mjtEq.mjEQ_JOINT
           and m.jnt_bodyid[m.eq_obj1id[e]] in static]
    rng = np.random.default_rng(0)
    excitation = rng.uniform(0, 1, size=m.nu)
    worst = 0.0
    for _ in range(int(round(1.0 / m.opt.timestep))):
        d.ctrl[:] = excitation
        mujoco.mj_step(m, d)
        rows = np.flatnonzero((d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY) & np.isin(d.efc_id, eqs))
        worst = max(worst, float(np.max(np.abs(d.efc_pos[rows]), initial=0.0)))
    assert np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel)), name
    assert np.all(np.isfinite(d.ten_length))
    assert worst <= 5e-4, (name, worst)


# --------------------------------------------------------------------------------------------
# The wrapped MoBL-ARMS (84 wrap objects): not yet at the targets; its measured floors asserted
# --------------------------------------------------------------------------------------------

#: Measured on the wrapped MoBL-ARMS (quick mode, seed 0, 100 poses, 25 for moment arms, none of
#: them the wrap fit's own: o2m.convert.wrapfit.FIT_POSE_SEED): worst length 20.9 % (DELT3; PECM1
#: 18.8 %), moment arms 0.536 / 10.0 / 14.2 mm, 134 OpenSim samples left out, each with its
#: evidence (checked below): windings of SUP round its cylinder (over a full turn, for pro_sup
#: above about 0.07 rad), loops round TMAJ_LAThum (TMAJ, LAT1-3: OpenSim's quadrant rule takes the
#: path 268-299 degrees round, its runs crossing, which MuJoCo's wrap refuses), lengths not of the
#: path OpenSim draws (CORB: 183.7 mm for 253.6 mm drawn; several wraps on one segment) and spikes
#: or bands (TRIlong's 0.05-rad band among them). Each bound a little above. Until the fit drew its
#: poses apart, 70 of these 100 poses were its own fitting and check poses, and the same
#: conversion measured 15.6 % (PECM1) and 0.331 / 8.70 / 14.1 mm there: an in-sample figure. At
#: full size (120 fitting poses) 18.8 % (PECM1), 0.571 / 8.96 / 19.0 mm. PECM/LAT keep the no-wrap
#: model's same-body floor against computeMomentArm (8.4-12.4 mm RMS about shoulder_elv, asserted
#: there). Before the wrap fit chose among a tendon's variants on its validation poses too
#: (o2m.convert.wrap_choice): 26.4 % (PECM1), 0.600 / 11.3 / 18.5 mm.
WRAPPED_MOBL = {"len_pct": 21.5, "ma_median_mm": 0.56, "ma_p95_mm": 10.3, "ma_max_mm": 14.6, "left_out": 137}
#: The wrapped MoBL-ARMS's missed targets (same report) at a floor OpenSim's own path forces on any
#: tendon, o2m within the target of it (o2m.validate.floors; (path, coordinate) for a moment arm):
#: PECM2-3 and LAT1-2 keep the no-wrap model's same-body segments, where computeMomentArm is not
#: -dL/dq (8.4-14.7 mm RMS about shoulder_elv for any tendon within 1 %). PECM1's and LAT3's are
#: further than the target from their floors (9.85 mm against 3.29, 18.5 against 10.5): o2m's own.
WRAPPED_MOBL_FLOORS = {(m, "shoulder_elv") for m in ("PECM2", "PECM3", "LAT1", "LAT2")}
#: ... and those that are o2m's own, measured the same way (lengths over 1 %; moment-arm pairs
#: over 2 mm RMS, the p95 target): the set may only shrink. SUP's valid lengths (its windings
#: left out) are 4.3 % off at worst. The wrap fit's CMA-ES runs on a processor's own floating
#: point, so the fitted tendons differ a little between processors: PECM2 about shoulder_rot is
#: within 2 mm on an AMD EPYC and 3.77 mm RMS on an Intel Xeon (the model's summary numbers
#: the same on both).
#: Lengths beyond the 1 % target for any continuous tendon: OpenSim's own length steps near their
#: worst poses (quick and full size, seed 0: PECM1 16.2 %, where a finite cylinder's end crosses
#: the path; LAT1 9.9, DELT3 8.9, LAT3 8.6, LAT2 7.6 %; docs/muscle-paths.md). Those floors are
#: found from the worst pose, which the fit's processor moves a little, so the smaller ones (TMAJ
#: 3.3 %) are not asserted.
WRAPPED_MOBL_IMPOSSIBLE = {"PECM1", "LAT1", "LAT2", "LAT3", "DELT3"}
WRAPPED_MOBL_OWN = {(m, None) for m in ("LAT3", "LAT1", "PECM1", "LAT2", "BIClong", "TMIN", "PECM2", "SUP",
                                        "TMAJ", "CORB", "INFSP", "SUBSC", "PECM3", "TRIlong", "DELT3", "DELT1")} | {
    ("TMIN", "elv_angle"), ("TMIN", "shoulder_rot"), ("TMIN", "shoulder_elv"), ("LAT1", "elv_angle"),
    ("LAT1", "shoulder_rot"), ("LAT2", "elv_angle"), ("LAT2", "shoulder_rot"), ("LAT3", "shoulder_rot"),
    ("LAT3", "elv_angle"), ("LAT3", "shoulder_elv"), ("PECM1", "elv_angle"), ("PECM1", "shoulder_rot"),
    ("PECM1", "shoulder_elv"), ("PECM2", "elv_angle"), ("INFSP", "elv_angle"), ("INFSP", "shoulder_rot"),
    ("BIClong", "elv_angle"), ("BIClong", "shoulder_rot"), ("BIClong", "elbow_flexion"), ("TMAJ", "shoulder_elv"),
    ("TMAJ", "elv_angle"), ("TMAJ", "shoulder_rot"), ("CORB", "shoulder_elv"), ("TRIlong", "shoulder_rot"),
    ("TRIlong", "elv_angle"), ("TRIlong", "shoulder_elv"), ("SUBSC", "shoulder_rot"), ("DELT3", "elv_angle"),
    ("DELT3", "shoulder_rot"), ("DELT3", "shoulder_elv"), ("FCU", "elbow_flexion"), ("FDSL", "elbow_flexion"),
    ("TRIlong", "elbow_flexion"), ("CORB", "elv_angle"), ("PECM2", "shoulder_rot")}


@pytest.fixture(scope="module")
def wrapped_mobl(bundled_conversion):
    fetched, conv = bundled_conversion("mobl_arms")
    return fetched.osim, conv


@pytest.fixture(scope="module")
def wrapped_report(wrapped_mobl):
    osim, conv = wrapped_mobl
    return compare_muscles(osim, conv.xml, n_poses=100, seed=0, ma_poses=25)


def test_wrapped_mobl_arms_keeps_its_measured_floors(wrapped_report):
    rep = wrapped_report
    assert not rep.missing_tendons
    assert rep.max_len_pct <= WRAPPED_MOBL["len_pct"], rep.max_len_pct
    assert rep.ma_median * 1e3 <= WRAPPED_MOBL["ma_median_mm"], rep.ma_median
    assert rep.ma_p95 * 1e3 <= WRAPPED_MOBL["ma_p95_mm"], rep.ma_p95
    assert rep.ma_max * 1e3 <= WRAPPED_MOBL["ma_max_mm"], rep.ma_max
    # OpenSim's own failures left out, each with its evidence, and no more than measured (73)
    assert len(rep.opensim_spikes) <= WRAPPED_MOBL["left_out"], len(rep.opensim_spikes)
    for s in rep.opensim_spikes:
        if s.get("test") == "detour":  # OpenSim's path runs past a path point to a wrap and back
            assert s["beyond"] > DETOUR_FRACTION, s
        elif s.get("test") == "loop":  # OpenSim's path loops round a wrap, its runs crossing
            assert s["kind"] in LOOP_KINDS, s
        elif s.get("test") == "winding":  # OpenSim's arc turns over a full turn round a wrap
            assert s["turn"] > FULL_TURN and s["kind"] in LOOP_KINDS, s
        elif s.get("test") == "inconsistent":  # OpenSim's length is not that of the path it draws
            assert abs(s["drawn"] - s["length"]) > BAND_FRACTION * s["length"], s
        else:
            assert max(abs(s["length"] - n) for n in s["neighbours"]) > 1e-3, s


def test_wrapped_mobl_arms_misses_are_opensim_floors_or_known(wrapped_mobl, wrapped_report):
    """Every missed target is at a floor OpenSim's own path sets or among o2m's known misses,
    each of WRAPPED_MOBL_FLOORS that still misses is at its floor, and each length of
    WRAPPED_MOBL_IMPOSSIBLE that misses has a floor beyond the target."""
    osim, conv = wrapped_mobl
    misses = {(m.path, m.coordinate): m for m in target_misses(osim, conv.xml, wrapped_report)}
    unknown = [m.describe() for k, m in misses.items() if not m.at_floor and k not in WRAPPED_MOBL_OWN]
    assert not unknown, unknown
    lost = [m.describe() for k, m in misses.items() if k in WRAPPED_MOBL_FLOORS and not m.at_floor]
    assert not lost, lost
    possible = [m.describe() for k, m in misses.items() if k[0] in WRAPPED_MOBL_IMPOSSIBLE and k[1] is None
                and not m.target_impossible]
    assert not possible, possible


def test_a_step_into_a_winding_is_no_floor(wrapped_mobl):
    """OpenSim's SUP steps by over 20 mm at pro_sup 0.068 rad, where its path starts to wind round
    its cylinder (tests/osim/test_spikes.py). The comparison leaves the windings out, so the step
    binds no tendon: the step finder does not count it as a floor (before, a 19.3 % one)."""
    from o2m.osim.pair import ModelPair

    osim, conv = wrapped_mobl
    pair = ModelPair(osim, conv.xml)
    sup = [n for n, _, _ in pair.matched].index("SUP")
    below, above = (pair.os_lengths(pair.os_state({**pair.defaults, "pro_sup": q}, assemble=False))[sup]
                    for q in (0.06, 0.08))
    assert above - below > 0.02, (below, above)
    assert opensim_length_steps(osim, conv.xml, pair=pair, paths=["SUP"]) == []


def test_wrapped_mobl_arms_sup_lengthrange_leaves_out_opensim_windings(wrapped_mobl):
    """SUP's OpenSim path winds round its cylinder for pro_sup above about 0.07 rad (100-106 mm,
    tests/osim/test_spikes.py); its valid lengths stay under 65 mm. The muscle's lengthrange, over
    which its force curve is fitted, leaves the windings out, and the report says how many."""
    _, conv = wrapped_mobl
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    lo, hi = m.actuator("SUP").lengthrange
    assert 0.045 < lo < hi < 0.07, (lo, hi)
    assert any("SUP" in n and "winding" in n and "left out of the lengthrange" in n
               for n in conv.report.notes), conv.report.notes


def test_wrapped_mobl_arms_force_fits_leave_out_opensim_path_failures(wrapped_mobl):
    """OpenSim's TMAJ loops round its humerus cylinder at some poses (up to 0.38 m against 0.10-0.26
    elsewhere), and its TMIN takes TMINhum the long way round for a moment (0.30 m at 2 of 375
    sampled poses, 0.10-0.14 elsewhere, reached through a 0.16-m step). Their lengthranges leave
    both out, so their force curves are fitted where the muscles work: as well as the no-wrap
    model's (8.4 % and 6.9 % of max isometric force; spread over the failures, 84 % and 63 %)."""
    _, conv = wrapped_mobl
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert m.actuator("TMIN").lengthrange[1] < 0.15, m.actuator("TMIN").lengthrange
    assert m.actuator("TMAJ").lengthrange[1] < 0.27, m.actuator("TMAJ").lengthrange
    fits = {a.name: a.max_error for a in conv.report.approximations if "force-length fitted" in a.what}
    assert fits["TMIN"] < 10.0 and fits["TMAJ"] < 10.0, (fits["TMIN"], fits["TMAJ"])
    notes = " ".join(conv.report.notes)
    assert "length_island" in notes and "loop" in notes, notes


def test_wrapped_mobl_arms_simulates_one_second_of_random_excitation(wrapped_mobl):
    """No NaN in 1 s of random excitation (uniform in [0, 1], seed 0) from the default pose."""
    _, conv = wrapped_mobl
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("default-pose").id)
    d.ctrl[:] = np.random.default_rng(0).uniform(0, 1, size=m.nu)
    for _ in range(int(round(1.0 / m.opt.timestep))):
        mujoco.mj_step(m, d)
    assert np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel)) and np.all(np.isfinite(d.ten_length))


#: Jumps of the wrapped MoBL-ARMS's tendons along its runs of the dataset's 19 test sets (the
#: dataset's excitations and initial states; quick conversion) that OpenSim's path does not share
#: at the same poses. The conversion differs a little between processors (its wrap fit's CMA-ES
#: runs on OpenBLAS kernels chosen per processor), and with it which flip regions the runs cross:
#: measured, none on an AMD EPYC and three of TRIlong (1.23-1.66 mm) on an Intel Xeon (none there
#: either with OPENBLAS_CORETYPE=Haswell, the EPYC's kernels, set for the conversion). Asserted
#: what holds on both: each flip is of a tendon whose wrap fit reported flips between its poses
#: (TRIlong keeps TRIlongglen with TRIlonghh, 5 such flips), and none exceeds ``largest_m``. The
#: wrap fit prefers a variant that does not flip between its poses (o2m.convert.wrap_jumps);
#: choosing on errors at the poses alone, TRIlong kept its TRIlongglen cylinder alone and flipped
#: 17 times (1.6-3.4 mm) here. Jumps where OpenSim's own SUP winds round its cylinder (no
#: reference there) are left out.
WRAPPED_MOBL_FLIPS = {"largest_m": 0.002}


def test_wrapped_mobl_arms_paths_jump_where_opensims_do(wrapped_mobl):
    """Along the dataset's test-set runs, a tendon jumps only where OpenSim's path jumps too, or
    where OpenSim's own path winds or loops round a wrap (left out, with that evidence), or, by at
    most WRAPPED_MOBL_FLIPS's, where the conversion's report says it flips."""
    from o2m.mj.simulate import controls_from_excitations, initial_state, rollout
    from o2m.paper.dataset import load_dataset

    osim, conv = wrapped_mobl
    ds = load_dataset("data/mobl_arms")
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    sets = list(ds.test)
    init = np.array([initial_state(m, dict(zip(ds.coordinate_names, ds.coordinates[i, 0], strict=True)),
                                   speeds=dict(zip(ds.coordinate_names, ds.speeds[i, 0], strict=True)),
                                   activations=dict(zip(ds.muscle_names, ds.opensim_activations[i, 0], strict=True)))
                     for i in sets])
    runs = rollout(m, init, controls_from_excitations(m, list(ds.activations.muscles), ds.activations.values[sets]))
    assert not runs.diverged.any()
    found = trajectory_jumps(osim, conv.xml, runs.qpos)
    reported = {f["tendon"] for f in conv.report.path_fits if f.get("flips")}
    assert {f["tendon"] for f in found["flips"]} <= reported, (found["flips"], reported)
    assert all(f["mujoco"] <= WRAPPED_MOBL_FLIPS["largest_m"] for f in found["flips"]), found["flips"]
    for f in found["at_opensim_failures"]:
        evidence = f["opensim_failure"]
        assert evidence["test"] in ("winding", "loop") and evidence["kind"] in LOOP_KINDS, f
        assert evidence["test"] == "loop" or evidence["turn"] > FULL_TURN, f
