"""Seeded excitation sets follow the paper's specification."""

from __future__ import annotations

import numpy as np
import pytest

from o2m.activations import generate_activations, time_grid

MUSCLES = [f"m{i}" for i in range(50)]


def test_time_grid_is_2ms_over_one_second():
    t = time_grid()
    assert t.shape == (500,)
    assert t[0] == 0.0 and np.allclose(np.diff(t), 0.002) and t[-1] == pytest.approx(0.998)


def test_same_seed_same_sets_and_prefix_stable():
    a = generate_activations(MUSCLES, 10, seed=7)
    b = generate_activations(MUSCLES, 10, seed=7)
    c = generate_activations(MUSCLES, 20, seed=7)
    d = generate_activations(MUSCLES, 10, seed=8)
    assert np.array_equal(a.values, b.values)
    assert np.array_equal(a.values, c.values[:10])  # asking for more sets keeps the first ones
    assert not np.array_equal(a.values, d.values)


def test_values_duty_and_frequency_match_the_specification():
    s = generate_activations(MUSCLES, 400, seed=0)
    assert s.values.shape == (400, 500, 50)
    assert s.values.min() >= 0.0 and s.values.max() <= 1.0
    # inactive muscles are zero throughout; active ones are not
    per_muscle = s.values.transpose(0, 2, 1)  # (sets, muscles, time)
    assert np.all(per_muscle[~s.active] == 0.0)
    assert np.all(per_muscle[s.active].max(axis=-1) > 0.0)
    # each muscle active with probability 1/3: 20000 Bernoulli draws, 5 sigma is about 0.017
    assert abs(s.active.mean() - 1 / 3) < 0.017
    f = s.frequency[s.active]
    assert f.max() <= 1.0 and f.min() > 0.0
    # an active muscle follows A (1 + sin(2 pi f t + phi)) / 2
    i, m = np.argwhere(s.active)[0]
    t = s.times
    expected = s.amplitude[i, m] * 0.5 * (1 + np.sin(2 * np.pi * s.frequency[i, m] * t + s.phase[i, m]))
    assert np.allclose(s.values[i, :, m], expected)
    # slow: the largest change per 2-ms sample is bounded by A * pi * f * dt <= pi * 0.002
    assert np.abs(np.diff(s.values, axis=1)).max() <= np.pi * 0.002 + 1e-12


def test_bad_arguments_raise():
    with pytest.raises(ValueError):
        generate_activations(MUSCLES, -1, seed=0)
    with pytest.raises(ValueError):
        generate_activations(MUSCLES, 1, seed=0, p_active=1.5)
    with pytest.raises(ValueError):
        generate_activations(MUSCLES, 1, seed=0, max_freq=0.0)
