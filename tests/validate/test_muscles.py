"""Tests of o2m.validate_muscles against a small OpenSim arm and MuJoCo twins written by hand.

The OpenSim model (built with the API): ground -> humerus (PinJoint q_sh) -> radius (PinJoint
q_el) -> hand (PinJoint q_wr, a dependent coordinate: q_wr = 0.1 + 0.5 q_el - 0.2 q_el^2 through
a CoordinateCouplerConstraint). Paths without wrapping: a Thelen2003Muscle "bic" (ground ->
humerus -> radius, elbow flexor), a Thelen2003Muscle "tri" (humerus -> radius behind the elbow,
extensor) and a PathActuator "wflex" (radius -> hand, moved by q_el only through the coupling).

The MuJoCo twin is derived here, independently of the converter: an OpenSim joint with parent
offset frame (lp, op) in the parent body and child offset frame (lc, oc) in the child body puts
the child body, at q = 0, at rotation R(op) R(oc)^T and position lp - R(op) R(oc)^T lc in the
parent; the PinJoint is a hinge at lc about R(oc) e_z. Ground-fixed things are mapped by the
Y-up to Z-up rotation (x, y, z) -> (x, -z, y). Path points are sites at the same body-frame
locations, each path a spatial tendon through them, each muscle a <muscle> actuator (the
PathActuator a <general> one) on its tendon; the coupling is a joint equality.
"""

from __future__ import annotations

import json
import math

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m.mj.tendons import mujoco_moment_arms, mujoco_tendon_lengths
from o2m.validate.jumps import opensim_length_steps, sweep_jumps, trajectory_jumps
from o2m.validate.muscles import MuscleReport, compare_muscles, format_muscle_table
from o2m.validate.sweeps import moment_arm_curve, plot_moment_arms
from tests.helpers import add_coupler

osim.Logger.setLevelString("error")

#: OpenSim ground (Y up) -> MuJoCo world (Z up), written out by hand.
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def _rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _xyz(angles):
    return _rx(angles[0]) @ _ry(angles[1]) @ _rz(angles[2])


def _v(x) -> str:
    return " ".join(repr(float(c)) for c in np.ravel(x))


# Bodies: name -> (mass, COM, principal inertia).
BODIES = {
    "humerus": (2.0, (0.0, -0.15, 0.0), (0.02, 0.005, 0.02)),
    "radius": (1.0, (0.0, -0.12, 0.0), (0.01, 0.002, 0.01)),
    "hand": (0.4, (0.0, -0.05, 0.0), (0.002, 0.001, 0.002)),
}
# Pin joints: (name, parent, child, lp, op, lc, oc, coordinate, range).
JOINTS = [
    ("shoulder", "ground", "humerus", (0.05, 1.0, -0.02), (0.3, -0.2, 0.4), (0.0, 0.02, 0.0), (0.0, 0.0, 0.1),
     "q_sh", (-1.0, 1.2)),
    ("elbow", "humerus", "radius", (0.0, -0.3, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0),
     "q_el", (0.0, 2.5)),
    ("wrist", "radius", "hand", (0.0, -0.25, 0.0), (0.0, 0.1, 0.0), (0.0, 0.01, 0.0), (0.0, 0.0, 0.0),
     "q_wr", (-1.0, 1.0)),
]
#: q_wr = C0 + C1 q_el + C2 q_el^2.
COUPLING = (0.1, 0.5, -0.2)
# Paths: name -> (OpenSim class, [(point, body, location)]).
PATHS = {
    "bic": ("Thelen2003Muscle", [("bic-o", "ground", (0.07, 1.02, -0.01)), ("bic-v", "humerus", (0.03, -0.15, 0.0)),
                                 ("bic-i", "radius", (0.02, -0.05, 0.0))]),
    "tri": ("Thelen2003Muscle", [("tri-o", "humerus", (-0.03, -0.1, 0.0)), ("tri-i", "radius", (-0.025, 0.02, 0.0))]),
    "wflex": ("PathActuator", [("wflex-o", "radius", (0.01, -0.2, 0.0)), ("wflex-i", "hand", (0.015, -0.05, 0.005))]),
}


