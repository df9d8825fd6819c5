"""Fits whose optimum is flat in some direction give one answer whatever the rounding: the same
model converted on two machines (two BLAS libraries) has the same muscles and springs. Before,
data 1e-15 apart gave a muscle's lmin 1.8 apart and a limit spring's edge 5e-5 rad apart."""

import math

import numpy as np
import pytest

from o2m.convert.limit_forces import fit_deadband
from o2m.convert.muscle_samples import MuscleSample
from o2m.convert.muscles import _fit_length

#: Relative changes of the data far below any real change of a model, as rounding makes them.
ROUNDINGS = (1e-15, 1e-13, 1e-11)


def _narrow_muscle(scale: float = 1.0) -> MuscleSample:
    """A muscle whose MTU length spans 3.6 mm near its optimal fiber length (as MoBL-ARMS's EPL):
    the active force varies by 0.7 %, the passive one starts in the last 40 %; lmin, lmax and
    fpmax are then nearly free."""
    lengths = np.linspace(0.29045, 0.29408, 197)
    x = np.linspace(-1.0, 1.0, lengths.size)
    active = 88.3 * (0.99505 - 0.0065 * (x - 0.05) ** 2) * scale
    passive = 88.3 * 0.0034 * (np.maximum(x - 0.2, 0.0) / 0.8) ** 1.5 * scale
    return MuscleSample(name="narrow", type="Schutte1993Muscle_Deprecated", force=88.3, lopt=0.054, lts=0.2305,
                        alpha=0.10471976, vmax_os=10.0, lengthrange=np.array([lengths[0], lengths[-1]]),
                        lengths=lengths, active=active + passive, passive=passive, fv_u=np.linspace(-1, 1, 5),
                        fv=np.ones(5), timeconst=(0.01, 0.04), notes=[], seed=0)


@pytest.mark.parametrize("rounding", ROUNDINGS)
def test_the_length_fit_of_a_muscle_that_varies_little_does_not_depend_on_rounding(rounding):
    a, _, err_a, _ = _fit_length(_narrow_muscle(), math.inf)
    b, _, err_b, _ = _fit_length(_narrow_muscle(1.0 + rounding), math.inf)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-7)
    assert abs(err_a - err_b) < 1e-6


@pytest.mark.parametrize("rounding", ROUNDINGS)
def test_a_limit_springs_edge_does_not_depend_on_rounding(rounding):
    """A CoordinateLimitForce-like torque (40 N m/rad past 1.2 rad, stiffening over 0.2 rad) whose
    deadband fit's worst error is flat over a range of edges."""
    u = np.linspace(1.7628, -0.5411, 241)
    s = np.clip((u - 1.2) / 0.2, 0.0, 1.0)
    target = 40.0 * s * s * (3.0 - 2.0 * s) * np.maximum(u - 1.2, 0.0)
    e_a, p_a, err_a = fit_deadband(u, target, 1.047, 1.7628)
    e_b, p_b, err_b = fit_deadband(u, target * (1.0 + rounding), 1.047, 1.7628)
    assert abs(e_a - e_b) < 1e-9
    np.testing.assert_allclose(p_a, p_b, rtol=1e-6)
    assert abs(err_a - err_b) < 1e-6 * err_a
