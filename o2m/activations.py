"""Random muscle-excitation sets, as in Ikkala & Hämäläinen (2020).

Each set is ``duration`` seconds sampled at ``rate`` Hz. Every muscle is active with
probability ``p_active`` (1/3 in the paper); an active muscle follows a slow sine::

    u(t) = A * (1 + sin(2*pi*f*t + phi)) / 2,   A ~ U(0, 1],  f ~ U(0, max_freq],  phi ~ U(0, 2*pi)

so its values stay in ``[0, A] ⊂ [0, 1]``; an inactive muscle is zero throughout. The values
are muscle excitations (controls): both OpenSim and MuJoCo turn them into activations through
their own first-order activation dynamics.

Everything is drawn from ``numpy.random.default_rng(seed)``, so a seed gives the same sets.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ActivationSets", "generate_activations", "time_grid"]

DURATION = 1.0
"""Length of one set, seconds."""
RATE = 500.0
"""Samples per second (one every 2 ms, MuJoCo's time step)."""
P_ACTIVE = 1.0 / 3.0
"""Probability that a muscle is active in a set."""
MAX_FREQ = 1.0
"""Highest sine frequency, Hz."""


def time_grid(duration: float = DURATION, rate: float = RATE) -> np.ndarray:
    """Sample times ``0, 1/rate, ..., duration - 1/rate``, shape (round(duration*rate),), seconds."""
    n = int(round(duration * rate))
    return np.arange(n) / rate


@dataclass(frozen=True)
class ActivationSets:
    """Excitation sets and the sine parameters that made them.

    Attributes:
        times: sample times, shape (T,), seconds.
        values: excitations, shape (n_sets, T, n_muscles), in [0, 1].
        active: which muscles are active, shape (n_sets, n_muscles), bool.
        amplitude, frequency, phase: sine parameters, shape (n_sets, n_muscles); zero when inactive.
            Amplitude is unitless, frequency in Hz, phase in radians.
        muscles: muscle names, length n_muscles.
        seed: the seed that generated the sets.
    """

    times: np.ndarray
    values: np.ndarray
    active: np.ndarray
    amplitude: np.ndarray
    frequency: np.ndarray
    phase: np.ndarray
    muscles: tuple[str, ...]
    seed: int

    def __len__(self) -> int:
        return self.values.shape[0]


def generate_activations(muscles: list[str] | tuple[str, ...], n_sets: int, *, seed: int,
                         duration: float = DURATION, rate: float = RATE, p_active: float = P_ACTIVE,
                         max_freq: float = MAX_FREQ) -> ActivationSets:
    """Draw ``n_sets`` excitation sets for ``muscles`` (see the module docstring for the law).

    Set ``i`` depends only on ``seed`` and ``i``, not on ``n_sets``: asking for more sets
    extends a dataset without changing the sets already drawn.
    """
    if n_sets < 0:
        raise ValueError(f"n_sets must be >= 0, got {n_sets}")
    if not 0.0 <= p_active <= 1.0:
        raise ValueError(f"p_active must be in [0, 1], got {p_active}")
    if max_freq <= 0:
        raise ValueError(f"max_freq must be > 0 Hz, got {max_freq}")
    t = time_grid(duration, rate)
    m = len(muscles)
    shape = (n_sets, m)
    active = np.zeros(shape, bool)
    amp, freq, phase = np.zeros(shape), np.zeros(shape), np.zeros(shape)
    for i, child in enumerate(np.random.SeedSequence(seed).spawn(n_sets)):
        rng = np.random.default_rng(child)
        on = rng.random(m) < p_active
        # 1 - U[0, 1) lies in (0, 1]: no active muscle with zero amplitude or frequency
        a, f, p = 1.0 - rng.random(m), max_freq * (1.0 - rng.random(m)), 2 * np.pi * rng.random(m)
        active[i], amp[i], freq[i], phase[i] = on, a * on, f * on, p * on
    values = amp[:, None, :] * 0.5 * (1.0 + np.sin(2 * np.pi * freq[:, None, :] * t[None, :, None]
                                                    + phase[:, None, :]))
    values[~np.broadcast_to(active[:, None, :], values.shape)] = 0.0
    return ActivationSets(t, np.clip(values, 0.0, 1.0), active, amp, freq, phase, tuple(muscles), seed)