def build_osim(path) -> str:
    model = osim.Model()
    model.setName("arm")
    bodies = {"ground": model.getGround()}
    for name, (mass, com, inertia) in BODIES.items():
        b = osim.Body(name, mass, osim.Vec3(*com), osim.Inertia(*inertia))
        model.addBody(b)
        bodies[name] = b
    for name, parent, child, lp, op, lc, oc, coord, rng in JOINTS:
        j = osim.PinJoint(name, bodies[parent], osim.Vec3(*lp), osim.Vec3(*op), bodies[child], osim.Vec3(*lc),
                          osim.Vec3(*oc))
        c = j.updCoordinate()
        c.setName(coord)
        c.setRangeMin(rng[0])
        c.setRangeMax(rng[1])
        model.addJoint(j)
    coef = osim.Vector(3, 0.0)
    for k, c in enumerate(reversed(COUPLING)):  # PolynomialFunction: highest order first
        coef.set(k, c)
    add_coupler(model, "wrist_coupling", "q_el", "q_wr", osim.PolynomialFunction(coef))
    for name, (kind, points) in PATHS.items():
        if kind == "Thelen2003Muscle":
            f = osim.Thelen2003Muscle(name, 300.0, 0.1, 0.2, 0.0)
        else:
            f = osim.PathActuator()
            f.setName(name)
            f.setOptimalForce(50.0)
        for pname, body, loc in points:
            f.addNewPathPoint(pname, bodies[body], osim.Vec3(*loc))
        model.addForce(f)
    model.finalizeConnections()
    out = str(path / "arm.osim")
    model.printToXML(out)
    return out


def twin_xml(move: tuple[str, tuple[float, float, float]] | None = None, wrap: bool = False,
             drop: str | None = None) -> str:
    """The hand-written MuJoCo twin. ``move`` = (site, offset in its body frame, m) displaces a
    site; ``wrap`` puts a wrap sphere with a side site on the far side into bic's path (the path
    flips around it); ``drop`` leaves out a path's tendon and actuator."""
    sites: dict[str, list[str]] = {b: [] for b in ["ground", *BODIES]}
    for _, points in PATHS.values():
        for pname, body, loc in points:
            loc = np.array(loc, dtype=float)
            if move is not None and move[0] == pname:
                loc = loc + np.array(move[1])
            pos = Y_UP_TO_Z_UP @ loc if body == "ground" else loc
            sites[body].append(f'<site name="{pname}" pos="{_v(pos)}"/>')
    if wrap:
        sites["humerus"].append('<geom name="bic_wrap" type="sphere" size="0.015" pos="0.045 -0.25 0" '
                                'contype="0" conaffinity="0" mass="0"/>')
        sites["humerus"].append('<site name="bic_side" pos="0.075 -0.25 0"/>')

    def body_xml(name: str, indent: str) -> str:
        out = []
        for _, parent, child, lp, op, lc, oc, coord, rng in JOINTS:
            if parent != name:
                continue
            rot = _xyz(op) @ _xyz(oc).T
            pos = np.array(lp) - rot @ np.array(lc)
            if parent == "ground":
                rot, pos = Y_UP_TO_Z_UP @ rot, Y_UP_TO_Z_UP @ pos
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, rot.reshape(9))
            mass, com, inertia = BODIES[child]
            out.append(f'{indent}<body name="{child}" pos="{_v(pos)}" quat="{_v(quat)}">')
            out.append(f'{indent}  <joint name="{coord}" type="hinge" pos="{_v(lc)}" axis="{_v(_xyz(oc)[:, 2])}" '
                       f'range="{rng[0]} {rng[1]}" limited="true"/>')
            out.append(f'{indent}  <inertial pos="{_v(com)}" mass="{mass}" diaginertia="{_v(inertia)}"/>')
            out.extend(f"{indent}  {s}" for s in sites[child])
            out.append(body_xml(child, indent + "  "))
            out.append(f"{indent}</body>")
        return "\n".join(x for x in out if x)

    tendons, actuators = [], []
    for name, (kind, points) in PATHS.items():
        if name == drop:
            continue
        refs = [f'<site site="{p}"/>' for p, _, _ in points]
        if wrap and name == "bic":
            refs.insert(2, '<geom geom="bic_wrap" sidesite="bic_side"/>')
        tendons.append(f'<spatial name="{name}">{"".join(refs)}</spatial>')
        if kind == "PathActuator":
            actuators.append(f'<general name="{name}" tendon="{name}" gainprm="50"/>')
        else:
            actuators.append(f'<muscle name="{name}" tendon="{name}"/>')
    c0, c1, c2 = COUPLING
    return f"""<mujoco model="arm">
  <worldbody>
    {" ".join(sites["ground"])}
{body_xml("ground", "    ")}
  </worldbody>
  <equality><joint joint1="q_wr" joint2="q_el" polycoef="{c0} {c1} {c2} 0 0"/></equality>
  <tendon>{"".join(tendons)}</tendon>
  <actuator>{"".join(actuators)}</actuator>
</mujoco>
"""


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    d = tmp_path_factory.mktemp("arm")
    osim_path = build_osim(d)
    paths = {"osim": osim_path}
    variants = {
        "good": twin_xml(),
        "moved": twin_xml(move=("bic-i", (0.005, 0.0, 0.0))),  # insertion 5 mm anterior
        "wrap": twin_xml(wrap=True),
        "drop": twin_xml(drop="tri"),
    }
    for key, text in variants.items():
        p = d / f"arm_{key}.xml"
        p.write_text(text)
        paths[key] = str(p)
    return paths


