"""Simbody's Hunt-Crossley contact law, and the linear MuJoCo contact fitted to it.

**Hunt-Crossley (Simbody, what OpenSim's HuntCrossleyForce applies).** Each surface i has a
stiffness k_i (what OpenSim's ContactParameters call ``stiffness``, Pa-like: N/m²), a dissipation
c_i (s/m) and friction coefficients. Simbody stores k̃_i = k_i^(2/3) and, for a contact between
surfaces 1 and 2 with penetration x (m) and penetration rate ẋ (m/s), applies the normal force

    f = (4/3) k̃^(3/2) √R x^(3/2) (1 + 1.5 c ẋ),   clamped at 0 (no pull),
    k̃ = k̃_1 k̃_2 / (k̃_1 + k̃_2),   c = (c_1 k̃_2 + c_2 k̃_1) / (k̃_1 + k̃_2),

with R the effective radius of curvature (a sphere on a half space: its radius; two spheres:
R_1 R_2 / (R_1 + R_2)). Friction opposes the slip velocity v (m/s) with
f · [min(v/v_t, 1) (μ_d + 2(μ_s - μ_d) / (1 + (v/v_t)²)) + μ_v v], each μ the harmonic mean
2 μ_1 μ_2 / (μ_1 + μ_2) of the two surfaces' (0 when either is 0), v_t the force's
``transition_velocity``.

**The MuJoCo contact.** MuJoCo's soft contact is linear in penetration and velocity, so no choice
of ``solref`` reproduces x^(3/2). o2m puts MuJoCo's contact in its penalty regime (impedance
``solimp`` = :data:`IMPEDANCE` = 1e-4, MuJoCo's smallest): the contact force is then the
spring-damper f = K x + B ẋ, clamped at 0, with K = -solref[0] / w and B = -solref[1] / w, w the
two bodies' ``body_invweight0`` (MuJoCo's mass scale of the contact, fixed at the default pose),
plus 1e-4 of the load MuJoCo's constraint would otherwise carry. K and B are fitted so that the
pair's effective mass m (1 / n·J M⁻¹ Jᵀ·n along the contact normal at the default pose) hitting
the surface at :data:`REFERENCE_SPEED` reaches Hunt-Crossley's peak penetration and leaves with
its coefficient of restitution. Why an impact and not the static load: landing, walking and
kicking models are about impacts, and the spring that rests at Hunt-Crossley's penetration under
the weight m g is 2.3 times softer (the 1-kg ball of ``benchmarks/contact.py``: 1.8 times the
peak penetration at 1 m/s). Why linear: a penetration-dependent impedance (``solimp`` width and
power) bends MuJoCo's spring towards x^(3/2), but scales its damping with the square root of its
stiffness, so the damping ratio, and with it the restitution, is the same at every speed
(fitted over 0.5-4 m/s it brought peak penetration within -9..+19 % but left the restitution
as it was and lengthened slow contacts by 40 %). What the fit cannot keep: peak penetration
grows as v^(4/5) under Hunt-Crossley and as v here, contact lasts as v^(-1/5) there and
constantly here, and Hunt-Crossley's restitution falls with impact speed while the
spring-damper's does not; the conversion report measures these errors at several impact speeds
(:func:`measure_impacts`).

**Friction.** MuJoCo's elliptic cone has one Coulomb coefficient where Hunt-Crossley's μ(v)
varies with the slip speed (rising from 0 to μ_s at v_t, falling to μ_d, and growing by μ_v v).
o2m takes the μ that stops a body sliding from :data:`SLIDE_SPEED` in Hunt-Crossley's distance
(:func:`sliding_friction`, a mean of μ(v) over the slide); with large viscous friction
(ToyLanding's μ_v = 0.6 s/m) that is well above μ_d. Below the cone, MuJoCo's friction (in the
penalty regime) is viscous, f = b v with b the ``solreffriction`` damping; o2m sets b = m̃ g
(2μ_s - μ_d) / v_t, Hunt-Crossley's slope at v = 0 for a normal force m̃ g, capped at m̃ /
timestep (a higher slope stops the slip within one step and would make MuJoCo's explicit friction
unstable). Not kept: how μ(v) varies over a slide (slower slides see a different mean).

Units: SI (m, s, kg, N).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import mujoco
import numpy as np
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq

__all__ = ["IMPEDANCE", "REFERENCE_SPEED", "SLIDE_SPEED", "SPEEDS", "STOPPED", "HuntCrossley", "Impact",
           "LinearContact", "Slide", "Surface", "fit_linear", "measure_impacts", "measure_slide", "sliding_friction"]

#: Impact speed (m/s) at which the MuJoCo contact matches Hunt-Crossley's peak penetration and
#: restitution: a foot strike in walking or a small landing.
REFERENCE_SPEED = 1.0
#: MuJoCo's smallest impedance (mjMINIMP): the contact is a spring-damper on the effective mass.
IMPEDANCE = 1e-4
#: Impact speeds (m/s) at which the conversion measures the fitted contact.
SPEEDS = (0.5, 1.0, 2.0, 4.0)
#: Slip speed (m/s) of the slide the conversion measures friction with.
SLIDE_SPEED = 2.0
#: A slide has stopped when its speed falls below this fraction of the start.
STOPPED = 0.01
#: Largest zeta the fit tries (over-damped far beyond any OpenSim dissipation in use).
_MAX_ZETA = 20.0


@dataclass(frozen=True)
class Surface:
    """One OpenSim ContactParameters: stiffness (N/m²), dissipation (s/m), friction coefficients."""

    stiffness: float
    dissipation: float
    static_friction: float
    dynamic_friction: float
    viscous_friction: float  # s/m


def _harmonic(a: float, b: float) -> float:
    """Simbody's combination of two friction coefficients: 2ab / (a + b), 0 when both are 0."""
    return 0.0 if a == 0.0 and b == 0.0 else 2.0 * a * b / (a + b)


