"""MuJoCo's muscle curves as numpy functions, equal to the engine's (``engine_util_misc.c``:
``mju_muscleGainLength``, ``mju_muscleGain``, ``mju_muscleBias``).

Lengths are normalised (1 at the optimal length), velocities in optimal lengths per ``vmax``
seconds; forces are fractions of the peak force unless stated.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["MJMINVAL", "active_force_length", "force_velocity", "integrate_activations", "muscle_activation_rate",
           "mujoco_muscle_force", "normalized_length", "passive_force"]

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


def _sigmoid(x: np.ndarray) -> np.ndarray:
    """mju_sigmoid: quintic smoothstep, 0 below 0, 1 above 1."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (3.0 * x * (2.0 * x - 5.0) + 10.0)


def muscle_activation_rate(ctrl, act, tau_act, tau_deact, tausmooth=0.0) -> np.ndarray:
    """mju_muscleDynamics: d(act)/dt (1/s) for control ``ctrl`` and activation ``act``.

    Time constants in seconds (``dynprm[0:3]``): ``tau_act (0.5 + 1.5 a)`` rising and
    ``tau_deact / (0.5 + 1.5 a)`` falling (``a`` = act clipped to [0, 1]), switched hard, or
    blended by a quintic sigmoid of ``(ctrl - act) / tausmooth`` when ``tausmooth > 0``.
    Arrays broadcast.
    """
    ctrl, act = np.clip(np.asarray(ctrl, float), 0.0, 1.0), np.asarray(act, float)
    a = np.clip(act, 0.0, 1.0)
    t_act = np.asarray(tau_act, float) * (0.5 + 1.5 * a)
    t_deact = np.asarray(tau_deact, float) / (0.5 + 1.5 * a)
    dctrl = ctrl - act
    smooth = np.asarray(tausmooth, float)
    blend = _sigmoid(dctrl / np.maximum(smooth, MJMINVAL) + 0.5)
    tau = np.where(smooth < MJMINVAL, np.where(dctrl > 0, t_act, t_deact), t_deact + (t_act - t_deact) * blend)
    return dctrl / np.maximum(MJMINVAL, tau)


def integrate_activations(controls: np.ndarray, initial: np.ndarray, dynprm: np.ndarray, timestep: float,
                          actrange: tuple[np.ndarray | float, np.ndarray | float] | None = None) -> np.ndarray:
    """Muscle activations as MuJoCo's Euler step integrates them (``actearly`` off).

    Args:
        controls: the control of every step, shape (..., T - 1, M).
        initial: activations at the first sample, shape (..., M).
        dynprm: per muscle (tau_act, tau_deact, tausmooth) in seconds, shape (M, 3) (or broadcastable).
        timestep: seconds; actrange: (low, high) clamp of a limited activation, each a number or
            one per muscle (None: unlimited).
    Returns:
        activations at every sample, shape (..., T, M).
    """
    controls = np.asarray(controls, float)
    prm = np.asarray(dynprm, float)
    out = np.empty(controls.shape[:-2] + (controls.shape[-2] + 1, controls.shape[-1]))
    act = np.asarray(initial, float).copy()
    out[..., 0, :] = act
    for k in range(controls.shape[-2]):
        act = act + timestep * muscle_activation_rate(controls[..., k, :], act, prm[..., 0], prm[..., 1], prm[..., 2])
        if actrange is not None:
            act = np.clip(act, *actrange)
        out[..., k + 1, :] = act
    return out