@pytest.fixture(scope="module")
def good_report(arm) -> MuscleReport:
    return compare_muscles(arm["osim"], arm["good"], n_poses=60, ma_poses=20)


def _osim_length_and_arm(osim_path, values, muscle, coordinate, h=1e-5):
    """OpenSim's length, computeMomentArm, and -dL/dq by central differences (dependents assembled)."""
    model = osim.Model(osim_path)
    model.set_assembly_accuracy(1e-12)
    state = model.initSystem()
    f = osim.PathActuator.safeDownCast(model.getForceSet().get(muscle))
    coord = model.getCoordinateSet().get(coordinate)

    def at(vals):
        s = osim.State(state)
        for n, v in vals.items():
            model.getCoordinateSet().get(n).setValue(s, v, False)
        model.assemble(s)
        model.realizePosition(s)
        return s

    s0 = at(values)
    up = f.getLength(at({**values, coordinate: values[coordinate] + h}))
    dn = f.getLength(at({**values, coordinate: values[coordinate] - h}))
    return f.getLength(s0), f.computeMomentArm(s0, coord), -(up - dn) / (2 * h)


# --------------------------------------------------------------------------------------------


def test_twin_loads_and_matches_opensim_length_at_default(arm):
    m = mujoco.MjModel.from_xml_path(arm["good"])
    d = mujoco.MjData(m)
    lengths = mujoco_tendon_lengths(m, d, {"q_sh": 0.0, "q_el": 0.0})
    model = osim.Model(arm["osim"])
    model.set_assembly_accuracy(1e-12)  # q_wr exactly on its coupling
    s = model.initSystem()
    for i, name in enumerate(PATHS):
        assert lengths[i] == pytest.approx(osim.PathActuator.safeDownCast(model.getForceSet().get(name)).getLength(s),
                                           abs=1e-12)
    mujoco.mj_fwdPosition(m, d)  # actuator_length = tendon length
    np.testing.assert_allclose(d.actuator_length, d.ten_length, atol=0)


def test_correct_twin_agrees(good_report):
    r = good_report
    assert r.n_poses == 60 and r.ma_poses == 20 and r.skipped_poses == 0
    assert set(r.muscles) == set(PATHS)
    assert r.coordinates == ["q_sh", "q_el"] and r.dependent_coordinates == ["q_wr"]
    assert r.max_len_error < 1e-9
    assert r.max_len_pct < 1e-6
    assert r.ma_max < 1e-6 and r.ma_median < 1e-6 and r.ma_p95 < 1e-6
    assert r.ma_fd_vs_jacobian < 1e-6
    assert not r.missing_tendons and not r.extra_tendons and not r.actuator_issues
    # Spanned pairs: bic crosses both joints, tri the elbow, wflex the wrist, driven by q_el.
    assert {m: set(e.moment_arms) for m, e in r.muscles.items()} == {
        "bic": {"q_sh", "q_el"}, "tri": {"q_el"}, "wflex": {"q_el"}}
    assert r.ma_pairs == 4
    assert r.muscles["wflex"].moment_arms["q_el"].max_abs_opensim > 1e-3  # the coupling is seen
    assert r.muscles["bic"].kind == "Thelen2003Muscle" and r.muscles["wflex"].kind == "PathActuator"
    assert r.ok()
    d = r.to_dict()
    json.dumps(d)
    assert d["ok"] is True and d["name"] == "arm"
    text = r.summary()
    assert "bic" in text and "wflex" in text and text.rstrip().endswith("OK")


