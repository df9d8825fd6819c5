"""Contact (o2m.convert.contact) against OpenSim 4.6.

* Simbody's Hunt-Crossley law as o2m reimplements it (:class:`o2m.convert.contact_fit.HuntCrossley`,
  two surfaces with different parameters combined) gives OpenSim's contact force, normal and
  friction, at every penetration, penetration rate and slip speed tried.
* A ball (o2m.validate.contact) dropped on the half space and sliding over it, in OpenSim and in
  the converted model at its own 2-ms step: the errors in peak penetration, restitution (from the
  rebound height) and stopping distance stay within what the conversion report records for the
  force, and the first contact comes within one MuJoCo step of OpenSim's.
* The written pair is the spring-damper o2m fits (solref in MuJoCo's units, friction).
* What the geometry becomes (planes face out of the half space, spheres where OpenSim has them,
  no collision by themselves), which pairs a force gets (every pair on two bodies that can move
  against each other), and what is skipped (unused geometry, ElasticFoundationForce).
* SmoothSphereHalfSpaceForce: o2m's smooth law is OpenSim's force, and a ball dropped and slid
  with it stays within what the report records (deepest point, restitution, stopping distance).
* Corpus models with contact convert, load and step 1 s without NaN.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from o2m.convert.contact import FALL_DEEPEST, IMPACT_DURATION, IMPACT_PEAK, IMPACT_RESTITUTION, SLIDE_DISTANCE
from o2m.convert.contact_fit import SLIDE_SPEED, HuntCrossley, Surface, fit_linear, sliding_friction
from o2m.convert.contact_smooth import SmoothHuntCrossley
from o2m.convert.converter import ConvertOptions, convert
from o2m.osim import runtime
from o2m.validate.contact import STOPPED, BallModel, compare_drop, compare_slide, write_ball_model
from tests.helpers import model_file

FAST = ConvertOptions(quick=True, fit_mechanics=False, fit_wraps=False)
#: The ball of the drop and slide tests: corpus-like parameters (ToyLanding uses viscous friction too).
BALL = BallModel(viscous_friction=0.2)
#: Drop heights (m): impacts at 0.99 and 3.13 m/s, inside the speeds the report measures.
DROPS = (0.05, 0.5)


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ball")
    osim = write_ball_model(folder / "ball.osim", BALL)
    return osim, convert(osim, folder / "out", FAST)


#: A heavy body on a soft smooth contact (a foot sphere of a Moco gait model: stiffness 1e6, 3 cm).
SMOOTH_BALLS = (BallModel(smooth=True, viscous_friction=0.2),
                BallModel(smooth=True, mass=12.0, radius=0.03, stiffness=1e6))


@pytest.fixture(scope="module", params=range(len(SMOOTH_BALLS)))
def smooth_ball(request, tmp_path_factory):
    folder = tmp_path_factory.mktemp("smooth")
    ball = SMOOTH_BALLS[request.param]
    osim = write_ball_model(folder / "ball.osim", ball)
    return ball, osim, convert(osim, folder / "out", FAST)


def _recorded(conv, what: str, element: str = "HuntCrossleyForce") -> float:
    hits = [a for a in conv.report.approximations if a.element == element and a.what == what]
    assert len(hits) == 1, what
    return hits[0].max_error


# -- the law ------------------------------------------------------------------------------------
def _parameters(geometry: str, s: Surface) -> str:
    return (f"<HuntCrossleyForce::ContactParameters><geometry>{geometry}</geometry>"
            f"<stiffness>{s.stiffness!r}</stiffness><dissipation>{s.dissipation!r}</dissipation>"
            f"<static_friction>{s.static_friction!r}</static_friction>"
            f"<dynamic_friction>{s.dynamic_friction!r}</dynamic_friction>"
            f"<viscous_friction>{s.viscous_friction!r}</viscous_friction></HuntCrossleyForce::ContactParameters>")


def test_law_is_opensims(tmp_path):
    """Two surfaces with different parameters: o2m's combined law against OpenSim's force."""
    osim = runtime.opensim()
    floor = Surface(2e7, 0.3, 0.9, 0.5, 0.1)
    sphere = Surface(5e6, 0.8, 0.7, 0.6, 0.4)
    radius, transition = 0.05, 0.05
    text = write_ball_model(tmp_path / "one.osim", BallModel(radius=radius, transition_velocity=transition)).read_text()
    start = text.index("<HuntCrossleyForce::ContactParameters>")
    end = text.index("</HuntCrossleyForce::ContactParameters>") + len("</HuntCrossleyForce::ContactParameters>")
    text = text[:start] + _parameters("floor", floor) + _parameters("ball_sphere", sphere) + text[end:]
    (tmp_path / "two.osim").write_text(text)
    model = osim.Model(str(tmp_path / "two.osim"))
    force = model.getForceSet().get("contact")
    state = model.initSystem()
    law = HuntCrossley.combine(floor, sphere, radius, transition)
    coords = model.getCoordinateSet()
    labels = [force.getRecordLabels().get(i) for i in range(force.getRecordLabels().size())]
    fx, fy = labels.index("contact.ball.force.X"), labels.index("contact.ball.force.Y")
    for x in (1e-4, 1e-3, 4e-3):
        for xdot in (-0.5, 0.0, 0.3):
            for slip in (0.01, 0.05, 1.0):
                coords.get("ball_ty").setValue(state, radius - x)
                coords.get("ball_ty").setSpeedValue(state, -xdot)
                coords.get("ball_tx").setSpeedValue(state, slip)
                model.realizeDynamics(state)
                values = force.getRecordValues(state)
                assert values.get(fy) == pytest.approx(float(law.force(x, xdot)), rel=1e-9, abs=1e-9)
                f = law.stiffness * x ** 1.5 * (1 + 1.5 * law.dissipation * xdot)  # Simbody's, unclamped
                assert values.get(fx) == pytest.approx(-float(law.friction(f, slip)), rel=1e-9, abs=1e-9)


# -- drop and slide against OpenSim -------------------------------------------------------------
@pytest.mark.parametrize("drop", DROPS)
def test_drop_within_recorded_errors(ball, drop):
    osim, conv = ball
    c = compare_drop(osim, conv.xml, BALL, drop)
    step = mujoco.MjModel.from_xml_path(str(conv.xml)).opt.timestep
    assert abs(c.error("contact_time")) <= step, c.summary()
    assert abs(c.relative("peak_penetration")) <= _recorded(conv, IMPACT_PEAK) / 100, c.summary()
    assert abs(c.error("restitution")) <= _recorded(conv, IMPACT_RESTITUTION), c.summary()


def test_slide_within_recorded_error(ball):
    osim, conv = ball
    c = compare_slide(osim, conv.xml, BALL, SLIDE_SPEED)
    assert abs(c.relative("stop_distance")) <= _recorded(conv, SLIDE_DISTANCE) / 100, c.summary()


#: A heavy ball on a soft, strongly damped contact (as the hip and knee contacts of OpenSim's
#: WalkerModel_ClutchedPathSpring: about 3 kg, dissipation 2 s/m): under gravity the contact takes
#: the whole rebound, so the ball dropped on the floor stays on it.
HELD = BallModel(mass=3.0, stiffness=2e6, dissipation=2.0)


def test_a_ball_gravity_holds_on_the_floor_stays_there(tmp_path):
    """OpenSim's ball does not rebound; the conversion measures such impacts (it raised before)
    and says where the body stays on the surface."""
    osim = write_ball_model(tmp_path / "held.osim", HELD)
    conv = convert(osim, tmp_path / "out", FAST)
    c = compare_drop(osim, conv.xml, HELD, 0.0127)  # impact at 0.5 m/s
    assert c.opensim["restitution"] == pytest.approx(0.0, abs=1e-3), c.summary()
    assert c.mujoco["restitution"] == pytest.approx(0.0, abs=1e-3), c.summary()
    duration = [a for a in conv.report.approximations if a.what == IMPACT_DURATION]
    assert len(duration) == 1 and "the body stays on the surface at" in duration[0].detail
    law = HuntCrossley.combine(Surface(HELD.stiffness, HELD.dissipation, HELD.static_friction,
                                       HELD.dynamic_friction, HELD.viscous_friction),
                               Surface(HELD.stiffness, HELD.dissipation, HELD.static_friction,
                                       HELD.dynamic_friction, HELD.viscous_friction),
                               HELD.radius, HELD.transition_velocity)
    held, free = law.impact(HELD.mass, 0.5, 9.80665), law.impact(HELD.mass, 0.5)
    assert held.stays and held.restitution == 0.0 and math.isinf(held.duration)
    assert not free.stays and 0.0 < free.restitution < 1.0
    assert held.peak > free.peak > 0.0  # gravity pushes it deeper


# -- what the elements become -------------------------------------------------------------------
def test_geometry_and_pair(ball):
    _, conv = ball
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    floor, sphere = m.geom("floor"), m.geom("ball_sphere")
    assert floor.type[0] == mujoco.mjtGeom.mjGEOM_PLANE and sphere.type[0] == mujoco.mjtGeom.mjGEOM_SPHERE
    assert np.allclose(d.geom_xmat[floor.id].reshape(3, 3)[:, 2], [0, 0, 1])  # OpenSim's +y: out of the floor
    assert sphere.size[0] == BALL.radius
    assert (m.geom_contype == 0).all() and (m.geom_conaffinity == 0).all()
    assert m.npair == 1 and m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert {m.pair_geom1[0], m.pair_geom2[0]} == {floor.id, sphere.id} and m.pair_dim[0] == 3
    assert not conv.report.skipped


def test_written_pair_is_the_fit(ball):
    """The pair's solref, in MuJoCo's units (scaled by the bodies' inverse weight), is the spring-damper
    fitted to the ball's law; its friction is the slide's Coulomb coefficient."""
    _, conv = ball
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    surface = Surface(BALL.stiffness, BALL.dissipation, BALL.static_friction, BALL.dynamic_friction,
                      BALL.viscous_friction)
    law = HuntCrossley.combine(surface, surface, BALL.radius, BALL.transition_velocity)
    fit = fit_linear(law, BALL.mass, float(np.linalg.norm(m.opt.gravity)), m.opt.timestep)
    weight = m.body_invweight0[m.body("ball").id, 0]
    assert -m.pair_solref[0] / weight == pytest.approx([fit.stiffness, fit.damping], rel=1e-5)
    assert -m.pair_solreffriction[0, 1] / weight == pytest.approx(fit.friction_damping, rel=1e-5)
    assert m.pair_friction[0, :2] == pytest.approx([fit.friction] * 2, rel=1e-5)
    assert fit.friction == pytest.approx(sliding_friction(law)) and fit.friction > BALL.dynamic_friction


def test_pairs_and_skips(tmp_path):
    """Three balls and a floor: pairs between every two that can move against each other; an unused
    sphere and an ElasticFoundationForce are skipped with their reasons."""
    osim = runtime.opensim()
    model = osim.Model(str(write_ball_model(tmp_path / "one.osim")))
    for name, attach in (("second", "ball"), ("third", None)):
        body = osim.Body(name, 1.0, osim.Vec3(0), osim.Inertia(1e-3))
        model.addBody(body)
        model.addJoint(osim.FreeJoint(f"{name}_free", model.getGround(), body) if attach is None
                       else osim.WeldJoint(f"{name}_weld", model.getBodySet().get(attach), body))
        model.addContactGeometry(osim.ContactSphere(0.03, osim.Vec3(0.2, 0, 0), body, f"{name}_sphere"))
    model.addContactGeometry(osim.ContactSphere(0.03, osim.Vec3(0), model.getGround(), "unused"))
    force = osim.HuntCrossleyForce.safeDownCast(model.getForceSet().get("contact"))
    for g in ("second_sphere", "third_sphere"):
        force.addGeometry(g)
    foundation = osim.ElasticFoundationForce()
    foundation.setName("foundation")
    model.addForce(foundation)
    model.finalizeConnections()
    model.printToXML(str(tmp_path / "three.osim"))
    conv = convert(tmp_path / "three.osim", tmp_path / "out", FAST)
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    pairs = {frozenset((m.geom(m.pair_geom1[i]).name, m.geom(m.pair_geom2[i]).name)) for i in range(m.npair)}
    # ball and second are welded: no pair between their spheres
    assert pairs == {frozenset(p) for p in (("floor", "ball_sphere"), ("floor", "second_sphere"),
                                             ("floor", "third_sphere"), ("ball_sphere", "third_sphere"),
                                             ("second_sphere", "third_sphere"))}
    skipped = {(s.element, s.name): s.reason for s in conv.report.skipped}
    assert set(skipped) == {("ContactSphere", "unused"), ("ElasticFoundationForce", "foundation")}
    assert "no converted force uses" in skipped[("ContactSphere", "unused")]
    assert "pass through" in skipped[("ElasticFoundationForce", "foundation")]
    d = mujoco.MjData(m)
    for _ in range(500):
        mujoco.mj_step(m, d)
    assert np.isfinite(d.qpos).all()


# -- corpus ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["ToyLanding/ToyLandingModel.osim", "WalkerModel/WalkerModel.osim"])
def test_corpus_models_step(tmp_path, name):
    src = model_file(f"opensim-models/Models/{name}")
    conv = convert(src, tmp_path, FAST)
    assert not any(s.element.startswith("Contact") or s.element == "HuntCrossleyForce" for s in conv.report.skipped)
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    touched = 0
    for _ in range(int(round(1.0 / m.opt.timestep))):
        mujoco.mj_step(m, d)
        touched = max(touched, d.ncon)
    assert m.npair > 0 and touched > 0
    assert np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()
    assert math.isfinite(float(np.max(np.abs(d.qacc))))


# -- SmoothSphereHalfSpaceForce -------------------------------------------------------------------
def _smooth_law(ball: BallModel) -> SmoothHuntCrossley:
    surface = Surface(ball.stiffness, ball.dissipation, ball.static_friction, ball.dynamic_friction,
                      ball.viscous_friction)
    return SmoothHuntCrossley(**vars(HuntCrossley.combine(surface, surface, ball.radius, ball.transition_velocity)),
                              hertz_smoothing=ball.hertz_smoothing,
                              hunt_crossley_smoothing=ball.hunt_crossley_smoothing,
                              constant_contact_force=ball.constant_contact_force)


def test_smooth_law_is_opensims(tmp_path):
    """o2m's smooth law against OpenSim's force, outside the surface (where it already pushes),
    at it and inside, approaching and leaving."""
    osim = runtime.opensim()
    ball = SMOOTH_BALLS[0]
    model = osim.Model(str(write_ball_model(tmp_path / "smooth.osim", ball)))
    force = model.getForceSet().get("contact")
    state = model.initSystem()
    law = _smooth_law(ball)
    labels = [force.getRecordLabels().get(i) for i in range(force.getRecordLabels().size())]
    fx, fy = labels.index("contact.Sphere.force.X"), labels.index("contact.Sphere.force.Y")
    coords = model.getCoordinateSet()
    for x in (-5e-3, -1e-3, 0.0, 1e-3, 4e-3):
        for xdot in (-0.5, 0.0, 0.3):
            for slip in (0.0, 0.01, 0.05, 1.0):
                coords.get("ball_ty").setValue(state, ball.radius - x)
                coords.get("ball_ty").setSpeedValue(state, -xdot)
                coords.get("ball_tx").setSpeedValue(state, slip)
                model.realizeDynamics(state)
                values = force.getRecordValues(state)
                f = float(law.force(x, xdot))
                assert values.get(fy) == pytest.approx(f, rel=1e-9)
                assert values.get(fx) == pytest.approx(-float(law.friction(f, slip)), rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("drop", DROPS)
def test_smooth_drop_within_recorded_errors(smooth_ball, drop):
    ball, osim, conv = smooth_ball
    m = mujoco.MjModel.from_xml_path(str(conv.xml))
    assert m.npair == 1 and not conv.report.skipped
    c = compare_drop(osim, conv.xml, ball, drop)
    assert abs(c.error("peak_penetration")) <= _recorded(conv, FALL_DEEPEST, "SmoothSphereHalfSpaceForce") / 1e3, \
        c.summary()
    assert abs(c.error("restitution")) <= _recorded(conv, IMPACT_RESTITUTION, "SmoothSphereHalfSpaceForce"), \
        c.summary()


def test_smooth_slide_within_recorded_error(smooth_ball):
    """Set down where the smooth law rests (a light ball above the floor, a heavy one in it). The
    report measures MuJoCo against o2m's smooth law; OpenSim's slide is that law's within 0.1 %,
    and MuJoCo is within the recorded error of the law."""
    ball, osim, conv = smooth_ball
    law = _smooth_law(ball)
    c = compare_slide(osim, conv.xml, ball, SLIDE_SPEED, height=ball.radius - law.resting(ball.mass * 9.80665))
    expected = law.slide(ball.mass, SLIDE_SPEED, 9.80665).distance
    assert abs(c.opensim["stop_distance"] / expected - 1) < 1e-3, c.summary()
    recorded = _recorded(conv, SLIDE_DISTANCE, "SmoothSphereHalfSpaceForce") / 100 * expected
    step = mujoco.MjModel.from_xml_path(str(conv.xml)).opt.timestep
    resolution = STOPPED * SLIDE_SPEED * step  # the stop is found to within one MuJoCo step
    assert abs(c.mujoco["stop_distance"] - expected) <= recorded + resolution, c.summary()