@dataclass(frozen=True)
class HuntCrossley:
    """Simbody's Hunt-Crossley law for one pair of surfaces: f = K x^1.5 (1 + 1.5 c ẋ).

    ``stiffness`` K in N/m^1.5, ``dissipation`` c in s/m, ``transition_velocity`` in m/s."""

    stiffness: float
    dissipation: float
    static_friction: float
    dynamic_friction: float
    viscous_friction: float
    transition_velocity: float

    @classmethod
    def combine(cls, a: Surface, b: Surface, radius: float, transition_velocity: float) -> HuntCrossley:
        """The law between surfaces ``a`` and ``b`` with effective radius ``radius`` (m)."""
        ka, kb = a.stiffness ** (2.0 / 3.0), b.stiffness ** (2.0 / 3.0)
        k = ka * kb / (ka + kb)
        c = (a.dissipation * kb + b.dissipation * ka) / (ka + kb)
        return cls(4.0 / 3.0 * k ** 1.5 * math.sqrt(radius), c,
                   _harmonic(a.static_friction, b.static_friction), _harmonic(a.dynamic_friction, b.dynamic_friction),
                   _harmonic(a.viscous_friction, b.viscous_friction), transition_velocity)

    def force(self, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        """Normal force (N) at penetration ``x`` (m) and penetration rate ``xdot`` (m/s)."""
        x = np.maximum(np.asarray(x, dtype=float), 0.0)
        return np.maximum(self.stiffness * x ** 1.5 * (1.0 + 1.5 * self.dissipation * np.asarray(xdot)), 0.0)

    def unclamped(self, x: float, xdot: float) -> float:
        """Simbody's normal force (N) before the clamp at 0, which its friction scales with."""
        return self.stiffness * x ** 1.5 * (1.0 + 1.5 * self.dissipation * xdot) if x > 0 else 0.0

    def friction(self, normal: float, slip: np.ndarray) -> np.ndarray:
        """Friction force (N) at slip speed ``slip`` (m/s, >= 0) under normal force ``normal`` (N)."""
        v = np.asarray(slip, dtype=float)
        r = v / self.transition_velocity
        mu = np.minimum(r, 1.0) * (self.dynamic_friction + 2 * (self.static_friction - self.dynamic_friction)
                                   / (1 + r * r)) + self.viscous_friction * v
        return normal * mu

    def length_scale(self, mass: float, speed: float) -> float:
        """(m v² / K)^(2/5) (m): the penetration scale of an impact."""
        return (mass * speed * speed / self.stiffness) ** 0.4

    def impact(self, mass: float, speed: float, gravity: float = 0.0) -> Impact:
        """A body of ``mass`` (kg) hitting the surface at ``speed`` (m/s) under ``gravity`` (m/s²,
        towards the surface)."""
        x0 = self.length_scale(mass, speed)
        unit = _hertz_impact(round(self.dissipation * speed, 12), round(gravity * x0 / speed ** 2, 12))
        return Impact(unit.peak * x0, unit.restitution, unit.duration * x0 / speed)

    def resting(self, weight: float) -> float:
        """Penetration (m) under a static load ``weight`` (N)."""
        return (weight / self.stiffness) ** (2.0 / 3.0)

    def slide(self, mass: float, speed: float, gravity: float) -> Slide:
        """A body of ``mass`` (kg) set down touching the surface under ``gravity`` (m/s²) and
        sliding at ``speed`` (m/s): where and when its speed falls below :data:`STOPPED` of the start."""
        return _hertz_slide(self, mass, speed, gravity)


@dataclass(frozen=True)
class Slide:
    """One slide: distance (m) and time (s) until the speed falls below :data:`STOPPED` of the start."""

    distance: float
    time: float


@dataclass(frozen=True)
class Impact:
    """One impact: peak penetration (m), coefficient of restitution, contact duration (s). A body
    that stays on the surface (gravity holding it) has restitution 0 and duration ``inf``."""

    peak: float
    restitution: float
    duration: float

    @property
    def stays(self) -> bool:
        """Whether the body never left the surface."""
        return math.isinf(self.duration)


def _touchdown(t: float, y: np.ndarray) -> float:
    return y[0]


_touchdown.terminal = True
_touchdown.direction = -1.0


def _integrate(rhs, t_max: float) -> Impact:
    """The impact from touch-down at unit speed until the body leaves the surface; one that has not
    left by ``t_max`` stays on it (:attr:`Impact.stays`): under gravity a dissipative contact can
    take all of the rebound's energy, so the body settles at its resting penetration."""
    sol = solve_ivp(rhs, (0.0, t_max), [0.0, 1.0], events=_touchdown, rtol=1e-10, atol=1e-13, max_step=t_max / 400,
                    dense_output=True)
    left = bool(sol.t_events[0].size)
    t_end = float(sol.t_events[0][0]) if left else float(sol.t[-1])
    t = np.linspace(0.0, t_end, 2001)
    peak = float(np.max(sol.sol(t)[0]))
    if not left:
        return Impact(peak, 0.0, math.inf)
    return Impact(peak, float(-sol.y_events[0][0][1]), t_end)


@cache
def _hertz_impact(gamma: float, weight: float = 0.0) -> Impact:
    """Hunt-Crossley impact in units x0 = (m v²/K)^(2/5), t0 = x0/v:
    x'' = G - x^1.5 (1 + 1.5 γ x'), γ = c v, G = g x0 / v² (gravity)."""
    def rhs(t, y):
        x, v = y
        return [v, weight - max(max(x, 0.0) ** 1.5 * (1.0 + 1.5 * gamma * v), 0.0)]
    return _integrate(rhs, 40.0)


@cache
def _hertz_slide(law: HuntCrossley, mass: float, speed: float, gravity: float, start: float = 0.0) -> Slide:
    """Normal (penetration z, from ``start`` m) and sliding (x) motion under Simbody's law;
    Simbody's friction scales with the unclamped normal force f."""
    def rhs(t, y):
        z, zd, x, xd = y
        f = law.unclamped(z, zd)
        return [zd, gravity - max(f, 0.0) / mass, xd, -float(law.friction(f, abs(xd))) * np.sign(xd) / mass]

    def stopped(t, y):
        return y[3] - STOPPED * speed
    stopped.terminal, stopped.direction = True, -1.0
    t_max = 10.0 * speed / (max(law.dynamic_friction, 1e-3) * gravity) + 1.0
    sol = solve_ivp(rhs, (0.0, t_max), [start, 0.0, 0.0, speed], events=stopped, rtol=1e-9, atol=1e-12,
                    max_step=1e-3)
    if not sol.t_events[0].size:
        return Slide(math.inf, math.inf)
    return Slide(float(sol.y_events[0][0][2]), float(sol.t_events[0][0]))


@cache
def _linear_impact(zeta: float) -> Impact:
    """Spring-damper impact in units v/ω, 1/ω: x'' = -max(x + 2ζ x', 0) while x > 0."""
    def rhs(t, y):
        x, v = y
        return [v, -max(x + 2.0 * zeta * v, 0.0)]
    return _integrate(rhs, 40.0 + 40.0 * zeta)


@dataclass(frozen=True)
class LinearContact:
    """The MuJoCo contact as a spring-damper: ``stiffness`` (N/m), ``damping`` (N s/m), fitted for
    a body of effective mass ``mass`` (kg); ``friction`` the Coulomb coefficient and
    ``friction_damping`` (N s/m) MuJoCo's friction below the cone."""

    stiffness: float
    damping: float
    mass: float
    friction_damping: float
    friction: float  # MuJoCo's (Coulomb) friction coefficient
    margin: float = 0.0  # m: the spring acts from this far outside the surface (MuJoCo's pair margin)

    @property
    def omega(self) -> float:
        """Natural frequency (rad/s) on the effective mass."""
        return math.sqrt(self.stiffness / self.mass)

    def solref(self, inverse_weight: float) -> tuple[float, float]:
        """MuJoCo's ``solref`` (-stiffness, -damping) in its units: MuJoCo scales both by the
        contact's ``inverse_weight`` (1/kg, the bodies' ``body_invweight0`` summed)."""
        return (-self.stiffness * inverse_weight, -self.damping * inverse_weight)

    def solreffriction(self, inverse_weight: float) -> tuple[float, float]:
        return (0.0, -self.friction_damping * inverse_weight)


def fit_linear(law: HuntCrossley, mass: float, gravity: float, timestep: float,
               speed: float = REFERENCE_SPEED) -> LinearContact:
    """The spring-damper with Hunt-Crossley's peak penetration and restitution for ``mass`` (kg)
    hitting at ``speed`` (m/s); its friction damping is Hunt-Crossley's friction slope at slip 0
    under the weight ``mass`` x ``gravity`` (m/s²), capped at ``mass`` / ``timestep`` (s)."""
    target = law.impact(mass, speed)
    zeta = _zeta_for(target.restitution)
    omega = _linear_impact(zeta).peak * speed / target.peak
    slope = gravity * max(2.0 * law.static_friction - law.dynamic_friction, 0.0) / law.transition_velocity
    return LinearContact(mass * omega ** 2, 2.0 * zeta * omega * mass, mass, mass * min(slope, 1.0 / timestep),
                         sliding_friction(law))


def sliding_friction(law: HuntCrossley, speed: float = SLIDE_SPEED) -> float:
    """The Coulomb coefficient that stops a body sliding at ``speed`` (m/s) where Hunt-Crossley's
    μ(v) does, both under a constant normal force: (v0² - v1²) / (2 ∫ v / μ(v) dv) from v1 =
    :data:`STOPPED` v0 to v0 (0 without friction)."""
    if law.static_friction == law.dynamic_friction == law.viscous_friction == 0.0:
        return 0.0
    def slowness(v: float) -> float:
        mu = float(law.friction(1.0, v))
        return v / mu if mu > 0 else math.inf
    v1 = STOPPED * speed
    integral = quad(slowness, v1, speed, points=[law.transition_velocity] if v1 < law.transition_velocity < speed
                    else None, limit=200)[0]
    return (speed ** 2 - v1 ** 2) / (2.0 * integral) if math.isfinite(integral) and integral > 0 else 0.0


def _zeta_for(restitution: float) -> float:
    """The damping ratio whose clamped spring-damper impact has this coefficient of restitution."""
    if restitution >= 1.0 - 1e-12:
        return 0.0
    lo, hi = 0.0, _MAX_ZETA
    if _linear_impact(hi).restitution > restitution:
        return hi
    return float(brentq(lambda z: _linear_impact(round(z, 12)).restitution - restitution, lo, hi, xtol=1e-10))


# -- measuring the MuJoCo contact ------------------------------------------------------------------
def _probe(contact: LinearContact, law: HuntCrossley, timestep: float, impedance: tuple[float, ...],
           gravity: float) -> mujoco.MjModel:
    """A body of the contact's effective mass on a vertical and a horizontal slide over a plane,
    with the pair's MuJoCo contact (the vertical slide is joint 0)."""
    spec = mujoco.MjSpec()
    spec.option.timestep = timestep
    spec.option.gravity = [0.0, 0.0, -gravity]
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.worldbody.add_geom(name="plane", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], contype=0,
                            conaffinity=0)
    body = spec.worldbody.add_body(name="probe", pos=[0, 0, 0.1])
    body.add_joint(type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1])
    body.add_joint(type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1, 0, 0])
    body.mass, body.inertia = contact.mass, [contact.mass * 1e-3] * 3
    body.explicitinertial = True
    body.add_geom(name="sphere", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.1, 0, 0], contype=0, conaffinity=0)
    mu = max(contact.friction, 1e-5)
    pair = spec.add_pair(geomname1="plane", geomname2="sphere", condim=3 if contact.friction > 0 else 1,
                         friction=[mu, mu, 0.005, 0.0001, 0.0001], solimp=list(impedance), margin=contact.margin)
    model = spec.compile()
    weight = float(model.body_invweight0[1, 0])
    pair.solref, pair.solreffriction = list(contact.solref(weight)), list(contact.solreffriction(weight))
    return spec.compile()


