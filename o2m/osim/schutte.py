"""OpenSim's Schutte1993Muscle_Deprecated as arrays: its parameters, its curves, its equations.

The muscle (``Schutte1993Muscle_Deprecated.cpp``) is an elastic tendon in series with a pennated
fibre of constant width; its state is the activation and the fibre length. ``computeActuation``
gives the activation's rate from the excitation (faster up than down), the fibre's velocity from
the force left for it (the tendon's pull along the fibre minus the passive fibre, clamped at
zero) through Schutte's inverse force-velocity relation with damping, and the tendon's pull from
its strain. :class:`SchutteMuscle` holds one muscle, with its curves tabulated on uniform grids
by OpenSim's own ``Function.calcValue`` (what :mod:`o2m.mj.schutte_plugin` gives MuJoCo), and
:meth:`SchutteMuscle.step` is the plugin's time step, for tests and measurements in Python.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from o2m.errors import O2MError
from o2m.osim import runtime

__all__ = ["CurveTable", "SchutteMuscle", "curve_values", "default_states", "muscle_types", "schutte_muscle",
           "schutte_muscles"]

#: Schutte's force-velocity constants (``calcFiberVelocity``).
KV, SLOPE_K, FMAX = 0.15, 0.13, 1.4


@dataclass(frozen=True)
class CurveTable:
    """A curve sampled at ``lo + k * step``, k = 0 .. len(values) - 1, linear in between and
    extrapolated linearly from the end intervals (as the plugin evaluates it)."""

    lo: float
    step: float
    values: np.ndarray

    def __call__(self, x: np.ndarray | float) -> np.ndarray:
        u = (np.asarray(x, float) - self.lo) / self.step
        k = np.clip(np.floor(u).astype(int), 0, len(self.values) - 2)
        return self.values[k] + (u - k) * (self.values[k + 1] - self.values[k])

    def config(self) -> str:
        """The table as the plugin's config text: ``lo step v0 v1 ...``."""
        return " ".join(f"{x:.12g}" for x in (self.lo, self.step, *self.values))


#: Grids: tendon strain (-) and normalized fibre length (-), (lo, hi, points). Linear
#: interpolation on them follows OpenSim's curves to about 1e-5 of max isometric force (up to 2e-4
#: at a curve's corners, as MoBL-ARMS's passive curve has); finer tables cost every new mjData
#: their parsing (MoBL-ARMS's 50 muscles: 115 ms at eight times the points).
STRAIN_GRID = (0.0, 0.1, 1001)
FIBRE_GRID = (0.3, 2.0, 851)


