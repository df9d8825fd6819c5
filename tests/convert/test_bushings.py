"""BushingForce beyond one joint (o2m.convert.bushings) against OpenSim 4.6.

A small model: ground -CustomJoint 'ball' (rotations about X, -Y through a mirrored function, Z
through q -> 2 q + 0.1: a complement joint in MuJoCo)-> a -Pin p1-> b -Pin p2 (axis parallel to
p1's)-> c, c -Weld-> d, c -Pin p3 (locked)-> e. Bushing 'ball' spans the 3-coordinate joint with
frames on its axes (deflections linear in rx, ry, rz), 'chain' spans p1 and p2 (its Z angle is
q1 + q2; its isotropic translational spring between points off the axes is not linear),
'locked' spans p2 and the locked p3 (one free coordinate: a joint spring), 'points' is
an isotropic translational spring between a and c, 'welded' joins c and d, 'composed' spans
'ball' and p1 (rotations about different axes composed: not linear). The exact ones' MuJoCo
passive force equals OpenSim's generalized force (M · Δu̇ with the bushing on and off) to 1e-9 of
its size; the composed one, and 'points_damped' (its damping across the line between its frame
origins), become ghost bodies welded to their second frames (o2m.convert.bushing_ghost), which
change the coordinates' accelerations as OpenSim's bushing does; ``bushing_tolerance`` above
the measured non-linearity makes them fixed tendons instead.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m.convert.bushing_ghost import pose_ghost
from o2m.convert.converter import ConvertOptions, convert
from o2m.mj.posing import pose_mujoco
from tests.helpers import convert_options

osim.Logger.setLevelString("error")

COORDS = ["rx", "ry", "rz", "q1", "q2"]
RANGES = {"rx": (-1.0, 1.0), "ry": (-1.0, 1.0), "rz": (-0.6, 0.6), "q1": (-1.0, 1.0), "q2": (-1.2, 1.4)}
BUSHINGS = ("ball", "chain", "composed", "points", "points_damped", "welded", "locked")


def _v(*a) -> osim.Vec3:
    return osim.Vec3(*a)


def _ball_joint(parent: osim.PhysicalFrame, child: osim.Body) -> osim.CustomJoint:
    """Rotations rx about X, -ry about Y and 2 rz + 0.1 about Z (``set_function`` copies the
    function; ``setFunction`` would take ownership and crash)."""
    st = osim.SpatialTransform()
    moving = {0: ("rx", (1.0, 0.0)), 1: ("ry", (-1.0, 0.0)), 2: ("rz", (2.0, 0.1))}
    for i, axis in enumerate([(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 0, 0), (0, 1, 0), (0, 0, 1)]):
        ax = st.updTransformAxis(i)
        names = osim.ArrayStr()
        if i in moving:
            names.append(moving[i][0])
        ax.setCoordinateNames(names)
        ax.setAxis(_v(*axis))
        ax.set_function(osim.LinearFunction(*moving[i][1]) if i in moving else osim.Constant(0.0))
    return osim.CustomJoint("ball", parent, _v(0.1, 0.9, -0.05), _v(0.2, -0.1, 0.4), child, _v(0.0, 0.15, 0.02),
                            _v(-0.3, 0.2, 0.1), st)


def _offset(name: str, joint_frame: osim.PhysicalOffsetFrame, body: osim.PhysicalFrame,
            turn: tuple[float, float, float], shift: tuple[float, float, float] = (0.0, 0.0, 0.0)
            ) -> osim.PhysicalOffsetFrame:
    """A frame on ``body``: the joint frame turned by body-fixed X-Y-Z angles ``turn`` and shifted."""
    rot = osim.Rotation(osim.BodyRotationSequence, turn[0], osim.CoordinateAxis(0), turn[1], osim.CoordinateAxis(1),
                        turn[2], osim.CoordinateAxis(2))
    frame = osim.PhysicalOffsetFrame(name, body, joint_frame.findTransformInBaseFrame().compose(
        osim.Transform(rot, _v(*shift))))
    body.addComponent(frame)
    return frame


def _build(path: Path) -> Path:
    m = osim.Model()
    m.setName(path.stem)
    inertia = osim.Inertia(0.02, 0.012, 0.018, 0.001, -0.0005, 0.0002)
    a, b, c = (osim.Body(n, mass, _v(*com), inertia) for n, mass, com in
               [("a", 2.0, (0.03, -0.2, 0.01)), ("b", 1.2, (-0.02, -0.15, 0.03)), ("c", 0.8, (0.01, -0.1, 0.02))])
    for body in (a, b, c):
        m.addBody(body)
    ball = _ball_joint(m.getGround(), a)
    aligned = _v(0.3, -0.2, 0.5)  # p1's child frame and p2's parent frame: parallel pin axes
    p1 = osim.PinJoint("p1", a, _v(0.05, -0.3, 0.02), _v(0.1, 0.2, -0.1), b, _v(0.0, 0.1, 0.0), aligned)
    p2 = osim.PinJoint("p2", b, _v(0.02, -0.25, 0.01), aligned, c, _v(0.01, 0.12, -0.02), _v(-0.2, 0.1, 0.3))
    for joint in (ball, p1, p2):
        m.addJoint(joint)
        for i in range(joint.numCoordinates()):
            coord = joint.upd_coordinates(i)
            if joint.getName() != "ball":
                coord.setName({"p1": "q1", "p2": "q2"}[joint.getName()])
            lo, hi = RANGES[coord.getName()]
            coord.setRangeMin(lo)
            coord.setRangeMax(hi)
    d = osim.Body("d", 0.3, _v(0.0, -0.05, 0.0), inertia)
    e = osim.Body("e", 0.5, _v(0.01, -0.04, 0.0), inertia)
    m.addBody(d)
    m.addBody(e)
    m.addJoint(osim.WeldJoint("weld", c, _v(0.0, -0.2, 0.0), _v(0.1, 0.0, 0.0), d, _v(0.0, 0.0, 0.0),
                              _v(0.0, 0.0, 0.0)))
    p3 = osim.PinJoint("p3", c, _v(0.0, -0.2, 0.0), _v(0.4, 0.1, -0.3), e, _v(0.0, 0.0, 0.0), _v(0.4, 0.1, -0.3))
    m.addJoint(p3)
    p3.upd_coordinates(0).setName("q3")  # locked at 0: e's frame is c's, shifted
    p3.upd_coordinates(0).setDefaultLocked(True)
    frames = {"ball": (_offset("ball_1", ball.getParentFrame(), m.getGround(), (0.3, 0.0, 0.0), (0.02, -0.01, 0.03)),
                       _offset("ball_2", ball.getChildFrame(), a, (0.0, 0.0, 0.2))),
              "chain": (_offset("chain_1", p1.getParentFrame(), a, (0.0, 0.0, 0.0)),
                        _offset("chain_2", p2.getChildFrame(), c, (0.0, 0.0, -0.2), (0.05, -0.1, 0.02))),
              "composed": (_offset("composed_1", ball.getParentFrame(), m.getGround(), (0.0, 0.0, 0.0)),
                           _offset("composed_2", p1.getChildFrame(), b, (0.0, 0.0, 0.0))),
              "welded": (_offset("welded_1", p2.getChildFrame(), c, (0.1, 0.2, 0.3), (0.01, 0.02, 0.03)),
                         osim.PhysicalOffsetFrame("welded_2", d, osim.Transform(_v(0.02, 0.0, -0.01))))}
    d.addComponent(frames["welded"][1])
    frames["locked"] = (_offset("locked_1", p2.getParentFrame(), b, (0.0, 0.0, 0.1)),
                        osim.PhysicalOffsetFrame("locked_2", e, p2.getChildFrame().findTransformInBaseFrame()))
    e.addComponent(frames["locked"][1])
    for name in ("points", "points_damped"):
        frames[name] = (_offset(f"{name}_1", p1.getParentFrame(), a, (0.2, -0.1, 0.4), (0.03, 0.02, -0.01)),
                        _offset(f"{name}_2", p2.getChildFrame(), c, (0.0, 0.3, 0.0), (0.05, -0.1, 0.02)))
    stiffness = {"ball": ((40.0, 50.0, 60.0), (30.0, 20.0, 10.0)), "chain": ((200.0,) * 3, (30.0, 20.0, 10.0)),
                 "points": ((500.0,) * 3, (0.0,) * 3),
                 "points_damped": ((500.0,) * 3, (0.0,) * 3)}
    damping = {"points": ((0.0,) * 3, (0.0,) * 3), "points_damped": ((2.0,) * 3, (0.0,) * 3)}
    for name, (f1, f2) in frames.items():
        trans, rot = stiffness.get(name, ((0.0,) * 3, (30.0, 20.0, 10.0)))
        trans_damp, rot_damp = damping.get(name, ((0.0,) * 3, (0.3, 0.5, 0.7)))
        # Python's argument order: translational stiffness, rotational stiffness, then the dampings
        m.addForce(osim.BushingForce(name, f1, f2, _v(*trans), _v(*rot), _v(*trans_damp), _v(*rot_damp)))
    m.finalizeConnections()
    m.printToXML(str(path))
    return path


def _opensim_forces(path: Path, bushing: str, states, accelerations: bool = False) -> list[np.ndarray]:
    """OpenSim's generalized force (coordinate order) of ``bushing`` alone at each (q, qdot): M · Δu̇
    with it on and off, M and u̇ in mobility order; with ``accelerations``, Δu̇ itself."""
    model = osim.Model(str(path))
    state = model.initSystem()
    cs = model.getCoordinateSet()
    matter = model.getMatterSubsystem()
    order = []
    for c in COORDS:  # each coordinate's mobility: the one u its speed sets
        st = osim.State(state)
        for other in COORDS:
            cs.get(other).setSpeedValue(st, float(other == c))
        order.append(int(np.argmax(np.abs([st.getU().get(i) for i in range(st.getNU())]))))
    out = []
    for q, qdot in states:
        udot = []
        for on in (False, True):
            st = osim.State(state)
            for c, qi, vi in zip(COORDS, q, qdot, strict=True):
                cs.get(c).setValue(st, float(qi), False)
                cs.get(c).setSpeedValue(st, float(vi))
            for name in BUSHINGS:
                model.getForceSet().get(name).setAppliesForce(st, on and name == bushing)
            model.realizeAcceleration(st)
            udot.append(np.array([st.getUDot().get(i) for i in range(st.getNU())]))
        if accelerations:
            out.append((udot[1] - udot[0])[order])
            continue
        mass = osim.Matrix()
        matter.calcM(st, mass)
        full = np.array([[mass.get(i, j) for j in range(mass.ncol())] for i in range(mass.nrow())])
        out.append((full @ (udot[1] - udot[0]))[order])
    return out


def _mujoco_forces(xml: Path, tendons: list[str], states, joints: tuple[str, ...] = ()) -> list[np.ndarray]:
    """MuJoCo's passive force on the coordinates' joints with only the springs and dampers of
    ``tendons`` and ``joints`` on, at each (q, qdot); asserts every other dof gets none (to round-off)."""
    m = mujoco.MjModel.from_xml_path(str(xml))
    keep_joints = [m.joint(j).id for j in joints]
    for arr, keep in ((m.tendon_stiffness, [m.tendon(t).id for t in tendons]),
                      (m.tendon_damping, [m.tendon(t).id for t in tendons]), (m.jnt_stiffness, keep_joints),
                      (m.dof_damping, [int(m.jnt_dofadr[j]) for j in keep_joints])):
        mask = np.ones(arr.shape[0], bool)
        mask[keep] = False
        arr[mask] = 0.0
    m.body_gravcomp[:] = 0.0  # the ghost bodies' weight, cancelled: no part of a bushing's force
    d = mujoco.MjData(m)
    dofs = [int(m.jnt_dofadr[m.joint(c).id]) for c in COORDS]
    out = []
    for q, qdot in states:
        pose_mujoco(m, d, dict(zip(COORDS, map(float, q), strict=True)))
        d.qvel[:] = 0.0
        d.qvel[dofs] = qdot
        mujoco.mj_forward(m, d)
        others = np.delete(d.qfrc_passive, dofs)  # a spatial tendon's, above its bodies: round-off
        assert np.abs(others).max(initial=0.0) <= 1e-12 * max(1.0, np.abs(d.qfrc_passive).max())
        out.append(d.qfrc_passive[dofs].copy())
    return out


def _states(n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    lo, hi = np.array([RANGES[c] for c in COORDS]).T
    return [(rng.uniform(lo, hi), rng.uniform(-2.0, 2.0, len(COORDS))) for _ in range(n)]


@pytest.fixture(scope="module")
def model_path(tmp_path_factory) -> Path:
    return _build(tmp_path_factory.mktemp("bushings") / "bushings.osim")


def test_linear_bushings_become_exact_fixed_tendons(model_path, tmp_path):
    """'ball' (3 coordinates of one joint) and 'chain' (two joints) become fixed tendons, one per
    stiff or damped angle or offset their coordinates move (ball's constant offsets none), and
    chain's translational spring a zero-length spatial tendon; so does 'points' (an
    isotropic translational spring) a zero-length spatial tendon; 'locked' the spring and damping
    of q2, the one free coordinate between its frames; 'welded' nothing. Each one's MuJoCo
    passive force equals OpenSim's generalized force to 1e-9 of its size at seeded poses and speeds.
    'composed' becomes a ghost body for its measured non-linearity, 'points_damped' for its damping
    across the line."""
    conv = convert(model_path, tmp_path / "out", convert_options(fit_mechanics=False))
    assert not [s for s in conv.report.skipped if s.element == "BushingForce"]
    ghosts = {a.name: a.what for a in conv.report.approximations if a.element == "BushingForce" and "ghost" in a.what}
    assert set(ghosts) == {"composed", "points_damped"}
    worst = float(ghosts["composed"].split("up to ")[1].split(" rad")[0])
    assert "not linear in 'rx', 'ry', 'rz', 'q1'" in ghosts["composed"] and worst > 0.01
    assert "damping (2 N s/m)" in ghosts["points_damped"]
    assert any("'welded': its frames do not move" in n for n in conv.report.notes)
    assert conv.report.counts["other forces"] == len(BUSHINGS)  # each one once
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    tendons = {name: sorted(m.tendon(i).name for i in range(m.ntendon)
                            if m.tendon(i).name == name or m.tendon(i).name.startswith(name + "_"))
               for name in ("ball", "chain", "points")}
    assert tendons == {"ball": ["ball_rx", "ball_ry", "ball_rz"], "chain": ["chain", "chain_rz"], "points": ["points"]}
    states = _states(6, seed=3)
    for name, ts in tendons.items():
        expected = _opensim_forces(model_path, name, states)
        for got, want in zip(_mujoco_forces(conv.xml, ts, states), expected, strict=True):
            assert np.abs(want).max() > 0.1
            np.testing.assert_allclose(got, want, rtol=0.0, atol=1e-9 * np.abs(want).max())
        [approx] = [a for a in conv.report.approximations if a.element == "BushingForce" and a.name == name]
        assert approx.max_error < 1e-6
    [locked] = [a for a in conv.report.approximations if a.element == "BushingForce" and a.name == "locked"]
    assert "joint 'q2'" in locked.what and locked.max_error < 1e-6
    q2 = m.joint("q2").id
    assert (m.jnt_stiffness[q2], m.qpos_spring[m.jnt_qposadr[q2]], m.dof_damping[m.jnt_dofadr[q2]]) == \
        pytest.approx((10.0, 0.1, 0.7), rel=1e-12)  # K_z, the frames' 0.1 rad turn, D_z
    expected = _opensim_forces(model_path, "locked", states)
    for got, want in zip(_mujoco_forces(conv.xml, [], states, joints=("q2",)), expected, strict=True):
        assert np.abs(want).max() > 0.1
        np.testing.assert_allclose(got, want, rtol=0.0, atol=1e-9 * np.abs(want).max())
    welded = _opensim_forces(model_path, "welded", states)
    assert max(np.abs(w).max() for w in welded) < 1e-9  # what OpenSim applies moves no coordinate
    for name in ghosts:  # the ghost's springs through its kinematics: -Jᵀ(K θ + D θ̇), to the five-point
        [approx] = [a for a in conv.report.approximations if a.element == "BushingForce" and a.name == name]
        largest = float(approx.detail.split("(largest ")[1].rstrip(")"))  # differences' truncation (step 1e-4)
        assert largest > 1.0 and approx.max_error < 1e-5 * largest


def _ghost(name: str) -> SimpleNamespace:
    """The ghost records :func:`pose_ghost` reads, by the converter's names."""
    return SimpleNamespace(ghost_body=f"{name}_ghost", ghost_weld=f"{name}_ghost",
                           ghost_joints=[f"{name}_ghost_{a}" for a in ("tx", "ty", "tz", "rx", "ry", "rz")])