#: Steps after which a MuJoCo probe still on the surface stays there, and the speed (a fraction of
#: the impact's) below which it has settled once it has stayed that slow for _REST_STEPS steps.
_MAX_PROBE_STEPS = 200000
_REST_SPEED = 1e-6
_REST_STEPS = 1000


def _mujoco_impact(model: mujoco.MjModel, speed: float) -> Impact:
    """Land the probe at ``speed`` (m/s), starting half a step above the surface; a probe that
    settles on it instead of leaving stays (:attr:`Impact.stays`)."""
    data, dt = mujoco.MjData(model), model.opt.timestep
    h0 = 0.5 * speed * dt
    data.qpos[0], data.qvel[0] = h0, -math.sqrt(max(speed ** 2 + 2 * model.opt.gravity[2] * h0, 0.0))
    x_prev, peak, t_in, still = -0.5 * speed * dt, 0.0, None, 0
    for i in range(1, _MAX_PROBE_STEPS + 1):
        mujoco.mj_step(model, data)
        x = -float(data.qpos[0])  # penetration (m)
        if t_in is None and x > 0.0:
            t_in = (i - 1 + -x_prev / (x - x_prev)) * dt
        if t_in is not None:
            peak = max(peak, x)
            if x <= 0.0:
                t_out = (i - 1 + x_prev / (x_prev - x)) * dt
                return Impact(peak, float(data.qvel[0]) / speed, t_out - t_in)
            still = still + 1 if abs(float(data.qvel[0])) < _REST_SPEED * speed else 0
            if still >= _REST_STEPS:
                break  # settled on the surface (gravity holds it)
        x_prev = x
    return Impact(peak, 0.0, math.inf)


