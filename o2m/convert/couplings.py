"""Coupling fits beyond a quartic: a coordinate's coupled axes as sums of MuJoCo joints.

A MuJoCo joint equality is a quartic of one joint, so a coupled axis that a quartic of its
coordinate cannot follow (a spline) is written as a main quartic plus inner joints (quartics of
the coordinate) and outer joints (quartics of an inner joint): :func:`fit_couplings` fits such a
structure to several axes of one coordinate at once, :func:`fit_coupling` to one function. The
numerical parts (the shapes' search, the bounded minimax linear program) are in
:mod:`o2m.convert.shapesearch`. Units: x in the driving coordinate's unit (radians or metres),
each axis's values and errors in its own (radians or metres).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from o2m.convert.polyfit import FitError, fit_polynomial
from o2m.convert.shapesearch import (
    SLOPE_STEP,
    ShapeSearch,
    axis_basis,
    axis_basis_slope,
    check_coupling_args,
    levenberg_marquardt,
    lp_bounded_minimax,
    numeric_slope,
    polynomial_slope_errors,
    power_shape,
    shifted_power_series,
    unit_flat,
    unit_rows,
    unit_shape,
    unit_shape_slope,
)
from o2m.osim.functions import FloatArray

__all__ = [
    "COUPLING_AMPLITUDE", "COUPLING_GAIN", "COUPLING_INNER_SCALE", "COUPLING_MARGIN_SLACK",
    "COUPLING_GUARD_TRAVEL", "COUPLING_RANDOM_STARTS", "COUPLING_STARTS", "AxisFit", "CouplingFit",
    "fit_coupling", "fit_couplings", "numeric_slope", "polynomial_slope_errors",
]

#: Starting shapes (c, p) of a new inner polynomial, (t - c)^p, before it is optimised.
COUPLING_STARTS: tuple[tuple[float, int], ...] = tuple((c, p) for p in (3, 4) for c in (-1.0, -0.5, 0.0, 0.5, 1.0))
#: Random starting shapes added to those (seeded, so a conversion is reproducible).
COUPLING_RANDOM_STARTS = 10
#: The terms of each outer joint's correction have amplitudes adding up to at most this times
#: its axis's max |y - y(x0)|: the extra joints then move about as much as the axis itself,
#: never by large amounts that cancel (which a free fit of the same error needs; see
#: fit_couplings).
COUPLING_AMPLITUDE = 2.0
#: An added inner joint is kept only if it brings the error below this fraction of the last.
COUPLING_GAIN = 0.9
#: Each inner joint moves through this many times the largest correction term of the axes it
#: drives (each in its host axis's scale; the choice changes no sum of joints, as the host's main
#: joint makes up for it). An outer joint's force reaches its inner joint times d outer / d inner,
#: and MuJoCo softens the inner joint's equality by its coordinate's inverse weight, so a larger
#: inner joint holds its outer joints stiffer, for an inertia added to the coordinate that grows
#: with its square. Leg6Dof9Musc hanging under gravity, its knee's shared inner slide (which also
#: drives the patella's rotation) sagged 3.8e-5 m off its equality scaled to its host axis's own
#: correction, 2.3e-5 m scaled to the largest of them, 1.2e-5 m at twice that; the extra joints
#: then add 2.3 % to the knee's 0.65 kg m² (the conversion report gives it per axis).
COUPLING_INNER_SCALE = 2.0
#: In the margins beyond [lo, hi] that fit_couplings covers, the error may be this many times
#: the error inside: a degree-16 polynomial fitted on [lo, hi] alone leaves it fast (0.7 mm
#: 0.045 rad beyond a knee's range), which a joint pressing into a soft limit reaches.
COUPLING_MARGIN_SLACK = 5.0
#: fit_couplings's guard (``guard``, a fraction of the range beyond each end, outside the margins):
#: there each axis's error may reach COUPLING_GUARD_TRAVEL times its travel over the range
#: (max - min of y on [lo, hi]) times ((distance beyond the range) / (hi - lo))², plus
#: COUPLING_MARGIN_SLACK times the error inside. A chained fit of the range alone leaves the
#: spline like a degree-16 polynomial (Gait10dof18musc's knee translation: 22 mm 0.2 rad beyond
#: its range, 1.8e5 m one range width beyond), and OpenSim does not hold a coordinate in its range.
COUPLING_GUARD_TRAVEL = 0.1
_GUARD_POINTS = 201
_SEARCH_POINTS = 401
_LAWSON_ROUNDS = 4
_LM_ITERATIONS = 200
_POLISHED = 3
_POLY = np.polynomial.polynomial


@dataclass(frozen=True)
class AxisFit:
    """One axis of a :class:`CouplingFit`: y(x) - y(x0) ≈ main(x) + Σ_{inners l it carries}
    inner_l(x) + Σ_{(l, c) in outers} c(inner_l(x)).

    ``main`` (5,): the axis's main joint, a quartic in (x - x0), lowest power first, ``main[0]``
    being fn(x0); ``outers``: (inner index l, (5,) quartic coefficients in inner l's value,
    constant and linear terms 0), each an outer joint on this axis. ``max_error`` /
    ``rms_error``: realised errors (the function's unit) on a grid 8x denser than the fitting
    grid, over [lo, hi]; ``quartic_error``: the plain quartic's worst error; ``amplitude``: the
    largest range an extra joint on this axis moves through (0 without extra joints);
    ``margin_error``: the worst error in the margins beyond [lo, hi] that the fit also covers.
    ``slope_error`` / ``slope_rms``: the worst and RMS error of the derivative dy/dx over [lo, hi]
    (the function's unit per x unit: for a path point's location against a rotational
    coordinate, m/rad, directly a moment-arm error); ``quartic_slope_error`` /
    ``quartic_slope_rms``: the plain quartic's; ``slope_target``: the derivative's target (inf
    when the fit bounds the value only); ``guard_error``: the worst error in the guard beyond the
    margins (0 without one).
    """

    main: FloatArray
    outers: tuple[tuple[int, FloatArray], ...]
    max_error: float
    rms_error: float
    quartic_error: float
    target: float
    amplitude: float
    margin_error: float = 0.0
    slope_error: float = 0.0
    slope_rms: float = 0.0
    quartic_slope_error: float = 0.0
    quartic_slope_rms: float = 0.0
    slope_target: float = math.inf
    guard_error: float = 0.0


@dataclass(frozen=True)
class CouplingFit:
    """Several functions of one variable x (the axes of a coordinate's couplings), each a sum of
    MuJoCo joints following quartic joint equalities; see :func:`fit_couplings`.

    ``inners`` (L, 5): inner joint l, a quartic in (x - x0) with no constant term (driven by x),
    carried by axis ``hosts[l]``; ``shapes`` (L, 4): the inner polynomials' Chebyshev
    coefficients (T_1..T_4) in t = (x - mid) / half, mid and half the centre and half-width of
    [lo - margin, hi + margin]; ``axes``: one :class:`AxisFit` per function; ``condition``: the
    largest 2-norm condition number of an axis's column-scaled linear-program basis;
    ``margin``: how far beyond [lo, hi] the fit reaches on each side (x's unit); ``guard``: how far
    beyond [lo, hi] its error is capped (x's unit, 0: not at all).
    """

    inners: FloatArray
    hosts: tuple[int, ...]
    shapes: FloatArray
    axes: tuple[AxisFit, ...]
    condition: float
    lo: float
    hi: float
    x0: float
    margin: float = 0.0
    guard: float = 0.0

    @property
    def n_inner(self) -> int:
        """L, the number of inner joints."""
        return int(self.inners.shape[0])

    def inner_values(self, x: ArrayLike) -> FloatArray:
        """Every inner joint's value at x: (L, *x.shape)."""
        dx = np.asarray(x, dtype=np.float64) - self.x0
        return np.array([_POLY.polyval(dx, c) for c in self.inners]).reshape(self.n_inner, *dx.shape)

    def joint_values(self, axis: int, x: ArrayLike) -> tuple[FloatArray, list[FloatArray], list[FloatArray]]:
        """Axis ``axis``'s joints at x, each evaluated as MuJoCo evaluates its equality: (main,
        [inner joints it carries], [its outer joints])."""
        dx = np.asarray(x, dtype=np.float64) - self.x0
        inner = self.inner_values(x)
        ax = self.axes[axis]
        hosted = [inner[k] for k in range(self.n_inner) if self.hosts[k] == axis]
        outers = [np.asarray(_POLY.polyval(inner[k], c), dtype=np.float64) for k, c in ax.outers]
        return np.asarray(_POLY.polyval(dx, ax.main), dtype=np.float64), hosted, outers

    def axis_value(self, axis: int, x: ArrayLike) -> FloatArray:
        """The sum of axis ``axis``'s joints at x (any shape)."""
        main, hosted, outers = self.joint_values(axis, x)
        return np.asarray(main + sum(hosted, np.zeros_like(main)) + sum(outers, np.zeros_like(main)), dtype=np.float64)

    def axis_slope(self, axis: int, x: ArrayLike) -> FloatArray:
        """d/dx of the sum of axis ``axis``'s joints at x (any shape): the chain rule through
        each outer joint's inner joint."""
        dx = np.asarray(x, dtype=np.float64) - self.x0
        inner = self.inner_values(x)
        dinner = [_POLY.polyval(dx, _POLY.polyder(c)) for c in self.inners]
        ax = self.axes[axis]
        s = _POLY.polyval(dx, _POLY.polyder(ax.main)) * np.ones_like(dx)
        for k in range(self.n_inner):
            if self.hosts[k] == axis:
                s = s + dinner[k]
        for k, c in ax.outers:
            s = s + _POLY.polyval(inner[k], _POLY.polyder(c)) * dinner[k]
        return np.asarray(s, dtype=np.float64)

    def __call__(self, x: ArrayLike) -> FloatArray:
        """Every axis's value at x: (n_axes, *x.shape)."""
        return np.array([self.axis_value(a, x) for a in range(len(self.axes))])

    def extra_joints(self, axis: int) -> int:
        """How many joints axis ``axis`` has besides its main joint."""
        return sum(h == axis for h in self.hosts) + len(self.axes[axis].outers)

    def structure(self, axis: int) -> str:
        """A short description of axis ``axis``'s joints, e.g. ``quartic + 1 inner + 1 outer quartic``."""
        ax = self.axes[axis]
        hosted = sum(h == axis for h in self.hosts)
        if not hosted and not ax.outers:
            return "quartic"
        parts = ["quartic"]
        if hosted:
            parts.append(f"{hosted} inner quartic{'s' if hosted > 1 else ''} (a quartic of the coordinate)")
        if ax.outers:
            n = len(ax.outers)
            parts.append(f"{n} outer quartic{'s' if n > 1 else ''} of inner joint{'s' if n > 1 else ''} "
                         + ", ".join(str(k + 1) for k, _ in ax.outers))
        return " + ".join(parts)


def fit_couplings(fns: Sequence[Callable[[FloatArray], FloatArray]], lo: float, hi: float, x0: float, *,
                  targets: Sequence[float], uses: Sequence[Sequence[int]], hosts: Sequence[int],
                  start_shapes: ArrayLike = (), n: int = 2001, amplitude: float = COUPLING_AMPLITUDE,
                  margin: float = 0.0, guard: float = 0.0, seed: int = 0,
                  slope_targets: Sequence[float] | None = None,
                  cache: dict[bytes, CouplingFit] | None = None) -> CouplingFit:
    """Approximate functions y_a of one variable x on [lo, hi] (the coupled axes of one
    coordinate) by sums of MuJoCo joints, each joint following a quartic joint equality.

    What: L inner joints D_l(x) = α_l h_l(x), each a quartic in (x - x0) (driven by x) and
    carried by axis ``hosts[l]``; axis a has a main joint C_a, a quartic in (x - x0), and for
    each l in ``uses[a]`` an outer joint E_al, a quartic in D_l (driven by it: a chain). So

        y_a(x) - y_a(x0) ≈ C_a(x) + Σ_{l: hosts[l] = a} D_l(x) + Σ_{l in uses[a]} E_al(D_l(x)).

    Every joint but C_a is 0 at x0 and C_a(x0) = 0 after y_a(x0), so the sums are exact at x0
    and the reference pose satisfies every equality.

    Why: a MuJoCo joint equality (``mjEQ_JOINT``) is a quartic, so one joint cannot follow a
    spline closely (about 0.25 mm on a knee translation). Joints of one body along the same
    axis add up (slides sum their translations, hinges about one axis through one point their
    angles), and a quartic of a quartic reaches degree 16. MuJoCo allows at most 6 degrees of
    freedom per body, so inner joints are shared: one inner joint can drive outer joints on
    several axes, also on other bodies (a knee's inner joint drives the patella's outers).

    How: for fixed inner shapes h_l (scaled to at most 1 in magnitude), each y_a is linear in
    its remaining coefficients (the main quartic's and b_alj of h_l^j, j = 2..4), so its minimax
    fit is one linear program, on column-scaled variables, with each outer's Σ_j |b_alj| held
    to ``amplitude`` times max |y_a - y_a(x0)|. The bound matters: with fixed shapes (x - c)^p a
    free fit reaches its error only with joints moving metres (or turns) in opposite
    directions to sum to millimetres (a degree-16 polynomial written in a poorly conditioned
    basis), which a simulation cannot follow. The shapes are found by a least-squares search
    (variable projection, Levenberg-Marquardt), from ``start_shapes`` (the first inners' shapes,
    e.g. a smaller structure's), for each further inner from (t - c)^p for the shifts and
    degrees of :data:`COUPLING_STARTS` and seeded random shapes, adding one inner at a time;
    the best few are reweighted towards minimax (Lawson's iteration) and scored by their linear
    programs (worst error relative to ``targets``). Then C_a is the main quartic minus the inner
    joints axis a carries, α_l :data:`COUPLING_INNER_SCALE` times the largest correction term
    of the axes using it (scaled to its host axis), and E_al = Σ_j b_alj (D_l / α_l)^j.

    ``margin`` (a fraction of hi - lo) widens the fit by that much on each side, where the error
    may be :data:`COUPLING_MARGIN_SLACK` times larger than inside; the errors reported are the
    ones inside [lo, hi] (the margins' in ``margin_error``). ``guard`` (a fraction of hi - lo, at
    least ``margin``) caps the error out to that far beyond each end (see
    :data:`COUPLING_GUARD_TRAVEL`; ``guard_error``): the chained joints then stay near the
    function where a coordinate leaves its range, which a fit of the range alone does not.

    ``slope_targets`` (one per function, its unit per x unit) makes the fits derivative-aware:
    the derivative of each sum of joints is linear in the same coefficients, so each linear
    program bounds, on the same samples, max(|error| / target, |d error / dx| / slope target)
    (the derivatives of y_a by :func:`numeric_slope`; the derivative inside [lo, hi] only, not in
    the margins), and the shapes are scored that way too (their search stays on values). A
    path point's location against a rotational coordinate has its derivative error as a
    moment-arm error. Without them only the value is bounded (the derivative errors are still
    reported). The plain quartic (no inner joints) is always the value's minimax quartic.

    ``cache`` (the caller's, e.g. one per conversion; None: none): fits already made, by a digest
    of the functions' values on the check grid and the arguments; a fit found there is returned
    as it is (the fit is deterministic, so this changes no result, only the time).

    Units: x in the driving coordinate's unit (rad or m); y_a and ``targets[a]`` in axis a's.
    """
    lo, hi, x0 = float(lo), float(hi), float(x0)
    start = check_coupling_args(len(fns), lo, hi, x0, targets, uses, hosts, start_shapes, slope_targets)
    samples = _Samples(fns, lo, hi, x0, n, margin, slope_targets, guard)
    # everything below sees the functions only through their values on this grid (which holds the others)
    key = hashlib.sha256(b"".join([samples.check.tobytes(), *(f.tobytes() for f in samples.fc),
                                   *(f.tobytes() for f in samples.dc), start.tobytes(),
                                   np.array([lo, hi, x0, n, amplitude, margin, guard, seed, *targets, *hosts,
                                             *samples.slopes]).tobytes(),
                                   repr([list(u) for u in uses]).encode()])).digest()
    if cache is not None and key in cache:
        return cache[key]
    problem = _Problem(samples, n, targets, amplitude)
    shapes = _search_shapes(problem, start, uses, len(hosts), seed)
    fit = _measured(problem, _assembled(problem, shapes, uses, hosts))
    _check_finite(fit)
    if cache is not None:
        cache[key] = fit
    return fit


def _check_finite(fit: CouplingFit) -> None:
    """Raise :class:`~o2m.convert.polyfit.FitError` when a coefficient or an error of ``fit`` is not finite."""
    numbers = [fit.inners.ravel()] + [np.concatenate([ax.main, *(c for _, c in ax.outers),
                                                      [ax.max_error, ax.slope_error]]) for ax in fit.axes]
    if not all(np.all(np.isfinite(v)) for v in numbers):
        raise FitError(f"the coupling fitted over [{fit.lo:g}, {fit.hi:g}] is not finite")


class _Samples:
    """The functions' values and derivatives on the grid the fit is measured on (``check``: 8x
    denser than the fitting grid, over [lo, hi] and its margins, with the functions' knots), and
    the grids and sample weights of :func:`fit_couplings` (x's unit)."""

    def __init__(self, fns: Sequence[Callable[[FloatArray], FloatArray]], lo: float, hi: float, x0: float,
                 n: int, margin: float, slope_targets: Sequence[float] | None, guard: float = 0.0):
        self.fns, self.lo, self.hi, self.x0 = fns, lo, hi, x0
        self.knots = [np.asarray(getattr(fn, "knots", np.empty(0)), dtype=float) for fn in fns]
        self.width = float(margin) * (hi - lo)
        self.lo_m, self.hi_m = lo - self.width, hi + self.width  # the range with its margins
        self.check = self.grid(8 * (n - 1) + 1)
        self.fc = [np.asarray(fn(self.check), dtype=np.float64) for fn in fns]
        self.step = SLOPE_STEP * (self.hi_m - self.lo_m)
        self.dc = [numeric_slope(fn, self.check, self.step) for fn in fns]
        self.slopes = [math.inf] * len(fns) if slope_targets is None else [float(v) for v in slope_targets]
        self.guard = max(float(guard), float(margin)) * (hi - lo)
        self.guard_x = self.guard_grid()
        inside = (self.check >= lo) & (self.check <= hi)
        beyond = np.maximum(lo - self.guard_x, self.guard_x - hi) / (hi - lo)
        self.guard_f = [np.asarray(fn(self.guard_x), dtype=np.float64) for fn in fns]
        self.guard_cap = [COUPLING_GUARD_TRAVEL * float(np.ptp(f[inside])) * beyond ** 2 for f in self.fc]

    def guard_grid(self) -> FloatArray:
        """The guard's samples beyond the margins on each side (empty without a guard)."""
        if self.guard <= self.width:
            return np.zeros(0)
        g = np.linspace(self.width, self.guard, _GUARD_POINTS)[1:]
        return np.concatenate([self.lo - g[::-1], self.hi + g])

    def grid(self, m: int) -> FloatArray:
        """m uniform points over the range with its margins, plus the knots and (with margins) lo and hi."""
        xs = np.linspace(self.lo_m, self.hi_m, m)
        k = np.concatenate([xs, *self.knots, [self.lo, self.hi]] if self.width else [xs, *self.knots])
        return np.unique(k[(k >= self.lo_m) & (k <= self.hi_m)])

    def rows(self, x: FloatArray) -> FloatArray:
        """Each sample's weight: 1 inside [lo, hi], 1 / COUPLING_MARGIN_SLACK in the margins."""
        return np.where((x >= self.lo) & (x <= self.hi), 1.0, 1.0 / COUPLING_MARGIN_SLACK)


class _Problem:
    """What the search and the final linear programs of :func:`fit_couplings` fit: each function
    less its value at x0, in t = (x - mid) / half, on the fitting grid (``t``, ``fs``, derivatives
    ``ds``) and the coarser search grid (``ts``, scaled to each axis's target: ``f_search``,
    ``d_search``), with the plain quartics."""

    def __init__(self, s: _Samples, n: int, targets: Sequence[float], amplitude: float):
        fns, lo, hi, x0 = s.fns, s.lo, s.hi, s.x0
        self.s, self.targets, self.amplitude = s, targets, amplitude
        self.quartics = [fit_polynomial(fn, lo, hi, x0, degree=4, n=n, exact_at_x0=True)  # type: ignore[arg-type]
                         for fn in fns]
        self.f0 = [float(np.asarray(fn(np.array([x0])), dtype=np.float64)[0]) for fn in fns]
        self.mid, self.half = (s.lo_m + s.hi_m) / 2, (s.hi_m - s.lo_m) / 2
        mid, half = self.mid, self.half
        self.t0 = (x0 - mid) / half
        xs = s.grid(n)
        self.t, self.w_fit = (xs - mid) / half, s.rows(xs)
        self.fs = [np.asarray(fn(xs), dtype=np.float64) - c for fn, c in zip(fns, self.f0, strict=True)]
        self.fscale = [max(float(np.max(np.abs(f))), 1e-300) for f in self.fs]
        weight = [1.0 / max(float(tg), 1e-9 * q.max_error, 1e-300)
                  for tg, q in zip(targets, self.quartics, strict=True)]
        ts_x = s.grid(_SEARCH_POINTS)
        self.ts, self.w_search = (ts_x - mid) / half, s.rows(ts_x)
        self.f_search = [(np.asarray(fn(ts_x), dtype=np.float64) - c) * w
                         for fn, c, w in zip(fns, self.f0, weight, strict=True)]
        # derivatives in t (x = mid + half t), each in its function's scale (fs) or its target's (f_search);
        # ratio: the value error a derivative error of its slope target counts as (None: value only)
        self.ratio = [None if math.isinf(sl) else float(tg) / sl for tg, sl in zip(targets, s.slopes, strict=True)]
        self.ds = [numeric_slope(fn, xs, s.step) * half for fn in fns]
        # the guard (values less their x0 value, caps), in each function's scale and its target's
        self.tg = (s.guard_x - mid) / half
        self.gs = [g - c for g, c in zip(s.guard_f, self.f0, strict=True)]
        self.g_search = [(g, np.maximum(cap + q.max_error, 1e-9 * fs)) for g, cap, q, fs
                         in zip(self.gs, s.guard_cap, self.quartics, self.fscale, strict=True)]
        self.g_search_w = [(g * w, cap * w) for (g, cap), w in zip(self.g_search, weight, strict=True)]
        # the shapes' least-squares search sees the guard too, each sample weighted by 1 / its
        # (most lenient) cap in the axes' target units: an error at the cap counts as the target inside
        guard_rows = 1.0 / np.max([cap for _, cap in self.g_search_w], axis=0, initial=1e-300) \
            if self.tg.size else np.zeros(0)
        self.search_t = np.concatenate([self.ts, self.tg])
        self.search_f = [np.concatenate([f, g]) for f, (g, _) in zip(self.f_search, self.g_search_w, strict=True)]
        self.search_rows = np.concatenate([self.w_search, np.minimum(guard_rows, 1.0)])
        self.d_search = [numeric_slope(fn, ts_x, s.step) * half * w for fn, w in zip(fns, weight, strict=True)]

    def unit(self, tt: FloatArray, shape: FloatArray) -> tuple[FloatArray, float, FloatArray]:
        """An inner shape scaled to at most 1 over ``tt`` and the guard: (values on tt, scale, values
        on the guard). Over the guard too, so the outer joints' amplitude bound holds there."""
        h, nk = unit_shape(np.concatenate([tt, self.tg]), self.t0, shape)
        return h[:tt.size], nk, h[tt.size:]

    def lp(self, shapes: Sequence[FloatArray], tt: FloatArray, ff: Sequence[FloatArray], dd: Sequence[FloatArray],
           ww: FloatArray, axis_uses, guard: Sequence[tuple[FloatArray, FloatArray]], polish=False):
        """Per axis: (worst error weighted by ``ww``, coefficients of the column-scaled basis,
        column scales, cond: the basis's condition number, with ``polish`` only, else nan). With
        ``polish`` (the final fit), the least-squares coefficients replace the linear
        program's when they respect the amplitude bound and have the smaller worst error (they
        reach round-off for a function the structure represents exactly, where the LP stops at
        its tolerance). ``dd``: each axis's derivative in t (ff's units), bounded (times
        ``ratio``) with the values where the axis has a slope target. ``guard``: each axis's (values,
        caps) on the guard's samples ``self.tg``, in ff's units."""
        t0, amplitude = self.t0, self.amplitude
        units = [self.unit(tt, s) for s in shapes]
        hs = [u[0] for u in units]
        hg = [u[2] for u in units]
        dhs = [unit_shape_slope(tt, s, u[1]) for s, u in zip(shapes, units, strict=True)]
        out = []
        for a, f in enumerate(ff):
            A = axis_basis(tt, t0, [hs[k] for k in axis_uses[a]])
            scale = np.max(np.abs(A), axis=0)
            As, target = A / scale * ww[:, None], f * ww
            if self.ratio[a] is not None:  # the derivative's rows, in the value's units
                dA = axis_basis_slope(tt, t0, [hs[k] for k in axis_uses[a]], [dhs[k] for k in axis_uses[a]])
                sw = (ww >= 1.0) * self.ratio[a]  # inside [lo, hi] only
                As = np.vstack([As, dA / scale * sw[:, None]])
                target = np.concatenate([target, dd[a] * sw])
            fsa = max(float(np.max(np.abs(f))), 1e-300)
            Ag = axis_basis(self.tg, t0, [hg[k] for k in axis_uses[a]]) / scale
            g_val, g_cap = guard[a]
            got = lp_bounded_minimax(As, target / fsa, len(axis_uses[a]), amplitude,
                                     (Ag, g_val / fsa, g_cap / fsa, COUPLING_MARGIN_SLACK))
            if got is None:
                return None
            coef, err = got[0] * fsa, got[1] * fsa
            if polish:
                ls = np.linalg.lstsq(As, target, rcond=None)[0]
                sums = np.abs(ls[4:]).reshape(-1, 3).sum(axis=1) if ls.size > 4 else np.zeros(0)
                ls_err = float(np.max(np.abs(As @ ls - target)))
                capped = np.all(np.abs(Ag @ ls - g_val) <= g_cap + COUPLING_MARGIN_SLACK * ls_err)
                if capped and np.all(sums <= amplitude * fsa) and ls_err < float(np.max(np.abs(As @ coef - target))):
                    coef, err = ls, ls_err
            out.append((err, coef, scale, float(np.linalg.cond(A / scale)) if polish else math.nan))
        return out

    def score(self, shapes, axis_uses) -> float:
        """The worst error of the search grid's linear programs, relative to each axis's target."""
        got = self.lp(shapes, self.ts, self.f_search, self.d_search, self.w_search, axis_uses, self.g_search_w)
        return math.inf if got is None else max(g[0] for g in got)


def _search_shapes(p: _Problem, start: FloatArray, uses: Sequence[Sequence[int]], L: int,
                   seed: int) -> list[FloatArray]:
    """The L inner shapes (Chebyshev T_1..T_4, unit norm): the start shapes polished, then one
    inner joint added at a time (:func:`_search_stage`)."""
    rng = np.random.default_rng(seed)
    shapes = [s / np.linalg.norm(s) for s in start]
    stages = list(range(len(shapes), L)) or ([L - 1] if L else [])
    for stage in stages:
        shapes = _search_stage(p, shapes, stage + 1, uses, rng)
    return shapes


def _search_stage(p: _Problem, shapes: list[FloatArray], k_all: int, uses: Sequence[Sequence[int]],
                  rng: np.random.Generator) -> list[FloatArray]:
    """The first ``k_all`` shapes: the given ones polished if there are as many, else with a new
    one searched from :data:`COUPLING_STARTS` and random starts (Levenberg-Marquardt from each)."""
    axis_uses = [[k for k in u if k < k_all] for u in uses]
    search = ShapeSearch(p.search_t, p.t0, p.search_f, axis_uses, p.search_rows)
    if len(shapes) >= k_all:
        starts = [np.zeros(0)]  # polish the given shapes
    else:
        starts = [power_shape(c, d) for c, d in COUPLING_STARTS]
        starts += list(rng.normal(size=(COUPLING_RANDOM_STARTS, 4)))
    runs = []
    for s0 in starts:
        flat0 = np.concatenate([*shapes[:k_all], s0 / max(float(np.linalg.norm(s0)), 1e-300)] if s0.size
                               else shapes[:k_all])
        search.sw = [np.ones_like(f) for f in p.search_f]
        flat = unit_flat(levenberg_marquardt(search, flat0, _LM_ITERATIONS))
        r = search.residual(flat)
        runs.append((float(r @ r), flat, flat0))
    # every result scored by its linear programs; the best few then reweighted towards
    # minimax (Lawson); the earlier shapes kept as they were with the best new one are a
    # candidate too (its error is no larger than the smaller structure's)
    runs.sort(key=lambda r: r[0])
    scored = [(p.score(unit_rows(f), axis_uses), i, f) for i, f in
              enumerate([runs[0][2]] + [r[1] for r in runs])]
    scored.sort(key=lambda z: (z[0], z[1]))
    for _, _, flat in list(scored[:_POLISHED]):
        ws = [np.ones_like(f) for f in p.search_f]
        for j in range(_LAWSON_ROUNDS):
            ws = [w * np.abs(e) for w, e in zip(ws, search.errors(flat), strict=True)]
            top = max(max(float(np.max(w)) for w in ws), 1e-300)
            ws = [w / top for w in ws]
            search.sw = [np.sqrt(w) for w in ws]
            flat = unit_flat(levenberg_marquardt(search, flat, _LM_ITERATIONS // 4))
            scored.append((p.score(unit_rows(flat), axis_uses), len(scored) + j, flat))
    best_flat = min(scored, key=lambda z: (z[0], z[1]))[2]
    return unit_rows(best_flat)


def _assembled(p: _Problem, shapes: list[FloatArray], uses: Sequence[Sequence[int]],
               hosts: Sequence[int]) -> CouplingFit:
    """The joints for the found shapes, from the final linear programs on the full grid (the
    errors not measured yet): the main quartics, the inner joints scaled by
    :data:`COUPLING_INNER_SCALE` and the outer quartics in the inner joints' values."""
    s, n_axes, L = p.s, len(p.s.fns), len(hosts)
    got = p.lp(shapes, p.t, p.fs, p.ds, p.w_fit, [list(u) for u in uses], p.g_search, polish=True) if L else None
    if L and got is None:
        raise ValueError("fit_couplings: the linear program failed")
    units = [p.unit(p.t, sh)[:2] for sh in shapes]
    inner_poly = [shifted_power_series(sh, p.t0, p.half) / nk for sh, (_, nk) in zip(shapes, units, strict=True)]
    corrections: dict[tuple[int, int], tuple[FloatArray, float]] = {}  # (axis, inner): (b (3,), max |g|)
    mains = []
    conds = [1.0]
    for a in range(n_axes):
        main = np.zeros(5)
        main[0] = p.f0[a]
        if L:
            _, coef, scale, cond = got[a]  # type: ignore[index]
            coef = coef / scale
            conds.append(cond)
            main[1:] = coef[:4] / p.half ** np.arange(1, 5)
            for i, k in enumerate(uses[a]):
                b = coef[4 + 3 * i: 7 + 3 * i]
                g = sum(b[j - 2] * units[k][0] ** j for j in (2, 3, 4))
                corrections[(a, k)] = (b, float(np.max(np.abs(g))))
        else:
            main = np.asarray(p.quartics[a].coef, dtype=float).copy()
        mains.append(main)
    alphas = []
    for k in range(L):
        host = hosts[k]
        own = corrections.get((host, k), (None, 0.0))[1]
        other = max([corrections[(a, k)][1] * p.fscale[host] / p.fscale[a] for a in range(n_axes)
                     if (a, k) in corrections], default=0.0)
        alphas.append(COUPLING_INNER_SCALE * max(own, other, 1e-3 * p.fscale[host]))
    inners = np.array([q * al for q, al in zip(inner_poly, alphas, strict=True)]).reshape(-1, 5)
    for k in range(L):
        mains[hosts[k]] = mains[hosts[k]] - inners[k]  # the host's main joint makes up for the inner joint
    outers_by_axis: list[list[tuple[int, FloatArray]]] = [[] for _ in range(n_axes)]
    for (a, k), (b, _) in sorted(corrections.items()):
        al = alphas[k]
        outers_by_axis[a].append((k, np.array([0.0, 0.0, b[0] / al ** 2, b[1] / al ** 3, b[2] / al ** 4])))
    return CouplingFit(inners=inners, hosts=tuple(int(h) for h in hosts), shapes=np.array(shapes).reshape(-1, 4),
                       axes=tuple(AxisFit(mains[a], tuple(outers_by_axis[a]), 0.0, 0.0, p.quartics[a].max_error,
                                          float(p.targets[a]), 0.0) for a in range(n_axes)),
                       condition=float(max(conds)), lo=s.lo, hi=s.hi, x0=s.x0, margin=s.width, guard=s.guard)


def _measured(p: _Problem, draft: CouplingFit) -> CouplingFit:
    """``draft`` with each axis's realised errors (values and derivatives, inside [lo, hi] and in
    the margins) and joint amplitudes, on the check grid."""
    s = p.s
    check, x0 = s.check, s.x0
    inside = (check >= s.lo) & (check <= s.hi)
    axes = []
    for a, ax in enumerate(draft.axes):
        err = draft.axis_value(a, check) - s.fc[a]
        slope = (draft.axis_slope(a, check) - s.dc[a])[inside]
        q_slope = (_POLY.polyval(check - x0, _POLY.polyder(p.quartics[a].coef)) - s.dc[a])[inside]
        _, hosted, outers = draft.joint_values(a, check)
        amp = max([float(np.ptp(v)) for v in hosted + outers], default=0.0)
        axes.append(AxisFit(ax.main, ax.outers, float(np.max(np.abs(err[inside]))),
                            float(np.sqrt(np.mean(err[inside] ** 2))), p.quartics[a].max_error, float(p.targets[a]),
                            amp, float(np.max(np.abs(err[~inside]), initial=0.0)),
                            float(np.max(np.abs(slope))), float(np.sqrt(np.mean(slope ** 2))),
                            float(np.max(np.abs(q_slope))), float(np.sqrt(np.mean(q_slope ** 2))), s.slopes[a],
                            float(np.max(np.abs(draft.axis_value(a, s.guard_x) - s.guard_f[a]), initial=0.0))))
    return CouplingFit(**{**draft.__dict__, "axes": tuple(axes)})


def fit_coupling(fn: Callable[[FloatArray], FloatArray], lo: float, hi: float, x0: float, *,
                 target: float, max_inner: int = 3, n: int = 2001, amplitude: float = COUPLING_AMPLITUDE,
                 margin: float = 0.0, seed: int = 0, slope_target: float | None = None,
                 cache: dict[bytes, CouplingFit] | None = None) -> CouplingFit:
    """One function as a sum of joints (:func:`fit_couplings` with one axis carrying all its inner
    joints): the plain quartic when its error is at most ``target``; otherwise K = 1, 2, ...
    ``max_inner`` inner/outer pairs, each K starting from K - 1's shapes, stopping at the first
    K that meets ``target`` (fewest extra joints), and only as long as each pair brings the
    error below :data:`COUPLING_GAIN` times the last; so the error never grows with
    ``max_inner``. With ``slope_target`` the error is max(error / target, slope error / slope
    target) and the fits are derivative-aware (see :func:`fit_couplings`). Units as
    :func:`fit_couplings`, ``cache`` passed on to it."""
    kw = {"n": n, "amplitude": amplitude, "margin": margin, "seed": seed,
          "slope_targets": None if slope_target is None else [slope_target], "cache": cache}

    def ratio(f: CouplingFit) -> float:
        ax = f.axes[0]
        return max(ax.max_error / max(target, 1e-300), ax.slope_error / slope_target if slope_target else 0.0)

    best = fit_couplings([fn], lo, hi, x0, targets=[target], uses=[[]], hosts=[], **kw)
    for k in range(1, max_inner + 1):
        if ratio(best) <= 1:
            break
        fit = fit_couplings([fn], lo, hi, x0, targets=[target], uses=[list(range(k))], hosts=[0] * k,
                            start_shapes=best.shapes, **kw)
        if ratio(fit) > COUPLING_GAIN * ratio(best):
            break
        best = fit
    return best
