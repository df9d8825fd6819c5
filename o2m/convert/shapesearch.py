"""The numerical parts of the coupling fit (:func:`o2m.convert.couplings.fit_couplings`).

An inner joint's shape is a quartic, held as its Chebyshev coefficients of T_1..T_4 in
t = (x - mid) / half (the fitted range scaled to [-1, 1]); for fixed shapes an axis's sum of
joints is linear in its remaining coefficients. Here: those linear bases and their derivatives
(:func:`axis_basis`, :func:`axis_basis_slope`), the least-squares search for the shapes
(:class:`ShapeSearch`, variable projection, with :func:`levenberg_marquardt`), the minimax fit
with bounded outer joints (:func:`lp_bounded_minimax`, a linear program) and the conversion of
a shape to power coefficients in (x - x0) (:func:`shifted_power_series`). Units: t is
dimensionless; x in the driving coordinate's unit (rad or m); values in each axis's (rad or m).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from o2m.osim.functions import FloatArray

__all__ = [
    "ShapeSearch", "axis_basis", "axis_basis_slope", "levenberg_marquardt", "lp_bounded_minimax",
    "power_shape", "shifted_power_series", "unit_flat", "unit_rows", "unit_shape", "unit_shape_slope",
]

_LP_OPTIONS = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}
_CHEB = np.polynomial.chebyshev
_POLY = np.polynomial.polynomial


#: Central-difference step of the derivatives fit_couplings bounds, as a fraction of the fitted range.
SLOPE_STEP = 1e-6


def numeric_slope(fn: Callable[[FloatArray], FloatArray], x: FloatArray, step: float) -> FloatArray:
    """dfn/dx at x by central differences of step ``step`` (x's unit): for the smooth functions
    fitted here (splines, polynomials) accurate to about step² |f'''| plus round-off."""
    x = np.asarray(x, dtype=np.float64)
    return (np.asarray(fn(x + step), dtype=np.float64) - np.asarray(fn(x - step), dtype=np.float64)) / (2 * step)


def polynomial_slope_errors(fn: Callable[[FloatArray], FloatArray], coef: ArrayLike, lo: float, hi: float,
                            x0: float, n: int = 16001) -> tuple[float, float]:
    """(worst, RMS) error over [lo, hi] of the derivative of sum_j coef[j] (x - x0)^j against
    fn's (uniform samples; fn's by :func:`numeric_slope`)."""
    x = np.linspace(float(lo), float(hi), n)
    e = _POLY.polyval(x - x0, _POLY.polyder(np.asarray(coef, dtype=float))) - numeric_slope(
        fn, x, SLOPE_STEP * max(float(hi) - float(lo), 1e-12))
    return float(np.max(np.abs(e))), float(np.sqrt(np.mean(e * e)))


def check_coupling_args(n_axes: int, lo: float, hi: float, x0: float, targets: Sequence[float],
                   uses: Sequence[Sequence[int]], hosts: Sequence[int], start_shapes: ArrayLike,
                   slope_targets: Sequence[float] | None) -> FloatArray:
    """fit_couplings's arguments checked (ValueError if they do not fit together); the start
    shapes as an (S, 4) array."""
    L = len(hosts)
    if not hi > lo:
        raise ValueError(f"fit_couplings needs hi > lo, got [{lo}, {hi}]")
    if not lo <= x0 <= hi:
        raise ValueError(f"fit_couplings needs lo <= x0 <= hi, got x0 = {x0} outside [{lo}, {hi}]")
    if len(targets) != n_axes or len(uses) != n_axes:
        raise ValueError("fit_couplings needs one target and one list of used inners per function")
    if any(not 0 <= h < n_axes for h in hosts) or any(not 0 <= k < L for u in uses for k in u):
        raise ValueError("fit_couplings: hosts must name axes and uses must name inner joints")
    start = np.asarray(start_shapes, dtype=float).reshape(-1, 4)
    if start.shape[0] > L:
        raise ValueError("fit_couplings: more start shapes than inner joints")
    if slope_targets is not None and len(slope_targets) != n_axes:
        raise ValueError("fit_couplings needs one slope target per function")
    return start


def _shape_values(t: FloatArray, t0: float, shape: FloatArray) -> FloatArray:
    """The inner polynomial Σ_i shape[i] T_{i+1}(t), minus its value at t0."""
    c = np.concatenate([[0.0], shape])
    return _CHEB.chebval(t, c) - _CHEB.chebval(t0, c)


def unit_flat(flat: FloatArray) -> FloatArray:
    """Flat shapes with each row of unit norm: a shape's length is free (its inner joint is
    scaled afterwards), and left free it carries round-off from one search into the next."""
    return np.concatenate(unit_rows(flat)) if flat.size else flat


def unit_rows(flat: FloatArray) -> list[FloatArray]:
    """Flat shapes (4L,) as L rows of unit norm."""
    c = flat.reshape(-1, 4)
    return list(c / np.maximum(np.linalg.norm(c, axis=1), 1e-300)[:, None])


def unit_shape(t: FloatArray, t0: float, shape: FloatArray) -> tuple[FloatArray, float]:
    """The inner polynomial on t scaled to at most 1 in magnitude, and the scale N."""
    h = _shape_values(t, t0, shape)
    nk = max(float(np.max(np.abs(h))), 1e-300)
    return h / nk, nk


def unit_shape_slope(t: FloatArray, shape: FloatArray, nk: float) -> FloatArray:
    """d/dt of the inner polynomial scaled as :func:`unit_shape` scales it (by 1 / nk)."""
    return _CHEB.chebval(t, _CHEB.chebder(np.concatenate([[0.0], shape]))) / nk


def axis_basis_slope(t: FloatArray, t0: float, hs: Sequence[FloatArray], dhs: Sequence[FloatArray]) -> FloatArray:
    """d/dt of the columns of :func:`axis_basis` (``dhs``: d h_k / dt)."""
    v = t - t0
    cols = [j * v ** (j - 1) for j in range(1, 5)] + [j * h ** (j - 1) * dh for h, dh in zip(hs, dhs, strict=True)
                                                      for j in (2, 3, 4)]
    return np.stack(cols, axis=1)


def axis_basis(t: FloatArray, t0: float, hs: Sequence[FloatArray]) -> FloatArray:
    """Columns (m, 4 + 3K) of one axis's fit at t: (t - t0)^j, j = 1..4 (the main quartic), then
    h_k^j, j = 2..4, for each inner shape h_k it has an outer joint of (h_k^1 is a quartic
    vanishing at t0, already in the main quartic's span)."""
    v = t - t0
    cols = [v ** j for j in range(1, 5)] + [h ** j for h in hs for j in (2, 3, 4)]
    return np.stack(cols, axis=1)


class ShapeSearch:
    """Variable projection for the inner shapes: for shapes θ (L, 4) (Chebyshev coefficients of
    T_1..T_4 in t, each scaled by |θ_l|, which the fit does not depend on), the weighted
    least-squares residuals of every axis's best linear coefficients, stacked, and their
    Jacobian in Kaufman's approximation, for a Levenberg-Marquardt search. ``sw`` (per axis,
    (m,)) turns least squares towards minimax (Lawson's iteration)."""

    def __init__(self, t: FloatArray, t0: float, fs: Sequence[FloatArray], uses: Sequence[Sequence[int]],
                 rows: FloatArray | None = None):
        #: fixed weight of each sample (the range's margin counts less), times ``sw``
        self.rows = np.ones_like(t) if rows is None else np.asarray(rows, dtype=float)
        self.V = np.stack([(t - t0) ** j for j in range(1, 5)], axis=1)
        self.phi = np.stack([_CHEB.chebval(t, np.eye(5)[i]) - _CHEB.chebval(t0, np.eye(5)[i])
                             for i in range(1, 5)], axis=1)
        self.fs = [np.asarray(f, dtype=float) for f in fs]
        self.uses = [list(u) for u in uses]
        self.sw = [np.ones_like(f) for f in self.fs]
        self._key: bytes | None = None

    def _solve(self, flat: FloatArray) -> None:
        key = flat.tobytes() + b"".join(w.tobytes() for w in self.sw)
        if key == self._key:
            return
        th = flat.reshape(-1, 4)
        norms = np.maximum(np.linalg.norm(th, axis=1), 1e-300)
        H = (self.phi @ th.T) / norms  # (m, L)
        self.H, self.th, self.norms = H, th, norms
        # axes with the same outer joints share their basis, and with the same weights its SVD
        # (every axis's, until Lawson's reweighting): computed once, the same numbers
        powers: dict[int, FloatArray] = {}  # inner k: its columns h_k^2..4, (m, 3)
        bases: dict[tuple[int, ...], tuple[FloatArray, FloatArray]] = {}  # uses: (A, column scales)
        factors: dict[tuple[tuple[int, ...], bytes], tuple[FloatArray, FloatArray, FloatArray]] = {}
        self.parts = []
        for f, u, sw in zip(self.fs, self.uses, self.sw, strict=True):
            sw = sw * self.rows
            uses = tuple(u)
            if uses not in bases:
                for k in u:
                    if k not in powers:
                        powers[k] = np.stack([H[:, k] ** j for j in (2, 3, 4)], axis=1)
                A = np.hstack([self.V] + [powers[k] for k in u])
                bases[uses] = (A, np.maximum(np.linalg.norm(A, axis=0), 1e-300))
            A, scale = bases[uses]
            weighted = (uses, sw.tobytes())
            if weighted not in factors:
                U, S, Vt = np.linalg.svd(A * sw[:, None] / scale, full_matrices=False)
                r = int(np.sum(S > S[0] * 1e-12))
                factors[weighted] = (U[:, :r], S[:r], Vt[:r])
            U, S, Vt = factors[weighted]
            c = (Vt.T @ ((U.T @ (sw * f)) / S)) / scale  # coefficients of the unscaled columns
            self.parts.append((A, U, S, Vt, scale, c, sw * (A @ c - f), sw))
        self._key = key

    def residual(self, flat: FloatArray) -> FloatArray:
        self._solve(flat)
        return np.concatenate([p[6] for p in self.parts])  # a new array: the caller may change it

    def errors(self, flat: FloatArray) -> list[FloatArray]:
        """Each axis's residual A c - f, weighted by the samples' fixed weights only."""
        self._solve(flat)
        return [self.rows * (p[0] @ p[5] - f) for p, f in zip(self.parts, self.fs, strict=True)]

    def jac(self, flat: FloatArray) -> FloatArray:
        """d residual / d θ, (Σ m, 4L): Golub and Pereyra's variable-projection derivative,
        P⊥ dA c - A⁺ᵀ dAᵀ r (r = A c - f), for the weighted, column-scaled basis."""
        self._solve(flat)
        L = self.H.shape[1]
        # per inner joint k, shared by the axes using it: d h_k / d θ_k (h = φ θ / |θ|, (m, 4))
        # and h_k^(j-1), j = 2..4
        dh_dth, h_powers = {}, {}
        for k in {k for u in self.uses for k in u}:
            h = self.H[:, k]
            unit = self.th[k] / self.norms[k]
            dh_dth[k] = (self.phi - h[:, None] * unit[None, :]) / self.norms[k]
            h_powers[k] = [h ** (j - 1) for j in (2, 3, 4)]
        blocks = []
        for (_, U, S, Vt, scale, c, res, sw), u in zip(self.parts, self.uses, strict=True):
            J = np.zeros((sw.size, 4 * L))
            for i, k in enumerate(u):
                cols = slice(4 + 3 * i, 7 + 3 * i)
                b = c[cols]
                dcol = np.stack([sw * j * hp for j, hp in zip((2, 3, 4), h_powers[k], strict=True)],
                                axis=1)  # d(weighted column)/dh
                g = (dcol @ b)[:, None] * dh_dth[k]  # dA c, (m, 4)
                first = g - U @ (U.T @ g)
                # A⁺ᵀ dAᵀ r: dA has nonzero columns only at this outer's 3 columns
                dAt_r = (dcol * res[:, None]).T @ dh_dth[k] / scale[cols][:, None]  # (3, 4)
                second = U @ ((Vt[:, cols] @ dAt_r) / S[:, None])
                J[:, 4 * k: 4 * k + 4] += first - second
            blocks.append(J)
        return np.vstack(blocks)


def levenberg_marquardt(search: ShapeSearch, x: FloatArray, iterations: int) -> FloatArray:
    """Minimise |search.residual(x)|^2 from x by Levenberg-Marquardt (Marquardt's diagonal
    scaling). Written out rather than scipy's MINPACK, whose steps differ in the last bit from
    run to run, which a search over many local minima turns into different fits of one model."""
    r, J = search.residual(x), search.jac(x)
    cost, lam = float(r @ r), 1e-3
    for _ in range(iterations):
        g, H = J.T @ r, J.T @ J
        d = np.diag(H).copy()
        d = np.maximum(d, 1e-12 * max(float(d.max()), 1e-300))
        try:
            step = np.linalg.solve(H + lam * np.diag(d), -g)
        except np.linalg.LinAlgError:
            lam *= 10.0
            continue
        x_new = x + step
        r_new = search.residual(x_new)
        cost_new = float(r_new @ r_new)
        if cost_new < cost:
            done = cost - cost_new <= 1e-9 * cost
            x, r, cost, lam = x_new, r_new, cost_new, max(lam / 3.0, 1e-12)
            J = search.jac(x)
            if done:
                break
        else:
            lam *= 4.0
            if lam > 1e12:
                break
    return x


def lp_bounded_minimax(A: FloatArray, f: FloatArray, n_outer: int, bound: float,
                       guard: tuple[FloatArray, FloatArray, FloatArray, float] | None = None
                       ) -> tuple[FloatArray, float] | None:
    """min_a max |A a - f| with Σ_j |a_kj| <= bound for each outer k (the 3 columns of outer k
    after the 4 main ones); A's columns are scaled to at most 1. (a, worst error) or None.

    ``guard`` (Ag (g, n), fg (g,), cap (g,), slack): rows that only need |Ag a - fg| <= cap +
    slack * (the worst error): capped far from where the error is minimised, never infeasible."""
    from scipy.optimize import linprog

    m, n = A.shape
    nb = 3 * n_outer
    ones = np.ones((m, 1))
    rows = [np.hstack([A, np.zeros((m, nb)), -ones]), np.hstack([-A, np.zeros((m, nb)), -ones])]
    rhs = [f, -f]
    if guard is not None and guard[0].shape[0]:
        Ag, fg, cap, slack = guard
        t_col = np.full((Ag.shape[0], 1), -float(slack))
        zeros = np.zeros((Ag.shape[0], nb))
        rows += [np.hstack([Ag, zeros, t_col]), np.hstack([-Ag, zeros, t_col])]
        rhs += [fg + cap, cap - fg]
    if nb:
        sel = np.zeros((nb, n))
        sel[:, 4:] = np.eye(nb)
        zero = np.zeros((nb, 1))
        rows += [np.hstack([sel, -np.eye(nb), zero]), np.hstack([-sel, -np.eye(nb), zero]),
                 np.hstack([np.zeros((n_outer, n)), np.kron(np.eye(n_outer), np.ones((1, 3))), np.zeros((n_outer, 1))])]
        rhs += [np.zeros(2 * nb), np.full(n_outer, bound)]
    cost = np.zeros(n + nb + 1)
    cost[-1] = 1.0
    # HiGHS's dual simplex sometimes stops on a numerical difficulty (status 4) at these tight
    # tolerances (a Leg6Dof9Musc patella fit did); its interior-point method then solves it
    for method in ("highs", "highs-ipm"):
        res = linprog(cost, A_ub=np.vstack(rows), b_ub=np.concatenate(rhs),
                      bounds=[(None, None)] * n + [(0, None)] * (nb + 1), method=method, options=_LP_OPTIONS)
        if res.status == 0:
            return res.x[:n], float(res.x[-1])
    return None


def power_shape(c: float, p: int) -> FloatArray:
    """Chebyshev coefficients T_1..T_4 of (t - c)^p (its constant term dropped)."""
    cheb = _CHEB.poly2cheb(_POLY.polypow([-c, 1.0], p))
    return np.concatenate([cheb, np.zeros(5 - cheb.size)])[1:5]


def shifted_power_series(cheb_shape: FloatArray, t0: float, half: float) -> FloatArray:
    """Power coefficients (5,) in (x - x0) of Σ_i shape[i] T_{i+1}(t) - (its value at t0), with
    t - t0 = (x - x0) / half."""
    p = _CHEB.cheb2poly(np.concatenate([[0.0], cheb_shape]))  # in t, lowest power first
    p = np.concatenate([p, np.zeros(5 - p.size)])
    shifted = np.zeros(5)  # p(t0 + v) = Σ_j shifted[j] v^j
    for i, pi in enumerate(p):
        for j in range(i + 1):
            shifted[j] += pi * math.comb(i, j) * t0 ** (i - j)
    shifted[0] = 0.0
    return shifted / half ** np.arange(5)
