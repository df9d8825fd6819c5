"""OpenSim's Schutte1993 muscle at zero activation, as arrays: a passive fibre that only lengthens.

``Schutte1993Muscle_Deprecated::computeActuation`` clamps the force left for the fibre's
velocity, ``tendon force / cos(pennation) - passive force``, at zero, and with no active force
``calcFiberVelocity`` then gives a fibre velocity of exactly zero. So a muscle whose activation is
zero can lengthen its fibres (the tendon pulling harder than the passive fibre) but never shorten
them: when its muscle-tendon unit shortens after a stretch, the fibres stay long and the stiff
tendon goes slack within millimetres, where a rigid-tendon muscle (MuJoCo's) keeps its static
passive force. :class:`PassiveFibre` reproduces that, quasi-statically (the fibre lengthening to
equilibrium at once: Schutte's fibre damping is small), from OpenSim's own curves, tabulated
with OpenSim's ``Function.calcValue``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from o2m.osim import runtime
from o2m.osim.schutte import curve_values, schutte_muscle

__all__ = ["PassiveFibre", "passive_fibres"]

#: Grids of the tabulated curves: tendon strain (-), normalized fibre length (-).
STRAIN_GRID = np.linspace(0.0, 0.05, 2001)
FIBRE_GRID = np.linspace(0.3, 2.0, 3401)


@dataclass(frozen=True)
class PassiveFibre:
    """One Schutte1993 muscle at zero activation (lengths m, forces N).

    ``tendon``: the normalized tendon force at :data:`STRAIN_GRID`; ``passive``: the normalized
    passive fibre force at :data:`FIBRE_GRID` (OpenSim's curves, or Schutte's exponential where
    the model keeps the default)."""

    name: str
    max_isometric_force: float
    optimal_fiber_length: float
    tendon_slack_length: float
    sin_pennation_at_optimal: float
    tendon: np.ndarray
    passive: np.ndarray

    @property
    def strains(self) -> np.ndarray:
        """The tendon strains (-) ``tendon`` is tabulated at (:data:`STRAIN_GRID`)."""
        return STRAIN_GRID

    def cos_pennation(self, fibre_length: np.ndarray | float) -> np.ndarray:
        """cos of the pennation angle at ``fibre_length`` (m), constant muscle width."""
        s = np.minimum(self.sin_pennation_at_optimal * self.optimal_fiber_length / np.asarray(fibre_length), 1.0)
        return np.sqrt(1.0 - s**2)

    def tendon_force(self, mtu_length: np.ndarray | float, fibre_length: np.ndarray | float) -> np.ndarray:
        """Tendon force (N) of the unit ``mtu_length`` long (m) with fibres ``fibre_length`` long (m)."""
        lf = np.asarray(fibre_length, float)
        strain = (np.asarray(mtu_length) - lf * self.cos_pennation(lf)) / self.tendon_slack_length - 1.0
        return self.max_isometric_force * np.where(strain > 0, np.interp(strain, STRAIN_GRID, self.tendon), 0.0)

    def passive_force(self, fibre_length: np.ndarray | float) -> np.ndarray:
        """Passive fibre force (N) at ``fibre_length`` (m), along the fibre."""
        x = np.asarray(fibre_length) / self.optimal_fiber_length
        return self.max_isometric_force * np.interp(x, FIBRE_GRID, self.passive)

    def equilibrium(self, mtu_length: np.ndarray | float, iterations: int = 60) -> np.ndarray:
        """Fibre length (m) where the tendon and the passive fibre pull alike (``equilibrateMuscles``
        at zero activation), by bisection: the tendon's pull falls and the fibre's rises with it."""
        L = np.asarray(mtu_length, float)
        lo = np.full(L.shape, FIBRE_GRID[0] * self.optimal_fiber_length)
        hi = np.full(L.shape, FIBRE_GRID[-1] * self.optimal_fiber_length)
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            pulls = self.tendon_force(L, mid) / self.cos_pennation(mid) > self.passive_force(mid)
            lo, hi = np.where(pulls, mid, lo), np.where(pulls, hi, mid)
        return 0.5 * (lo + hi)

    def ratchet(self, mtu_length: np.ndarray | float, fibre_length: np.ndarray | float) -> np.ndarray:
        """The fibre length (m) after the unit moves to ``mtu_length``: lengthened to equilibrium
        if the tendon pulls it there, else unchanged (it cannot shorten at zero activation)."""
        return np.maximum(np.asarray(fibre_length, float), self.equilibrium(mtu_length))


def passive_fibres(osim_path: str | os.PathLike[str], names: list[str]) -> dict[str, PassiveFibre]:
    """:class:`PassiveFibre` of each muscle ``names`` of the model (all Schutte1993Muscle_Deprecated)."""
    osim = runtime.opensim()
    model = osim.Model(str(osim_path))
    out = {}
    for name in names:
        muscle = schutte_muscle(model, name, osim_path)
        out[name] = PassiveFibre(
            name, muscle.getMaxIsometricForce(), muscle.getOptimalFiberLength(), muscle.getTendonSlackLength(),
            float(np.sin(muscle.getPennationAngleAtOptimalFiberLength())),
            curve_values(muscle, "tendon_force_length_curve", STRAIN_GRID),
            curve_values(muscle, "passive_force_length_curve", FIBRE_GRID))
    return out
