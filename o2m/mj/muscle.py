"""MuJoCo's muscle curves as numpy functions, equal to the engine's (``engine_util_misc.c``:
``mju_muscleGainLength``, ``mju_muscleGain``, ``mju_muscleBias``).

Lengths are normalised (1 at the optimal length), velocities in optimal lengths per ``vmax``
seconds; forces are fractions of the peak force unless stated.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["MJMINVAL", "active_force_length", "force_velocity", "mujoco_muscle_force", "normalized_length",
           "passive_force"]

MJMINVAL = 1e-15
"""MuJoCo's ``mjMINVAL``: the smallest divisor its muscle functions allow."""


def active_force_length(L: np.ndarray, lmin: float, lmax: float) -> np.ndarray:
    """mju_muscleGainLength: piecewise quadratic, 0 outside [lmin, lmax], 1 at L = 1."""
    a = 0.5 * (lmin + 1.0)
    b = 0.5 * (1.0 + lmax)
    x1 = (L - lmin) / max(MJMINVAL, a - lmin)
    x2 = (1.0 - L) / max(MJMINVAL, 1.0 - a)
    x3 = (L - 1.0) / max(MJMINVAL, b - 1.0)
    x4 = (lmax - L) / max(MJMINVAL, lmax - b)
    out = np.where(L <= a, 0.5 * x1 * x1,
                   np.where(L <= 1.0, 1.0 - 0.5 * x2 * x2,
                            np.where(L <= b, 1.0 - 0.5 * x3 * x3, 0.5 * x4 * x4)))
    return np.where((L >= lmin) & (L <= lmax), out, 0.0)


def passive_force(L: np.ndarray, lmax: float, fpmax: float) -> np.ndarray:
    """mju_muscleBias / force: 0 below 1, half-quadratic to (1 + lmax)/2, linear beyond."""
    b = 0.5 * (1.0 + lmax)
    x = (L - 1.0) / max(MJMINVAL, b - 1.0)
    xl = (L - b) / max(MJMINVAL, b - 1.0)
    return np.where(L <= 1.0, 0.0, np.where(L <= b, fpmax * 0.5 * x * x, fpmax * (0.5 + xl)))


def force_velocity(V: np.ndarray, fvmax: float) -> np.ndarray:
    """Force-velocity curve of mju_muscleGain."""
    y = fvmax - 1.0
    return np.where(V <= -1.0, 0.0,
                    np.where(V <= 0.0, (V + 1.0) ** 2,
                             np.where(V <= y, fvmax - (y - V) ** 2 / max(MJMINVAL, y), fvmax)))


def normalized_length(length, lengthrange, rng) -> tuple[np.ndarray, float]:
    L0 = (lengthrange[1] - lengthrange[0]) / max(MJMINVAL, rng[1] - rng[0])
    return rng[0] + (np.asarray(length, dtype=float) - lengthrange[0]) / max(MJMINVAL, L0), L0


def mujoco_muscle_force(params: Any, length, velocity=0.0, activation=1.0):
    """MuJoCo's muscle actuator force (N, negative = pulling) at actuator ``length`` (m),
    ``velocity`` (m/s) and activation state ``activation``: ``gain * act + bias`` exactly as
    ``mju_muscleGain`` and ``mju_muscleBias`` compute them. Arrays broadcast; a scalar in gives
    a float out. ``params`` is a :class:`o2m.convert.muscles.MuscleParams` (or anything with its
    fields: force, lengthrange, range, lmin, lmax, vmax, fvmax, fpmax)."""
    L, L0 = normalized_length(length, params.lengthrange, params.range)
    V = np.asarray(velocity, dtype=float) / max(MJMINVAL, L0 * params.vmax)
    gain = -params.force * active_force_length(L, params.lmin, params.lmax) * force_velocity(V, params.fvmax)
    bias = -params.force * passive_force(L, params.lmax, params.fpmax)
    out = gain * np.asarray(activation, dtype=float) + bias
    return float(out) if np.ndim(out) == 0 else out