def test_moved_site_is_detected(arm, good_report):
    r = compare_muscles(arm["osim"], arm["moved"], n_poses=60, ma_poses=20)
    assert r.muscles["bic"].max_len > 4e-3  # a 5 mm displacement
    assert r.max_len_pct > 1.0  # above the default tolerance of ok()
    assert r.muscles["bic"].moment_arms["q_el"].rms > 1e-3
    assert r.ma_max > 1e-3 and r.ma_p95 > 2e-3
    for m in ("tri", "wflex"):  # the other paths are untouched
        assert r.muscles[m].max_len < 1e-9
    assert r.worst_length is not None and r.worst_length["muscle"] == "bic"
    assert not r.ok()
    assert r.ok(len_pct=100, ma_median_mm=100, ma_p95_mm=100, ma_max_mm=100)
    table = format_muscle_table({"good": good_report, "moved": r})
    lines = table.splitlines()
    assert len(lines) == 4 and lines[2].split()[-1] == "yes" and lines[3].split()[-1] == "NO"


def test_moment_arm_sign_matches_opensim(arm):
    values = {"q_sh": 0.3, "q_el": 0.8}
    m = mujoco.MjModel.from_xml_path(arm["good"])
    d = mujoco.MjData(m)
    fd = mujoco_moment_arms(m, d, values, ["q_sh", "q_el"], method="fd")
    jac = mujoco_moment_arms(m, d, values, ["q_sh", "q_el"], method="jacobian")
    np.testing.assert_allclose(fd, jac, atol=1e-8)
    for i, name in enumerate(PATHS):
        for j, coord in enumerate(["q_sh", "q_el"]):
            length, r_os, r_fd = _osim_length_and_arm(arm["osim"], values, name, coord)
            assert r_os == pytest.approx(r_fd, abs=1e-7)  # OpenSim's convention: r = -dL/dq
            assert fd[i, j] == pytest.approx(r_os, abs=1e-8)
    assert fd[0, 1] > 0.01  # bic flexes the elbow
    assert fd[1, 1] < -0.005  # tri extends it
    assert abs(fd[2, 1]) > 1e-3 and abs(fd[2, 0]) < 1e-9  # wflex moves with q_el only, through the coupling