def _posed(m: mujoco.MjModel, d: mujoco.MjData, q: np.ndarray, ghosts: tuple[str, ...]) -> np.ndarray:
    pose_mujoco(m, d, dict(zip(COORDS, map(float, q), strict=True)))
    for name in ghosts:
        pose_ghost(m, d, _ghost(name))
    return d.qpos.copy()


def _mujoco_accelerations(xml: Path, bushing: str, states, ghosts: tuple[str, ...]) -> list[np.ndarray]:
    """MuJoCo's change of the coordinates' accelerations when ``bushing``'s ghost springs and
    dampers are switched on (every other spring and damper off), at each (q, qdot), the ghosts
    posed on their welds and moving with them."""
    m = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(m)
    own = [m.joint(j).id for j in _ghost(bushing).ghost_joints]
    stiffness, damping = m.jnt_stiffness[own].copy(), m.dof_damping[m.jnt_dofadr[own]].copy()
    m.jnt_stiffness[:], m.dof_damping[:], m.tendon_stiffness[:], m.tendon_damping[:] = 0.0, 0.0, 0.0, 0.0
    dofs = [int(m.jnt_dofadr[m.joint(c).id]) for c in COORDS]
    out = []
    for q, qdot in states:
        eps = 1e-6
        vel = np.zeros(m.nv)
        mujoco.mj_differentiatePos(m, vel, 2 * eps, _posed(m, d, q - eps * qdot, ghosts),
                                   _posed(m, d, q + eps * qdot, ghosts))
        acc = []
        for on in (False, True):
            m.jnt_stiffness[own], m.dof_damping[m.jnt_dofadr[own]] = (stiffness, damping) if on else (0.0, 0.0)
            d.qpos[:], d.qvel[:] = _posed(m, d, q, ghosts), vel
            mujoco.mj_forward(m, d)
            acc.append(d.qacc[dofs].copy())
        out.append(acc[1] - acc[0])
    return out


