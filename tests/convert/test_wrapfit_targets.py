"""The wrap fit's moment-arm targets (o2m.convert.drawn_arms): the moment arm of the path OpenSim draws.

Two models built here:

* two ground cylinders on one segment of a two-link arm (tests/convert/test_wrapping.py): OpenSim's
  ``getLength`` keeps an arc length from an earlier wrap iteration (568 mm where its drawn path is
  597 mm at q1 = q2 = -0.5), so its ``-dL/dq`` is about 20 mm from ``computeMomentArm``, which is
  the drawn path's ``-dL/dq`` to 1-4 mm: the target is ``computeMomentArm``;
* a MovingPathPoint next to a point of its own body (tests/convert/test_path_forces.py): OpenSim
  applies no tension along the same-body segment, so ``computeMomentArm`` differs from ``-dL/dq``,
  while the length is that of the drawn path: the target stays ``-dL/dq``.
"""

from __future__ import annotations

import numpy as np
import opensim as osim
import pytest

from o2m.convert.converter import convert
from o2m.convert.drawn_arms import MA_AGREEMENT, drawn_path_arms
from o2m.osim.pair import ModelPair
from o2m.osim.spikes import drawn_length
from tests.convert.test_path_forces import _model as _moving_point_model
from tests.convert.test_wrapping import _two_link_over_two_cylinders
from tests.helpers import convert_options

osim.Logger.setLevelString("error")

STEP = 1e-5  # rad, central differences of OpenSim's length


def _pair(tmp_path, build, name: str) -> ModelPair:
    osim_path = tmp_path / f"{name}.osim"
    build(osim_path)
    conv = convert(osim_path, tmp_path / name, convert_options(fit_wraps=False, fit_mechanics=False, workers=1))
    return ModelPair(osim_path, conv.xml)


def _dldq(pair: ModelPair, values: dict[str, float], coords: list[str]) -> np.ndarray:
    """(n paths, n coords) OpenSim's -dL/dq (m) by central differences."""
    out = np.zeros((len(pair.matched), len(coords)))
    for j, c in enumerate(coords):
        up = pair.os_lengths(pair.os_state({**values, c: values[c] + STEP}))
        dn = pair.os_lengths(pair.os_state({**values, c: values[c] - STEP}))
        out[:, j] = -(up - dn) / (2 * STEP)
    return out


@pytest.mark.parametrize("q1, q2", [(-0.5, -0.5), (-0.3, -0.1), (0.1, 0.1)])
def test_where_the_length_is_not_the_drawn_paths_the_target_is_compute_moment_arm(tmp_path, q1, q2):
    pair = _pair(tmp_path, _two_link_over_two_cylinders, "two_cylinders")
    values = {"q1": q1, "q2": q2}
    state = pair.os_state(values)
    force = pair.matched[0][2]
    assert drawn_length(pair.os_model, state, "m") - force.getLength(state) > 5e-3  # OpenSim's inconsistency
    dldq = _dldq(pair, values, ["q1", "q2"])
    dynamic = np.array([force.computeMomentArm(state, pair.coord(c)) for c in ("q1", "q2")])
    assert np.all(np.abs(dynamic - dldq[0]) > 5e-3)  # measured 10-22 mm
    targets = drawn_path_arms(pair, state, values, ["q1", "q2"], {0: {"q1", "q2"}}, dldq, 10 * STEP)
    np.testing.assert_allclose(targets[0], dynamic, rtol=0, atol=1e-12)


def test_where_the_length_is_the_drawn_paths_the_target_is_dldq(tmp_path):
    pair = _pair(tmp_path, _two_link_over_two_cylinders, "two_cylinders")
    values = {"q1": 0.5, "q2": 0.5}  # one cylinder: OpenSim consistent
    state = pair.os_state(values)
    dldq = _dldq(pair, values, ["q1", "q2"])
    targets = drawn_path_arms(pair, state, values, ["q1", "q2"], {0: {"q1", "q2"}}, dldq, 10 * STEP)
    np.testing.assert_array_equal(targets, dldq)


def test_a_same_body_moving_point_keeps_dldq(tmp_path):
    """"big": computeMomentArm leaves out the same-body segment P2-P3 (over 5 mm from -dL/dq);
    the length is the drawn path's, so -dL/dq stays the target."""
    pair = _pair(tmp_path, _moving_point_model, "moving")
    names = [n for n, _, _ in pair.matched]
    big = names.index("big")
    for q in (-0.5, 0.4, 1.2):
        values = {"q": q}
        state = pair.os_state(values)
        dldq = _dldq(pair, values, ["q"])
        dynamic = pair.matched[big][2].computeMomentArm(state, pair.coord("q"))
        assert abs(dynamic - dldq[big, 0]) > MA_AGREEMENT
        targets = drawn_path_arms(pair, state, values, ["q"], {i: {"q"} for i in range(len(names))}, dldq, 10 * STEP)
        np.testing.assert_array_equal(targets, dldq)


def test_a_tendon_follows_the_drawn_path_as_far_as_its_length_stays_within_target():
    """Rajagopal2016's gasmed_r: drawn path up to 6.7 mm longer than getLength (1.5 % of 456 mm)
    -> the drawn path shortened by 3.35 mm, its moment arms; a gap spreading half as much again
    (2.3 %) -> the share of the way that keeps the length within half the gate of getLength, the
    moment arms blended alike; a gap spreading four times as much (6 %, the share under
    MIN_SHARE) and a chord-sized gap (0.2 mm) keep getLength and -dL/dq."""
    from o2m.convert.drawn_arms import DRAWN_GATE, MIN_SHARE, drawn_targets

    length = np.full(5, 0.456)
    arm, drawn_arm = np.zeros((5, 2)), np.ones((5, 2))
    gap = np.array([6.7e-3, 3e-3, 0.0, -1e-4, -2e-4])
    target, target_arm = drawn_targets(length, gap, arm, drawn_arm)
    np.testing.assert_allclose(target - length, gap - 0.5 * (6.7e-3 - 2e-4))
    assert np.max(np.abs(target - length)) == pytest.approx(0.5 * 6.9e-3)
    assert target_arm is drawn_arm
    wider = gap * 1.5
    target, target_arm = drawn_targets(length, wider, arm, drawn_arm)
    share = DRAWN_GATE * 0.456 / (1.5 * 6.9e-3)
    assert MIN_SHARE < share < 1.0
    np.testing.assert_allclose(target - length, share * (wider - 0.5 * (wider.max() + wider.min())))
    assert np.max(np.abs(target - length)) == pytest.approx(0.5 * DRAWN_GATE * 0.456)
    np.testing.assert_allclose(target_arm, share * drawn_arm)
    for far in (gap * 4.0, gap * 0.03):
        target, target_arm = drawn_targets(length, far, arm, drawn_arm)
        assert target is length and target_arm is arm