@dataclass(frozen=True)
class SchutteMuscle:
    """One Schutte1993 muscle (lengths m, forces N, times s).

    ``tendon``: normalized tendon force over tendon strain; ``active``, ``passive``: normalized
    active and passive fibre force over normalized fibre length."""

    name: str
    max_isometric_force: float
    optimal_fiber_length: float
    tendon_slack_length: float
    pennation_angle_at_optimal: float
    time_scale: float
    activation1: float
    activation2: float
    damping: float
    tendon: CurveTable
    active: CurveTable
    passive: CurveTable

    def cos_pennation(self, fibre_length: np.ndarray | float) -> np.ndarray:
        """cos of the pennation angle at ``fibre_length`` (m), constant muscle width."""
        s = np.sin(self.pennation_angle_at_optimal) * self.optimal_fiber_length / np.asarray(fibre_length, float)
        return np.sqrt(1.0 - np.minimum(s, 1 - 1e-12) ** 2)

    def tendon_force(self, mtu_length: np.ndarray | float, fibre_length: np.ndarray | float) -> np.ndarray:
        """The tendon's pull (N) of a unit ``mtu_length`` long (m) with fibres ``fibre_length`` long (m)."""
        lf = np.asarray(fibre_length, float)
        strain = (np.asarray(mtu_length, float) - lf * self.cos_pennation(lf)) / self.tendon_slack_length - 1.0
        return self.max_isometric_force * np.where(strain > 0, self.tendon(np.maximum(strain, 0.0)), 0.0)

    def fibre_velocity(self, activation: float, fibre_length: float, mtu_length: float) -> float:
        """The fibre's velocity (m/s), Schutte's inverse force-velocity relation (``calcFiberVelocity``)."""
        x, d = fibre_length / self.optimal_fiber_length, self.damping
        fv = max(float(self.tendon_force(mtu_length, fibre_length)) / self.max_isometric_force
                 / float(self.cos_pennation(fibre_length)) - float(self.passive(x)), 0.0)
        af = activation * max(float(self.active(x)), 0.0)
        if fv < af:
            c, b = KV * (fv - af) / d, -KV * (fv / KV + af + d) / d
            v = (-b - np.sqrt(b * b - 4 * c)) / 2
        else:
            c = -(SLOPE_K * KV / (d * (KV + 1))) * (fv - af)
            b = -(fv / d - FMAX * af / d - SLOPE_K * KV / (KV + 1))
            v = (-b + np.sqrt(b * b - 4 * c)) / 2
        return float(v) * self.optimal_fiber_length / self.time_scale

    def equilibrium(self, activation: float, mtu_length: float) -> float:
        """The fibre length (m) at which the tendon of a unit ``mtu_length`` long (m) pulls as the
        fibres at rest do, ``activation`` times the active curve plus the passive one, along the
        tendon (``computeIsometricForce``'s static equilibrium); the muscle's width where the unit is
        shorter than its tendon's slack length (its fibres then vertical, as OpenSim sets them)."""
        from scipy.optimize import brentq

        width = self.optimal_fiber_length * np.sin(self.pennation_angle_at_optimal)
        slack = mtu_length - self.tendon_slack_length  # along the tendon, fibres at rest
        if slack <= 0.0:
            return float(max(width, 1e-9 * self.optimal_fiber_length))

        def residual(x: float) -> float:
            n = x / self.optimal_fiber_length
            fibre = activation * max(float(self.active(n)), 0.0) + float(self.passive(n))
            cos = float(self.cos_pennation(x))
            return float(self.tendon_force(mtu_length, x)) - self.max_isometric_force * fibre * cos

        # the tendon is slack where the fibres span the rest, and stretched as they shorten from
        # there; fibres that pull nothing there (a passive curve at or below zero) rest there
        hi = float(np.hypot(slack, width))
        if residual(hi) >= 0.0:
            return hi
        lo = max(width, 1e-6 * self.optimal_fiber_length)
        while residual(lo) < 0.0 and lo > 1e-12:
            lo /= 2.0
        return float(brentq(residual, lo, hi, xtol=1e-15, rtol=1e-14)) if residual(lo) > 0.0 else hi

    def step(self, activation: float, fibre_length: float, excitation: float, mtu_length_end: float,
             timestep: float) -> tuple[float, float]:
        """The state (activation, fibre length m) one ``timestep`` (s) later, as the plugin steps it:
        the activation exactly for a constant ``excitation``, the fibre by backward Euler at the
        muscle-tendon length the step ends at (m)."""
        e = min(max(excitation, 0.0), 1.0)
        rate = (self.activation1 * e + self.activation2 if e >= activation else self.activation2) / self.time_scale
        a = e + (activation - e) * np.exp(-rate * timestep)

        def residual(x: float) -> float:
            return x - fibre_length - timestep * self.fibre_velocity(a, x, mtu_length_end)

        from scipy.optimize import brentq

        g0 = residual(fibre_length)
        if g0 == 0:
            return float(a), fibre_length
        width, sign = abs(g0) + 1e-9 * self.optimal_fiber_length, -np.sign(g0)
        while np.sign(residual(fibre_length + sign * width)) == np.sign(g0):
            width *= 2
        lo, hi = sorted((fibre_length, fibre_length + sign * width))
        return float(a), float(brentq(residual, lo, hi, xtol=1e-15, rtol=1e-14))