def test_ghost_bushings_move_the_coordinates_as_opensim(model_path, tmp_path):
    """A ghost body (the 'composed' bushing, rotations composed about different axes, and
    'points_damped') changes the coordinates' accelerations as OpenSim's bushing does (Δu̇ with it
    on and off) within 8 % of their largest (measured 7.0 %: its weld's softness and its
    armature); posed by :func:`pose_ghost` (and in the default-pose keyframe) its weld holds to
    round-off; 2 s of falling from a
    pose stay finite, the welds slipping at most 0.02 (m or rad; measured 0.011, while the joints
    speed up to 7 rad/s) and 0.005 at the end."""
    conv = convert(model_path, tmp_path / "out", convert_options(fit_mechanics=False))
    ghosts = ("composed", "points_damped")
    states = _states(6, seed=3)
    for name in ghosts:
        want = _opensim_forces(model_path, name, states, accelerations=True)
        for got, expected in zip(_mujoco_accelerations(conv.xml, name, states, ghosts), want, strict=True):
            assert np.abs(expected).max() > 10.0
            assert np.abs(got - expected).max() <= 0.08 * np.abs(expected).max()
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("default-pose").id)
    mujoco.mj_forward(m, d)
    assert _weld_error(m, d, ghosts) < 1e-9  # the keyframe has the ghosts posed
    _posed(m, d, states[0][0], ghosts)
    d.qvel[:] = 0.0
    mujoco.mj_forward(m, d)
    assert _weld_error(m, d, ghosts) < 1e-9
    worst = 0.0
    for _ in range(int(round(2.0 / m.opt.timestep))):
        mujoco.mj_step(m, d)
        worst = max(worst, _weld_error(m, d, ghosts))
    assert np.isfinite(d.qpos).all() and worst < 0.02 and _weld_error(m, d, ghosts) < 0.005


