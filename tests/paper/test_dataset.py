"""The dataset's split: the paper's 78 training and 19 test sets, seeded, from successful runs only."""

from __future__ import annotations

import numpy as np

from o2m.paper.dataset import PAPER_SPLIT, load_dataset, make_split


def test_split_of_100_successes_is_the_papers_with_the_rest_for_validation():
    train, test, validation = make_split(np.ones(100, bool), seed=2020)
    assert (len(train), len(test), len(validation)) == (*PAPER_SPLIT, 3)
    assert not set(train) & set(test) and not set(train) & set(validation) and not set(test) & set(validation)
    assert sorted(train + test + validation) == list(range(100))
    assert make_split(np.ones(100, bool), seed=2020) == (train, test, validation)
    assert make_split(np.ones(100, bool), seed=1)[1] != test


def test_failed_runs_are_in_no_split_and_fewer_successes_shrink_it_in_proportion():
    ok = np.ones(100, bool)
    ok[[3, 17, 40, 41, 42, 60, 61, 62, 63, 90]] = False  # 90 successes, fewer than 78 + 19
    train, test, validation = make_split(ok, seed=0)
    assert not set(np.flatnonzero(~ok)) & set(train + test + validation)
    assert len(test) == round(90 * 19 / 97) and len(train) == 90 - len(test) and validation == []


def test_stored_dataset_has_finite_tendon_forces_for_every_successful_run():
    ds = load_dataset("data/mobl_arms")
    assert ds.tendon_forces.shape == ds.opensim_activations.shape
    assert np.isfinite(ds.tendon_forces[ds.ok]).all()
    assert (ds.tendon_forces[ds.ok] > -1.0).all()  # muscles pull (float16 rounding aside)
    assert (len(ds.train), len(ds.test)) == PAPER_SPLIT