def schutte_muscle(model, name: str, osim_path: str | os.PathLike[str]):
    """The OpenSim muscle ``name`` of ``model`` (loaded from ``osim_path``); :class:`O2MError` unless
    it is a Schutte1993Muscle_Deprecated."""
    muscle = model.getMuscles().get(name)
    if muscle.getConcreteClassName() != "Schutte1993Muscle_Deprecated":
        raise O2MError(f"{osim_path}: muscle '{name}' is a {muscle.getConcreteClassName()}, not a "
                       "Schutte1993Muscle_Deprecated")
    return muscle


def curve_values(muscle, prop: str, xs: np.ndarray) -> np.ndarray:
    """The Schutte muscle's curve ``prop`` (e.g. ``"tendon_force_length_curve"``) at ``xs``, by
    OpenSim's own ``Function.calcValue``; the passive curve left at its default is Schutte's
    exponential (``calcNonzeroPassiveForce``)."""
    osim = runtime.opensim()
    p = muscle.getPropertyByName(prop)
    if prop == "passive_force_length_curve" and p.getValueIsDefault():
        return np.exp(8.0 * (xs - 1.0)) / np.exp(4.0)
    fn = osim.Function.safeDownCast(p.getValueAsObject())
    return np.array([fn.calcValue(osim.Vector(1, float(x))) for x in xs])


def schutte_muscles(osim_path: str | os.PathLike[str], names: list[str]) -> dict[str, SchutteMuscle]:
    """:class:`SchutteMuscle` of each muscle ``names`` of the model (each a Schutte1993Muscle_Deprecated)."""
    osim = runtime.opensim()
    model = osim.Model(str(osim_path))
    out = {}
    for name in names:
        muscle = schutte_muscle(model, name, osim_path)

        def number(prop: str, muscle=muscle) -> float:
            return osim.PropertyHelper.getValueDouble(muscle.getPropertyByName(prop))

        def table(prop: str, grid: tuple[float, float, int], muscle=muscle) -> CurveTable:
            xs = np.linspace(*grid)
            return CurveTable(float(xs[0]), float(xs[1] - xs[0]), curve_values(muscle, prop, xs))

        out[name] = SchutteMuscle(
            name, muscle.getMaxIsometricForce(), muscle.getOptimalFiberLength(), muscle.getTendonSlackLength(),
            muscle.getPennationAngleAtOptimalFiberLength(), number("time_scale"), number("activation1"),
            number("activation2"), number("damping"), table("tendon_force_length_curve", STRAIN_GRID),
            table("active_force_length_curve", FIBRE_GRID), table("passive_force_length_curve", FIBRE_GRID))
    return out


def default_states(osim_path: str | os.PathLike[str], names: list[str]) -> dict[str, tuple[float, float, float]]:
    """``{muscle: (activation, fibre length m, muscle-tendon length m)}`` in the model's default
    state with its muscles in equilibrium (``equilibrateMuscles``), as OpenSim starts a
    simulation of it."""
    osim = runtime.opensim()
    model = osim.Model(str(osim_path))
    state = model.initSystem()
    model.equilibrateMuscles(state)
    muscles = model.getMuscles()
    return {n: (float(muscles.get(n).getActivation(state)), float(muscles.get(n).getFiberLength(state)),
                float(muscles.get(n).getLength(state))) for n in names}


def muscle_types(osim_path: str | os.PathLike[str]) -> dict[str, str]:
    """``{muscle: OpenSim class}`` of every muscle of the model, in its force set's order."""
    osim = runtime.opensim()
    model = osim.Model(str(osim_path))  # kept alive: the muscle set is a view into it
    muscles = model.getMuscles()
    return {muscles.get(i).getName(): muscles.get(i).getConcreteClassName() for i in range(muscles.getSize())}