def _weld_error(m: mujoco.MjModel, d: mujoco.MjData, ghosts: tuple[str, ...]) -> float:
    """The largest violation of the ghosts' welds (m, rad) in ``d`` (after mj_forward or mj_step)."""
    ids = [m.equality(f"{g}_ghost").id for g in ghosts]
    rows = (d.efc_type[:d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY) & np.isin(d.efc_id[:d.nefc], ids)
    assert rows.sum() == 6 * len(ghosts)
    return float(np.abs(d.efc_pos[:d.nefc][rows]).max())


def test_bushing_tolerance_converts_approximations(model_path, tmp_path):
    """With a bushing_tolerance above its measured non-linearity 'composed' becomes fixed tendons
    and 'points_damped' a spatial tendon (its damping along the line only); the report records
    their generalized-force errors. Below it, 'composed' stays a ghost body. A negative tolerance
    is refused."""
    default = convert(model_path, tmp_path / "default", convert_options(fit_mechanics=False))
    [reason] = [a.what for a in default.report.approximations if a.name == "composed"]
    worst = float(reason.split("up to ")[1].split(" rad")[0])
    below = convert(model_path, tmp_path / "below", convert_options(fit_mechanics=False,
                                                                     bushing_tolerance=worst / 2))
    assert [a.name for a in below.report.approximations if "ghost" in a.what] == ["composed"]
    above = convert(model_path, tmp_path / "above", convert_options(fit_mechanics=False,
                                                                    bushing_tolerance=worst * 2))
    assert not [s for s in above.report.skipped if s.element == "BushingForce"]
    approx = {a.name: a for a in above.report.approximations if a.element == "BushingForce"}
    assert approx["composed"].max_error > 0.0 and f"{worst:.3g}" in approx["composed"].what
    assert approx["points_damped"].max_error > 0.0 and "along the line only" in approx["points_damped"].what
    m = mujoco.MjModel.from_xml_path(str(above.xml))
    assert {m.tendon(i).name for i in range(m.ntendon)} >= {"composed_rx", "composed_ry", "composed_rz",
                                                             "points_damped"}
    with pytest.raises(ValueError, match="bushing_tolerance"):
        ConvertOptions(bushing_tolerance=-1.0)
    from o2m.cli import main  # the same choice from the command line

    assert main(["convert", str(model_path), "-o", str(tmp_path / "cli"), "--bushing-tolerance", f"{worst * 2}",
                 "--no-moment-arm-plots"]) == 0
    report = (tmp_path / "cli" / f"{model_path.stem}.report.txt").read_text()
    assert "composed" in report and f"{worst:.3g}" in report
    with pytest.raises(SystemExit, match="bushing_tolerance"):
        main(["convert", str(model_path), "-o", str(tmp_path / "bad"), "--bushing-tolerance", "-1"])
