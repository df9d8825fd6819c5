"""SmoothSphereHalfSpaceForce's law, and the MuJoCo contact fitted to it.

**The law (Simbody's SmoothSphereHalfSpaceForce).** The Hunt-Crossley law of one surface against
itself (:class:`~o2m.convert.contact_fit.HuntCrossley` with both surfaces equal), made smooth
for gradient-based optimal control:

    f = K (x² + c_f)^(3/4) s(b_d x) (1 + 1.5 c ẋ) s(b_v (ẋ + 2 / (3 c))),   s(u) = (1 + tanh u) / 2,

with ``hertz_smoothing`` b_d (1/m), ``hunt_crossley_smoothing`` b_v (s/m) and
``constant_contact_force`` c_f (m²; OpenSim's name). Far inside the surface it is Hunt-Crossley;
near it, it is not: c_f gives a force at zero penetration (K c_f^(3/4) / 2, 94 N for a 5-cm
sphere of stiffness 1e7) and s(b_d x) lets it push from several millimetres outside, so a light
body rests above the surface and a heavy one in it.

**The MuJoCo contact.** As for Hunt-Crossley (:mod:`o2m.convert.contact_fit`: a spring-damper in
MuJoCo's penalty regime), plus MuJoCo's pair ``margin`` δ (m): the spring acts from δ outside the
surface, f = K (x + δ) + B ẋ. Three numbers are fitted to three of the smooth law's, for the
pair's effective mass m: the restitution of an impact at
:data:`~o2m.convert.contact_fit.REFERENCE_SPEED` (from far outside back to there; sets the
damping ratio), its deepest point, and where the body rests under its weight m g. A margin
cannot be negative: where the fit asks for one, δ = 0 and the spring matches the impact alone
(as for Hunt-Crossley). Friction is Hunt-Crossley's (:func:`~o2m.convert.contact_fit.sliding_friction`).

Units: SI (m, s, kg, N).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cache

import mujoco
import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from o2m.convert.contact_fit import (
    REFERENCE_SPEED,
    SLIDE_SPEED,
    SPEEDS,
    HuntCrossley,
    LinearContact,
    Slide,
    _hertz_slide,
    _linear_impact,
    _mujoco_slide,
    _probe,
    _zeta_for,
    fit_linear,
)

__all__ = ["Fall", "SmoothHuntCrossley", "fit_smooth", "measure_falls", "measure_smooth_slide"]


@dataclass(frozen=True)
class SmoothHuntCrossley(HuntCrossley):
    """Simbody's SmoothSphereHalfSpaceForce law (module docstring); ``stiffness`` K in N/m^1.5 as
    :class:`HuntCrossley`'s."""

    hertz_smoothing: float = 300.0
    hunt_crossley_smoothing: float = 50.0
    constant_contact_force: float = 1e-5

    def unclamped(self, x: float, xdot: float) -> float:
        return float(self.force(x, xdot))

    def force(self, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        """Normal force (N) at penetration ``x`` (m, negative outside) and its rate ``xdot`` (m/s)."""
        x, xdot = np.asarray(x, dtype=float), np.asarray(xdot, dtype=float)
        hertz = self.stiffness * (x * x + self.constant_contact_force) ** 0.75 * 0.5 * (
            1.0 + np.tanh(self.hertz_smoothing * x))
        c = self.dissipation
        gate = 0.5 * (1.0 + np.tanh(self.hunt_crossley_smoothing * (xdot + 2.0 / (3.0 * c)))) if c > 0 else 1.0
        return hertz * (1.0 + 1.5 * c * xdot) * gate

    def friction(self, normal: float, slip: np.ndarray) -> np.ndarray:
        """Friction force (N) at slip speed ``slip`` (m/s) under ``normal`` (N): Hunt-Crossley's at
        the smoothed slip √(v² + c_f), along the slip (so 0 at v = 0)."""
        v = np.abs(np.asarray(slip, dtype=float))
        smoothed = np.sqrt(v * v + self.constant_contact_force)
        return HuntCrossley.friction(self, normal, smoothed) * v / smoothed

    @property
    def reach(self) -> float:
        """How far outside the surface (m) the force is negligible: 10 / b_d (s = 2e-9 there)."""
        return 10.0 / self.hertz_smoothing

    def resting(self, weight: float) -> float:
        """Penetration (m; negative: above the surface) under a static load ``weight`` (N)."""
        top = 10.0 * HuntCrossley.resting(self, weight) + 1e-3
        return float(brentq(lambda x: self.unclamped(x, 0.0) - weight, -self.reach, top, xtol=1e-12))

    def fall(self, mass: float, speed: float, gravity: float = 0.0, start: float | None = None) -> Fall:
        """A body of ``mass`` (kg) arriving at ``speed`` (m/s) from ``start`` (m, default
        :attr:`reach`) outside the surface, under ``gravity`` (m/s²)."""
        return _smooth_fall(self, mass, speed, gravity, self.reach if start is None else max(start, self.reach))

    def slide(self, mass: float, speed: float, gravity: float) -> Slide:
        """As :meth:`HuntCrossley.slide`, set down where the body rests."""
        return _hertz_slide(self, mass, speed, gravity, self.resting(mass * gravity))


@dataclass(frozen=True)
class Fall:
    """One impact from far outside: the deepest penetration (m; negative: the body never touched)
    and the coefficient of restitution (speed back at the start over speed in; 0 if it stays)."""

    deepest: float
    restitution: float


@cache
def _smooth_fall(law: SmoothHuntCrossley, mass: float, speed: float, gravity: float, outside: float) -> Fall:
    start = -outside

    def rhs(t, y):
        return [y[1], gravity - law.unclamped(y[0], y[1]) / mass]

    def back(t, y):
        return y[0] - start
    back.terminal, back.direction = True, -1.0
    t_max = 50.0 * outside / speed + 1.0
    sol = solve_ivp(rhs, (0.0, t_max), [start, speed], events=back, rtol=1e-10, atol=1e-13,
                    max_step=law.reach / speed / 50, dense_output=True)
    t_end = float(sol.t_events[0][0]) if sol.t_events[0].size else t_max
    deepest = float(np.max(sol.sol(np.linspace(0.0, t_end, 4001))[0]))
    return Fall(deepest, float(-sol.y_events[0][0][1]) / speed if sol.t_events[0].size else 0.0)


def fit_smooth(law: SmoothHuntCrossley, mass: float, gravity: float, timestep: float,
               speed: float = REFERENCE_SPEED) -> LinearContact:
    """The spring-damper and margin with the smooth law's restitution, deepest point and resting
    point for ``mass`` (kg) hitting at ``speed`` (m/s) under ``gravity`` (m/s²); see the module."""
    plain = fit_linear(law, mass, gravity, timestep, speed)  # friction; the fallback
    target = law.fall(mass, speed)
    zeta = _zeta_for(max(target.restitution, 0.0))
    p = _linear_impact(zeta).peak  # deepest point of a unit spring-damper impact (units v/ω)
    if gravity <= 0:
        return plain
    rest = law.resting(mass * gravity)
    span = target.deepest - rest  # = v p / ω - g / ω²
    disc = (speed * p) ** 2 - 4.0 * gravity * span
    if span <= 0 or disc < 0:
        return plain
    u = (speed * p - math.sqrt(disc)) / (2.0 * gravity)  # 1 / ω, the root that is v p / span as g -> 0
    margin = gravity * u * u - rest
    if margin <= 0:
        return plain
    omega = 1.0 / u
    return replace(plain, stiffness=mass * omega ** 2, damping=2.0 * zeta * omega * mass, margin=margin)


def _mujoco_fall(model: mujoco.MjModel, speed: float, start: float) -> Fall:
    """The probe arriving at ``speed`` (m/s) from ``start`` (m) outside the surface."""
    data, dt = mujoco.MjData(model), model.opt.timestep
    data.qpos[0], data.qvel[0] = start, -speed
    deepest = -start
    for _ in range(int(20.0 / dt)):
        mujoco.mj_step(model, data)
        deepest = max(deepest, -float(data.qpos[0]))
        if data.qpos[0] >= start and data.qvel[0] > 0:
            return Fall(deepest, float(data.qvel[0]) / speed)
    return Fall(deepest, 0.0)


def measure_falls(law: SmoothHuntCrossley, contact: LinearContact, timestep: float, impedance: tuple[float, ...],
                  gravity: float, speeds: tuple[float, ...] = SPEEDS) -> list[tuple[float, Fall, Fall]]:
    """(speed, smooth law's fall, MuJoCo's fall) at each speed, from where both push nothing."""
    model = _probe(contact, law, timestep, impedance, gravity)
    start = max(law.reach, contact.margin + 1e-3)
    return [(v, law.fall(contact.mass, v, gravity, start), _mujoco_fall(model, v, start)) for v in speeds]


def measure_smooth_slide(law: SmoothHuntCrossley, contact: LinearContact, timestep: float,
                         impedance: tuple[float, ...], gravity: float, speed: float = SLIDE_SPEED
                         ) -> tuple[Slide, Slide]:
    """(smooth law's slide, MuJoCo's slide), both set down where the smooth law rests under ``gravity``."""
    model = _probe(contact, law, timestep, impedance, gravity)
    return law.slide(contact.mass, speed, gravity), _mujoco_slide(model, speed, law.resting(contact.mass * gravity))