def measure_impacts(law: HuntCrossley, contact: LinearContact, timestep: float, impedance: tuple[float, ...],
                    gravity: float, speeds: tuple[float, ...] = SPEEDS) -> list[tuple[float, Impact, Impact]]:
    """(speed, Hunt-Crossley impact, MuJoCo impact) at each speed: a body of the contact's
    effective mass falling onto the surface under ``gravity`` (m/s²), in MuJoCo at ``timestep`` (s)."""
    model = _probe(contact, law, timestep, impedance, gravity)
    return [(v, law.impact(contact.mass, v, gravity), _mujoco_impact(model, v)) for v in speeds]


def _mujoco_slide(model: mujoco.MjModel, speed: float, penetration: float = 0.0) -> Slide:
    """Slide the probe from ``speed`` (m/s), set down at ``penetration`` (m)."""
    data, dt = mujoco.MjData(model), model.opt.timestep
    data.qpos[0], data.qvel[1] = -penetration, speed
    for i in range(1, int(60.0 / dt)):
        mujoco.mj_step(model, data)
        if data.qvel[1] < STOPPED * speed:
            return Slide(float(data.qpos[1]), i * dt)
    return Slide(math.inf, math.inf)


def measure_slide(law: HuntCrossley, contact: LinearContact, timestep: float, impedance: tuple[float, ...],
                  gravity: float, speed: float = SLIDE_SPEED) -> tuple[Slide, Slide]:
    """(Hunt-Crossley slide, MuJoCo slide): a body of the contact's effective mass set down touching
    the surface under ``gravity`` (m/s²) and sliding at ``speed`` (m/s), MuJoCo at ``timestep`` (s)."""
    return law.slide(contact.mass, speed, gravity), _mujoco_slide(_probe(contact, law, timestep, impedance, gravity),
                                                                  speed)