def test_jacobian_follows_nonlinear_equalities():
    """A chain of quartic joint equalities: the projected Jacobian equals finite differences."""
    xml = """<mujoco><worldbody>
      <site name="a" pos="0.3 0.1 0"/>
      <body name="b1"><joint name="q" axis="0 0 1"/><geom size="0.01"/>
        <body name="b2" pos="0.2 0 0"><joint name="d1" axis="0 1 0"/><geom size="0.01"/>
          <body name="b3" pos="0 0.1 0.1"><joint name="d2" type="slide" axis="1 0 0"/><geom size="0.01"/>
            <site name="b" pos="0.05 0.02 0.1"/></body></body></body></worldbody>
      <equality><joint joint1="d1" joint2="q" polycoef="0.1 0.4 -0.3 0.2 0.05"/>
                <joint joint1="d2" joint2="d1" polycoef="0 0.05 0.02 0 -0.01"/></equality>
      <tendon><spatial name="t"><site site="a"/><site site="b"/></spatial></tendon></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    for q in (-0.7, 0.2, 1.1):
        fd = mujoco_moment_arms(m, d, {"q": q}, ["q"], method="fd")
        jac = mujoco_moment_arms(m, d, {"q": q}, ["q"], method="jacobian")
        assert abs(fd[0, 0]) > 1e-3
        assert jac[0, 0] == pytest.approx(fd[0, 0], abs=1e-8)


def test_sweep_finds_no_jump_in_correct_twin(arm):
    s = sweep_jumps(arm["osim"], arm["good"])
    assert s["jumps"] == []
    el = s["coordinates"]["q_el"]
    assert el["steps"] == 145 and el["opensim_swept"]
    for name in PATHS:
        row = el["tendons"][name]
        assert row["mujoco"] == pytest.approx(row["opensim"], abs=1e-9)
        assert row["mujoco"] < 2e-3  # about 1 degree times the moment arm
    json.dumps(s)


def test_sweep_finds_wrapping_flip(arm):
    s = sweep_jumps(arm["osim"], arm["wrap"])
    assert s["jumps"], "the side-site flip went unnoticed"
    j = s["jumps"][0]
    assert j["tendon"] == "bic" and j["coordinate"] == "q_el"
    assert j["mujoco"] > 5e-3 and j["opensim"] < 2e-3
    assert s["worst"]["bic"]["coordinate"] == "q_el"
    assert {x["tendon"] for x in s["jumps"]} == {"bic"}


def _elbow_swing(xml: str) -> np.ndarray:
    """qpos (301, nq): the elbow swung over its OpenSim range while the shoulder moves a little."""
    m = mujoco.MjModel.from_xml_path(xml)
    qpos = np.zeros((301, m.nq))
    qpos[:, m.joint("q_el").qposadr[0]] = np.linspace(*JOINTS[1][-1], 301)
    qpos[:, m.joint("q_sh").qposadr[0]] = np.linspace(0.1, 0.3, 301)
    return qpos


def test_trajectory_of_the_correct_twin_has_no_jump(arm):
    s = trajectory_jumps(arm["osim"], arm["good"], _elbow_swing(arm["good"])[None])
    assert s["jumps"] == [] and s["flips"] == []
    json.dumps(s)


def test_trajectory_finds_a_flip_opensim_does_not_share(arm):
    s = trajectory_jumps(arm["osim"], arm["wrap"], _elbow_swing(arm["wrap"])[None])
    assert [(f["tendon"], f["trajectory"]) for f in s["flips"]] == [("bic", 0)]
    flip = s["flips"][0]
    assert flip["mujoco"] > 5e-3 and flip["opensim_step"] < 1e-3  # OpenSim: no wrap, no step


def test_continuous_opensim_paths_have_no_steps(arm):
    """Fixed-point paths are continuous: the step finder reports nothing (its threshold is not
    met by a steep but smooth length, ~1 degree x the moment arm per sweep interval)."""
    assert opensim_length_steps(arm["osim"], arm["good"], min_step=1e-4) == []


def test_missing_tendon_fails(arm):
    r = compare_muscles(arm["osim"], arm["drop"], n_poses=5)
    assert r.missing_tendons == ["tri"]
    assert "tri" not in r.muscles
    assert not r.ok()
    assert "no MuJoCo tendon: tri" in r.summary()


def test_moment_arm_curve_and_plot(arm):
    qs, r_os, r_mj = moment_arm_curve(arm["osim"], arm["good"], "wflex", "q_el", n=21)
    assert qs[0] == 0.0 and qs[-1] == 2.5
    np.testing.assert_allclose(r_mj, r_os, atol=1e-7)
    # The wrist moment arm about the elbow is the wrist's, times dq_wr/dq_el = C1 + 2 C2 q_el.
    # It changes sign where that derivative does, at q_el = 1.25.
    assert abs(r_os[10]) < 1e-9 and np.sign(r_os[0]) == -np.sign(r_os[-1]) != 0
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ax = plot_moment_arms(arm["osim"], arm["good"], "bic", "q_el", n=11)
    assert len(ax.get_lines()) == 2 and "deg" in ax.get_xlabel()
    plt.close(ax.figure)


def test_bad_arguments(arm):
    with pytest.raises(ValueError):
        compare_muscles(arm["osim"], arm["good"], n_poses=0)
    with pytest.raises(KeyError):
        moment_arm_curve(arm["osim"], arm["good"], "nope", "q_el")


def test_nan_moment_arms_of_opensim_are_left_out_and_counted(tmp_path):
    """A muscle on a ±10 m slider whose two points meet at rest (a public test model's form):
    OpenSim's computeMomentArm is NaN at the comparison's poses. Those samples are left out and
    counted, and no NaN reaches the moment-arm statistics (once all three were NaN)."""
    from tests.helpers import slider_model

    m, b = slider_model("hanging")
    coord = m.updJointSet().get(0).upd_coordinates(0)
    coord.setRangeMin(-10.0)
    coord.setRangeMax(10.0)
    muscle = osim.Thelen2003Muscle()
    muscle.setName("hanging")
    muscle.addNewPathPoint("origin", m.getGround(), osim.Vec3(0))
    muscle.addNewPathPoint("insertion", b, osim.Vec3(0))
    m.addForce(muscle)
    m.finalizeConnections()
    osim_path = tmp_path / "hanging.osim"
    m.printToXML(str(osim_path))
    xml = tmp_path / "hanging.xml"
    xml.write_text(f"""<mujoco><worldbody><site name="origin"/>
<body name="b"><joint name="{coord.getName()}" type="slide" axis="1 0 0" range="-10 10"/>
<geom size="0.05" mass="1"/><site name="insertion"/></body></worldbody>
<tendon><spatial name="hanging"><site site="origin"/><site site="insertion"/></spatial></tendon>
<actuator><muscle name="hanging" tendon="hanging" lengthrange="0 10"/></actuator></mujoco>""")
    rep = compare_muscles(osim_path, xml, n_poses=12, seed=0, ma_poses=6)
    assert rep.max_len_pct < 1e-6  # the lengths agree: |x| in both
    assert rep.ma_opensim_nan > 0
    assert all(math.isfinite(v) for v in (rep.ma_median, rep.ma_p95, rep.ma_max)), rep
    assert "computeMomentArm is NaN" in rep.summary()
