"""Woltring's GCVSPL, ported by hand from Simbody (SimTKmath/src/gcvspl.cpp), for ``GCVSpline``.

OpenSim's ``GCVSpline`` is Simbody's ``SplineFitter``, which runs Woltring's Fortran GCVSPL
(K = 1, unit weights). o2m must evaluate a model's GCVSpline as OpenSim does, to round-off: with
``error_variance`` 0 GCVSPL only nearly interpolates (its search stops at a tiny smoothing
parameter), which no library reproduces (scipy's exact interpolant differs by up to ~1e-10),
so this is a line-by-line port: the same operations in the same order as the Fortran.
:class:`o2m.osim.functions.GCVSpline` calls :func:`gcvspl` for the coefficients and
:func:`gcv_splder` to evaluate them.

Band matrices are stored as lists of columns, column i (1..n) holding rows -w..w at [r + w];
lists are 1-based as in the Fortran (index 0 unused). Units: x in the spline's independent
variable (rad or m), y and c in its value's unit.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = ["gcvspl", "gcv_splder"]

FloatArray = NDArray[np.float64]


def _gcv_basis(m: int, n: int, x: list[float]) -> tuple[list[list[float]], float]:
    """BASIS: B(1-m:m-1, n) and its mean absolute row sum bl."""
    mm1 = m - 1
    B = [[0.0] * (2 * m - 1) for _ in range(n + 1)]
    if m == 1:
        for i in range(1, n + 1):
            B[i][0] = 1.0
        return B, 1.0
    mp1, m2 = m + 1, 2 * m
    for l_ in range(1, n + 1):
        q = [0.0] * (2 * m)  # q[j + mm1], j = -mm1..m
        q[mm1 + mm1] = 1.0
        if l_ != 1 and l_ != n:
            q[mm1 + mm1] = 1.0 / (x[l_ + 1] - x[l_ - 1])
        arg = x[l_]
        for i in range(3, m2 + 1):
            ir = mp1 - i
            v = q[ir + mm1]
            if l_ < i:
                for j in range(l_ + 1, i + 1):
                    u = v
                    v = q[ir + 1 + mm1]
                    q[ir + mm1] = u + (x[j] - arg) * v
                    ir += 1
            j1 = max(l_ - i + 1, 1)
            j2 = min(l_ - 1, n - i)
            if j1 <= j2:
                if i < m2:
                    for j in range(j1, j2 + 1):
                        yy = x[i + j]
                        u = v
                        v = q[ir + 1 + mm1]
                        q[ir + mm1] = u + (v - u) * (yy - arg) / (yy - x[j])
                        ir += 1
                else:
                    for j in range(j1, j2 + 1):
                        u = v
                        v = q[ir + 1 + mm1]
                        q[ir + mm1] = (arg - x[j]) * u + (x[i + j] - arg) * v
                        ir += 1
            nmip1 = n - i + 1
            if nmip1 < l_:
                for j in range(nmip1, l_):
                    u = v
                    v = q[ir + 1 + mm1]
                    q[ir + mm1] = (arg - x[j]) * u + v
                    ir += 1
        for j in range(-mm1, mm1 + 1):
            B[l_][j + mm1] = q[j + mm1]
    for i in range(1, mm1 + 1):
        for k in range(i, mm1 + 1):
            B[i][-k + mm1] = 0.0
            B[n + 1 - i][k + mm1] = 0.0
    bl = 0.0
    for i in range(1, n + 1):
        for k in range(-mm1, mm1 + 1):
            bl += abs(B[i][k + mm1])
    return B, bl / n


def _gcv_prep(m: int, n: int, x: list[float], w: list[float]) -> tuple[list[list[float]], float]:
    """PREP: WE(-m:m, n), the weighted divided-difference matrix, and its mean abs sum el."""
    m2, mp1 = 2 * m, m + 1
    m2m1, m2p1 = m2 - 1, m2 + 1
    nm = n - m
    we = [0.0] * (n * m2p1 + 1)  # 1-based flat, WE(k, i) = we[(k + m + 1) + (i - 1) * m2p1]
    f1 = -1.0
    if m != 1:
        for i in range(2, m + 1):
            f1 = -f1 * i
        for i in range(mp1, m2m1 + 1):
            f1 *= i
    i1, i2, jm = 1, m, mp1
    for j in range(1, n + 1):
        inc = m2p1
        if j > nm:
            f1 = -f1
            f = f1
        else:
            if j < mp1:
                inc = 1
                f = f1
            else:
                f = f1 * (x[j + m] - x[j - m])
        if j > mp1:
            i1 += 1
        if i2 < n:
            i2 += 1
        jj = jm
        ff = f
        yy = x[i1]
        i1p1 = i1 + 1
        for i in range(i1p1, i2 + 1):
            ff /= yy - x[i]
        we[jj] = ff
        jj += m2
        i2m1 = i2 - 1
        if i1p1 <= i2m1:
            for l_ in range(i1p1, i2m1 + 1):
                ff = f
                yy = x[l_]
                for i in range(i1, l_):
                    ff /= yy - x[i]
                for i in range(l_ + 1, i2 + 1):
                    ff /= yy - x[i]
                we[jj] = ff
                jj += m2
        ff = f
        yy = x[i2]
        for i in range(i1, i2m1 + 1):
            ff /= yy - x[i]
        we[jj] = ff
        jj += m2
        jm += inc
    kl = 1
    n2m = m2p1 * n + 1
    for i in range(1, m + 1):
        ku = kl + m - i
        for k in range(kl, ku + 1):
            we[k] = 0.0
            we[n2m - k] = 0.0
        kl += m2p1
    jj = 0
    el = 0.0
    for i in range(1, n + 1):
        wi = w[i]
        for _ in range(m2p1):
            jj += 1
            we[jj] /= wi
            el += abs(we[jj])
    WE = [[0.0] * m2p1 for _ in range(n + 1)]
    for i in range(1, n + 1):
        for k in range(-m, m + 1):
            WE[i][k + m] = we[(k + m + 1) + (i - 1) * m2p1]
    return WE, el / n


def _gcv_bandet(E: list[list[float]], m: int, n: int) -> None:
    """BANDET: in-place LU decomposition of the band matrix E(-m:m, n)."""
    if m <= 0:
        return
    for i in range(1, n + 1):
        di = E[i][m]
        mi = min(m, i - 1)
        if mi >= 1:
            for k in range(1, mi + 1):
                di -= E[i][-k + m] * E[i - k][k + m]
            E[i][m] = di
        lm = min(m, n - i)
        if lm >= 1:
            for l_ in range(1, lm + 1):
                dl = E[i + l_][-l_ + m]
                km = min(m - l_, i - 1)
                if km >= 1:
                    du = E[i][l_ + m]
                    for k in range(1, km + 1):
                        du -= E[i][-k + m] * E[i - k][l_ + k + m]
                        dl -= E[l_ + i][-l_ - k + m] * E[i - k][k + m]
                    E[i][l_ + m] = du
                E[i + l_][-l_ + m] = dl / di


def _gcv_bansol(E: list[list[float]], y: list[float], m: int, n: int) -> list[float]:
    """BANSOL: solve with the LU-decomposed band matrix; c (1-based, n)."""
    c = [0.0] * (n + 1)
    if m == 0:
        for i in range(1, n + 1):
            c[i] = y[i] / E[i][m]
        return c
    c[1] = y[1]
    for i in range(2, n + 1):
        mi = min(m, i - 1)
        dd = y[i]
        for l_ in range(1, mi + 1):
            dd -= E[i][-l_ + m] * c[i - l_]
        c[i] = dd
    c[n] /= E[n][m]
    for i in range(n - 1, 0, -1):
        mi = min(m, n - i)
        dd = c[i]
        for l_ in range(1, mi + 1):
            dd -= E[i][l_ + m] * c[i + l_]
        c[i] = dd / E[i][m]
    return c


def _gcv_trinv(Bw: list[list[float]], E: list[list[float]], m: int, n: int) -> float:
    """TRINV: trace of Bw * inverse(E) from the central 2m+1 bands of E^-1 (E overwritten)."""
    E[n][m] = 1.0 / E[n][m]
    for i in range(n - 1, 0, -1):
        mi = min(m, n - i)
        dd = 1.0 / E[i][m]
        for k in range(1, mi + 1):
            E[n][k + m] = E[i][k + m] * dd
            E[1][-k + m] = E[k + i][-k + m]
        dd += dd
        for j in range(mi, 0, -1):
            du = 0.0
            dl = 0.0
            for k in range(1, mi + 1):
                du -= E[n][k + m] * E[i + k][j - k + m]
                dl -= E[1][-k + m] * E[i + j][k - j + m]
            E[i][j + m] = du
            E[j + i][-j + m] = dl
            dd -= E[n][j + m] * dl + E[1][-j + m] * du
        E[i][m] = dd * 0.5
    dd = 0.0
    for i in range(1, n + 1):
        mn = -min(m, i - 1)
        mp = min(m, n - i)
        for k in range(mn, mp + 1):
            dd += Bw[i][k + m] * E[k + i][-k + m]
    for k in range(1, m + 1):
        E[n][k + m] = 0.0
        E[1][-k + m] = 0.0
    return dd


def _gcv_splc(m: int, n: int, y: list[float], wx: list[float], mode: int, val: float, p: float,
              eps: float, B: list[list[float]], WE: list[list[float]], el: float,
              stat: list[float]) -> tuple[float, list[float]]:
    """SPLC: fit for smoothing parameter p; returns (criterion, c 1-based)."""
    dp = p
    stat[4] = p
    pel = p * el
    if pel < eps:
        dp = eps / el
        stat[4] = 0.0
    if pel * eps > 1.0:
        dp = 1.0 / (el * eps)
        stat[4] = dp
    E = [[0.0] * (2 * m + 1) for _ in range(n + 1)]
    for i in range(1, n + 1):
        km = -min(m, i - 1)
        kp = min(m, n - i)
        for l_ in range(km, kp + 1):
            if abs(l_) == m:
                E[i][l_ + m] = dp * WE[i][l_ + m]
            else:
                E[i][l_ + m] = B[i][l_ + m - 1] + dp * WE[i][l_ + m]
    _gcv_bandet(E, m, n)
    c = _gcv_bansol(E, y, m, n)
    stat[3] = _gcv_trinv(WE, E, m, n) * dp
    trn = stat[3] / n
    esn = 0.0
    for i in range(1, n + 1):
        dt = -y[i]
        km = -min(m - 1, i - 1)
        kp = min(m - 1, n - i)
        for l_ in range(km, kp + 1):
            dt += B[i][l_ + m - 1] * c[i + l_]
        esn += dt * dt * wx[i] * 1.0
    esn /= n * 1
    stat[6] = esn / trn
    stat[1] = stat[6] / trn
    stat[2] = esn
    if abs(mode) != 3:
        stat[5] = stat[6] - esn
        ret = 0.0
        if abs(mode) == 2:
            ret = stat[1]
        if abs(mode) == 4:
            ret = abs(stat[3] - val)
    else:
        stat[5] = esn - val * (trn * 2.0 - 1.0)
        ret = stat[5]
    return ret, c


def gcvspl(x_: Sequence[float], y_: Sequence[float], m: int, md: int, val: float) -> list[float]:
    """GCVSPL with unit weights: natural spline coefficients c (n,) of half order m."""
    n = len(x_)
    x = [0.0, *map(float, x_)]
    y = [0.0, *map(float, y_)]
    wx = [1.0] * (n + 1)
    if m <= 0 or n < 2 * m:
        raise ValueError(f"GCVSpline of half order {m} needs at least {2 * m} points, got {n}")
    eps = 1e-15
    B, r1 = _gcv_basis(m, n, x)
    WE, el = _gcv_prep(m, n, x, wx)
    el /= r1
    stat = [0.0] * 7

    def splc(p: float) -> tuple[float, list[float]]:
        return _gcv_splc(m, n, y, wx, md, val, p, eps, B, WE, el, stat)

    if abs(md) == 1:
        return splc(val)[1][1:]
    budget = 10000  # the Fortran loops have no iteration limit; guard against pathological data
    r1 = 1.0 / el
    r2 = r1 * 2.0
    gf2 = splc(r2)[0]
    while True:  # L40: decrease p while the criterion decreases
        gf1 = splc(r1)[0]
        budget -= 1
        if gf1 > gf2:
            break
        if stat[4] <= 0.0 or budget <= 0:
            return splc(r1)[1][1:]
        r2, gf2 = r1, gf1
        r1 /= 2.0
    r3 = r2 * 2.0  # L50
    while True:  # L60: increase p while the criterion decreases
        gf3 = splc(r3)[0]
        budget -= 1
        if gf3 > gf2:
            break
        if stat[4] >= 999999999999999.88 or budget <= 0:
            return splc(r1)[1][1:]
        r2, gf2 = r3, gf3
        r3 *= 2.0
    r2, gf2 = r3, gf3  # L70: golden section search
    alpha = (r2 - r1) / 1.618033983
    r4 = r1 + alpha
    r3 = r2 - alpha
    gf3 = splc(r3)[0]
    gf4 = splc(r4)[0]
    while budget > 0:  # L80
        budget -= 1
        if gf3 <= gf4:
            r2, gf2 = r4, gf4
            err = (r2 - r1) / (r1 + r2)
            if err * err + 1.0 == 1.0 or err <= 1e-6:
                break
            r4, gf4 = r3, gf3
            alpha /= 1.618033983
            r3 = r2 - alpha
            gf3 = splc(r3)[0]
        else:
            r1, gf1 = r3, gf3
            err = (r2 - r1) / (r1 + r2)
            if err * err + 1.0 == 1.0 or err <= 1e-6:
                break
            r3, gf3 = r4, gf4
            alpha /= 1.618033983
            r4 = r1 + alpha
            gf4 = splc(r4)[0]
    r1 = (r1 + r2) * 0.5  # L90
    return splc(r1)[1][1:]  # L100


def gcv_splder(ider: int, m: int, t: FloatArray, x: list[float], c: list[float], l_: int) -> FloatArray:
    """SPLDER for all t (p,) lying in the same interval l_ (x[l_] <= t < x[l_+1], 0..n).

    x and c are 1-based lists.  Same operations as the Fortran, element-wise over t.
    """
    n = len(x) - 1
    m2 = 2 * m
    k = m2 - ider
    if k < 1:
        return np.zeros_like(t)
    tt = t
    mp1, npm, m2m1 = m + 1, n + m, m2 - 1
    k1, nk = k - 1, n - k
    lk1 = l_ - k + 1
    jl, ju, ii, ml = l_ + 1, l_ + m2, n - m2, -l_
    q: list = [0.0] * (m2 + 1)
    for j in range(jl, ju + 1):
        q[j + ml] = c[j - m] if mp1 <= j <= npm else 0.0
    if ider > 0:
        jl -= m2
        ml += m2
        for i in range(1, ider + 1):
            jl += 1
            ii += 1
            j1 = max(1, jl)
            j2 = min(l_, ii)
            mi = m2 - i
            j = j2 + 1
            if j1 <= j2:
                for _ in range(j1, j2 + 1):
                    j -= 1
                    jm = ml + j
                    q[jm] = (q[jm] - q[jm - 1]) / (x[j + mi] - x[j])
            if jl >= 1:
                continue
            i1 = i + 1
            j = ml + 1
            if i1 <= ml:
                for _ in range(i1, ml + 1):
                    j -= 1
                    q[j] = -q[j - 1]
        for j in range(1, k + 1):
            q[j] = q[j + ider]
    if k1 >= 1:
        for i in range(1, k1 + 1):
            nki = nk + i
            ir = k
            jj = l_
            ki = k - i
            nki1 = nki + 1
            if l_ >= nki1:
                for _ in range(nki1, l_ + 1):
                    q[ir] = q[ir - 1] + (tt - x[jj]) * q[ir]
                    jj -= 1
                    ir -= 1
            lk1i = lk1 + i
            j1 = max(1, lk1i)
            j2 = min(l_, nki)
            if j1 <= j2:
                for _ in range(j1, j2 + 1):
                    xjki = x[jj + ki]
                    z = q[ir]
                    q[ir] = z + (xjki - tt) * (q[ir - 1] - z) / (xjki - x[jj])
                    ir -= 1
                    jj -= 1
            if lk1i <= 0:
                jj = ki
                for _ in range(1, 1 - lk1i + 1):
                    q[ir] = q[ir] + (x[jj] - tt) * q[ir - 1]
                    jj -= 1
                    ir -= 1
    z = q[k]
    if ider > 0:
        for j in range(k, m2m1 + 1):
            z = z * j
    return np.broadcast_to(np.asarray(z, dtype=np.float64), t.shape).copy()

