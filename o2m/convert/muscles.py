"""Muscle mechanics: the parameters of a MuJoCo muscle actuator fitted to an OpenSim muscle.

MuJoCo's muscle (``<muscle>``, i.e. ``<general dyntype="muscle" gaintype="muscle"
biastype="muscle">``) has a rigid tendon: its force is a function of the actuator length
(here the MuJoCo tendon length, equal to OpenSim's muscle-tendon (MTU) length), the
lengthening velocity and the activation (``mju_muscleGain`` / ``mju_muscleBias``)::

    L0 = (lengthrange[1] - lengthrange[0]) / (range[1] - range[0])   # optimal length, m
    L  = range[0] + (length - lengthrange[0]) / L0                   # normalized length
    V  = velocity / (L0 * vmax)                                      # normalized velocity
    force = -F * (act * FL(L; lmin, lmax) * FV(V; fvmax) + FP(L; lmax, fpmax))

with FL a piecewise quadratic bump (0 outside ``[lmin, lmax]``, 1 at L = 1), FP zero below
L = 1, quadratic up to ``(1 + lmax) / 2`` where it reaches ``fpmax / 2``, linear beyond, and FV
quadratic from 0 (V = -1) through 1 (V = 0) up to ``fvmax``. :func:`o2m.mj.muscle.mujoco_muscle_force`
evaluates exactly this (the tests check it against ``mjData.actuator_force``).

:func:`fit_muscles` maps every muscle of an OpenSim model (Thelen2003Muscle,
Millard2012EquilibriumMuscle, Millard2012AccelerationMuscle, Schutte1993Muscle_Deprecated,
DeGrooteFregly2016Muscle, RigidTendonMuscle, Delp1990Muscle_Deprecated,
Thelen2003Muscle_Deprecated, MeyerFregly2016Muscle) to a :class:`MuscleParams`:

* ``lengthrange``: the smallest and largest MTU length OpenSim computes over random poses
  (every independent coordinate uniform in its range, seeded), the default pose, each
  coordinate at its range ends, and the range corners of the coordinates the muscle spans;
  leaving out the samples where OpenSim's path fails as a path and an island of lengths it
  reaches only through a step (:func:`o2m.convert.muscle_samples.length_island`).
* ``force`` = max isometric force; ``timeconst`` from OpenSim's activation dynamics.
* ``range, lmin, lmax, fpmax`` by bounded least squares so that MuJoCo's static force matches
  OpenSim's static-equilibrium tendon force over the lengthrange at activation 1 (active +
  passive) and 0 (passive). OpenSim's forces come from a *bench*: a copy of the model's
  muscles, each with its own straight two-point path along a slider, so that its MTU length is
  set exactly; in static equilibrium (zero velocity) a muscle's tendon force depends on its
  MTU length and activation only, so the bench reproduces the full model's force at any pose
  with that MTU length (the tests check this against the full model).
* ``vmax``, ``fvmax`` fitted to OpenSim's force-velocity curve at optimal length over the speeds
  movements reach (:data:`FV_FIT_RANGE`), treating the tendon as rigid (MTU velocity = fiber
  velocity / cos(pennation)).

The errors are percentages of the max isometric force, over 197 lengths spanning the
lengthrange (the fit uses every fourth one).
"""


from __future__ import annotations

import concurrent.futures as cf
import functools
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np

from o2m.convert.muscle_samples import MuscleSample, _PoseModel, measure_muscles, sample_lengths
from o2m.convert.muscle_types import MUJOCO_DEFAULTS, SUPPORTED_MUSCLES
from o2m.errors import ModelFileError
from o2m.mj.muscle import (
    MJMINVAL,
    active_force_length,
    force_velocity,
    mujoco_muscle_force,
    passive_force,
)
from o2m.osim.skeleton import Skipped
from o2m.parallel import worker_context

__all__ = [
    "MUJOCO_DEFAULTS",
    "SUPPORTED_MUSCLES",
    "FitResult",
    "MuscleParams",
    "error_summary",
    "fit_muscles",
]

#: The fit uses every FIT_STRIDE-th of the N_EVAL lengths OpenSim's forces are computed at (50 lengths).
FIT_STRIDE = 4
#: Random restarts of the length fit besides the two deterministic starts (more change the
#: bundled models' RMS errors by < 0.05 % of max isometric force).
N_RANDOM_STARTS = 2
#: The force (max isometric forces) at which the length fit saturates both models' forces
#: (:func:`_residuals`): an order of magnitude past any working force. Over their own coordinate
#: ranges the corpus' muscles stay below it but gait2392's quadratus femoris (12.4).
FIT_FORCE_CAP = 10.0

#: The length fit's prior: each parameter's distance from its start (MuJoCo's defaults, the range
#: from OpenSim's tendon slack and optimal fiber length), one x_scale unit of it counted as this
#: RMS error (max isometric forces). A muscle whose length varies little leaves lmin, lmax and
#: fpmax nearly undetermined; without a prior the solver stops anywhere in that flat valley, where
#: rounding puts it, and one model converted on two machines gets two sets of muscles
#: (docs/conversion.md, "Fits with a flat optimum").
FIT_PRIOR = 1e-5
#: The length fit's tolerances (scipy's ftol, xtol, gtol) and evaluation budget per start.
FIT_TOL = 1e-10
FIT_MAX_NFEV = 400

# Bounds of the fitted parameters: range[0], range width, lmin, lmax, fpmax; and their scales.
_X_SCALE = np.array([0.1, 0.1, 0.1, 0.1, 0.3])
_LOWER = np.array([0.0, 1e-3, 0.0, 1.0 + 1e-4, 1e-3])
_UPPER = np.array([4.0, 8.0, 1.0 - 1e-4, 6.0, 100.0])


# ---------------------------------------------------------------------------------------------
# Result type
# ---------------------------------------------------------------------------------------------


@dataclass
class MuscleParams:
    """Parameters of the MuJoCo muscle actuator for one OpenSim muscle, and how well it fits.

    ``force`` N; ``timeconst`` (activation, deactivation) s; ``range`` normalized operating
    lengths at ``lengthrange`` (m, MTU length); ``lmin, lmax, vmax, fpmax, fvmax`` as MuJoCo
    defines them. ``err_*_pct``: MuJoCo's static force minus OpenSim's static tendon force, in
    % of ``force``, max |.| and RMS over the lengthrange, at activation 1 (active) and 0
    (passive). ``cost`` and ``start_cost`` are the RMS (% of force, both activations together)
    of the fit and of its starting point (``start``), so ``cost <= start_cost``.
    ``lengths``, ``opensim_active``, ``opensim_passive`` hold OpenSim's tendon force (N,
    positive when pulling) at the evaluated MTU lengths (m); NaN where OpenSim found no
    equilibrium. ``velocity_rms_pct`` is the RMS error of the force-velocity fit (% of force at
    optimal length, over normalized fiber velocities within ±:data:`~o2m.convert.muscle_samples.FV_FIT_RANGE`).
    ``damping`` (N s/m): the tendon damping that stands for OpenSim's fiber damping (:func:`tendon_damping`).
    """

    name: str
    type: str
    force: float
    timeconst: np.ndarray
    range: np.ndarray
    lmin: float
    lmax: float
    vmax: float
    fpmax: float
    fvmax: float
    lengthrange: np.ndarray
    err_active_max_pct: float
    err_active_rms_pct: float
    err_passive_max_pct: float
    err_passive_rms_pct: float
    notes: list[str] = field(default_factory=list)
    cost: float = math.nan
    start_cost: float = math.nan
    start: dict[str, float] = field(default_factory=dict, repr=False)
    velocity_rms_pct: float = math.nan
    min_activation: float = 0.0
    default_activation: float = math.nan
    damping: float = 0.0
    lengths: np.ndarray | None = field(default=None, repr=False)
    opensim_active: np.ndarray | None = field(default=None, repr=False)
    opensim_passive: np.ndarray | None = field(default=None, repr=False)

    def mjcf_attributes(self) -> dict[str, str]:
        """Attributes of a MuJoCo ``<muscle>`` element (besides name and tendon)."""

        def fmt(v) -> str:
            return " ".join(f"{float(x):.10g}" for x in np.atleast_1d(v))

        attrs = {
            "timeconst": fmt(self.timeconst), "range": fmt(self.range), "force": fmt(self.force),
            "lmin": fmt(self.lmin), "lmax": fmt(self.lmax), "vmax": fmt(self.vmax),
            "fpmax": fmt(self.fpmax), "fvmax": fmt(self.fvmax), "lengthrange": fmt(self.lengthrange),
        }
        if self.min_activation > 0.0:
            attrs.update(actlimited="true", actrange=fmt([self.min_activation, 1.0]))
        return attrs

    def unloadable(self) -> str:
        """What MuJoCo would refuse of these parameters ("" when nothing): every number finite, the
        time constants, force, vmax, fpmax and fvmax at least mjMINVAL (MuJoCo: "positive ...
        required"), lmin < 1 < lmax and range[0] < range[1]. Properties far out of scale (an optimal
        fiber length of 1e-300 m) fit to such parameters."""
        numbers = {"timeconst": np.min(self.timeconst), "force": self.force, "vmax": self.vmax,
                   "fpmax": self.fpmax, "fvmax": self.fvmax}
        if not all(np.all(np.isfinite(v)) for v in [*numbers.values(), self.range, self.lmin, self.lmax,
                                                     self.lengthrange]):
            return "a number that is not finite"
        small = [f"{k} {float(v):g}" for k, v in numbers.items() if v < MJMINVAL]
        if small:
            return f"{', '.join(small)} (MuJoCo needs at least {MJMINVAL:g})"
        if not (self.lmin < 1 < self.lmax and self.range[0] < self.range[1]):
            return f"lmin {self.lmin:g}, lmax {self.lmax:g}, range {self.range.tolist()}"
        return ""

    def apply_to(self, actuator) -> None:
        """Make a ``mujoco.MjsActuator`` this muscle (``set_to_muscle`` plus ``lengthrange``)."""
        actuator.set_to_muscle(
            timeconst=[float(t) for t in self.timeconst], tausmooth=0.0,
            range=[float(r) for r in self.range], force=float(self.force), scale=200.0,
            lmin=float(self.lmin), lmax=float(self.lmax), vmax=float(self.vmax),
            fpmax=float(self.fpmax), fvmax=float(self.fvmax),
        )
        actuator.lengthrange = [float(v) for v in self.lengthrange]
        if self.min_activation > 0.0:
            # OpenSim's minimum activation clamps the activation its force uses, not the state:
            # MuJoCo clamps the state itself (actrange), which gives the same force.
            actuator.actlimited = mujoco.mjtLimited.mjLIMITED_TRUE
            actuator.actrange = [float(self.min_activation), 1.0]


class FitResult(dict):
    """``{muscle name: MuscleParams}`` in model order; ``skipped`` lists the muscles of
    unsupported types (as :class:`o2m.skeleton.Skipped`), ``timings`` the seconds per stage."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.skipped: list[Skipped] = []
        self.timings: dict[str, float] = {}


# ---------------------------------------------------------------------------------------------
# Fitting (pure numpy/scipy; runs in worker processes)
# ---------------------------------------------------------------------------------------------


def _model_forces(x, s, a_min) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's static force (max isometric forces) at activation 1 and at ``a_min``, for x =
    (range[0], range width, lmin, lmax, fpmax) at lengths s (0..1 across the lengthrange)."""
    r0, w, lmin, lmax, fpmax = x
    L = r0 + s * w
    fp = passive_force(L, lmax, fpmax)
    fl = active_force_length(L, lmin, lmax)
    return fl + fp, a_min * fl + fp


def _residuals(x, s, ya, yp, ma, mp, a_min, cap) -> np.ndarray:
    """Residuals (MuJoCo minus OpenSim, in max isometric forces) at activation 1 then at the
    lowest activation ``a_min`` (OpenSim's minimum activation, 0 for most muscle types), both
    forces saturated at ``cap`` (:func:`_saturation`)."""
    fa, fp = _model_forces(x, s, a_min)
    return np.concatenate([(np.minimum(fa, cap) - np.minimum(ya, cap))[ma],
                           (np.minimum(fp, cap) - np.minimum(yp, cap))[mp]])


def _saturation(t: MuscleSample) -> float:
    """Where the length fit, and the errors reported of it, saturate both models' forces (max
    isometric forces): at :data:`FIT_FORCE_CAP` for a muscle OpenSim pulls harder than that at
    some length the fit uses, nowhere (inf) for the others. A coordinate range far wider than the
    joint moves (a free joint's default ±1 m) stretches a muscle to many optimal fiber lengths,
    where OpenSim's passive force reaches 100 max isometric forces, which MuJoCo's passive curve
    does not follow; unsaturated, those lengths outweigh the ones the muscle works at."""
    y = np.concatenate([t.active[::FIT_STRIDE], t.passive[::FIT_STRIDE]]) / t.force
    y = y[np.isfinite(y)]
    return FIT_FORCE_CAP if y.size and float(np.max(y)) > FIT_FORCE_CAP else math.inf


def _jacobian(x, s, ya, yp, ma, mp, a_min, cap) -> np.ndarray:
    """d residuals / d x of :func:`_residuals` (the derivatives of MuJoCo's piecewise curves)."""
    r0, w, lmin, lmax, fpmax = x
    L = r0 + s * w
    a, b = 0.5 * (lmin + 1.0), 0.5 * (1.0 + lmax)
    dn, up = max(MJMINVAL, 1.0 - lmin), max(MJMINVAL, lmax - 1.0)
    inside = (L >= lmin) & (L <= lmax)
    lo_half, hi_half = L <= 1.0, L > 1.0
    # active curve: pieces [lmin, a], (a, 1], (1, b], (b, lmax]; x_k as in mju_muscleGainLength
    xl = np.where(L <= a, 2 * (L - lmin) / dn, 2 * (1.0 - L) / dn)
    xh = np.where(L <= b, 2 * (L - 1.0) / up, 2 * (lmax - L) / up)
    dfl_dL = np.where(inside, np.where(lo_half, xl * 2 / dn, -xh * 2 / up), 0.0)
    dfl_dlmin = np.where(inside & lo_half, xl * 2 * (L - 1.0) / dn**2, 0.0)
    dfl_dlmax = np.where(inside & hi_half, xh * 2 * (L - 1.0) / up**2, 0.0)
    # passive curve
    h = 0.5 * up
    xq = (L - 1.0) / h
    quad = L <= b
    dfp_dL = np.where(hi_half, np.where(quad, fpmax * xq / h, fpmax / h), 0.0)
    dfp_dlmax = np.where(hi_half, -fpmax * (L - 1.0) / (2 * h * h) * np.where(quad, xq, 1.0), 0.0)
    dfp_dfpmax = np.where(hi_half, np.where(quad, 0.5 * xq * xq, 0.5 + (L - b) / h), 0.0)
    ja = np.column_stack([dfl_dL + dfp_dL, (dfl_dL + dfp_dL) * s, dfl_dlmin, dfl_dlmax + dfp_dlmax, dfp_dfpmax])
    jp = np.column_stack([a_min * dfl_dL + dfp_dL, (a_min * dfl_dL + dfp_dL) * s, a_min * dfl_dlmin,
                          a_min * dfl_dlmax + dfp_dlmax, dfp_dfpmax])
    fa, fp = _model_forces(x, s, a_min)  # saturated forces do not move
    return np.concatenate([ja[ma] * (fa[ma] < cap)[:, None], jp[mp] * (fp[mp] < cap)[:, None]])


def _start_point(t: MuscleSample) -> np.ndarray:
    """MuJoCo's defaults with ``range`` from OpenSim's tendon slack and optimal fiber length:
    the normalized fiber length of a rigid tendon, linearized at optimal length,
    L = 1 + (l - lts - lopt cos a) cos a / lopt."""
    ca = math.cos(t.alpha)
    r = 1.0 + (t.lengthrange - t.lts - t.lopt * ca) * ca / t.lopt
    x = np.array([r[0], r[1] - r[0], MUJOCO_DEFAULTS["lmin"], MUJOCO_DEFAULTS["lmax"], MUJOCO_DEFAULTS["fpmax"]])
    return np.clip(x, _LOWER, _UPPER)


def _fit_length(t: MuscleSample, cap: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    from scipy.optimize import least_squares

    idx = np.arange(0, len(t.lengths), FIT_STRIDE)
    lengths = t.lengths[idx]
    ya, yp = t.active[idx] / t.force, t.passive[idx] / t.force
    ma, mp = np.isfinite(ya), np.isfinite(yp)
    s = (lengths - t.lengthrange[0]) / max(MJMINVAL, t.lengthrange[1] - t.lengthrange[0])
    args = (s, ya, yp, ma, mp, t.min_activation, cap)

    x_start = _start_point(t)
    # the prior's residuals: each parameter's distance from the start, in x_scale units, counted as
    # FIT_PRIOR max isometric forces at every sample (see FIT_PRIOR)
    n_fit = max(1, int(ma.sum() + mp.sum()))
    prior = FIT_PRIOR * math.sqrt(n_fit) / _X_SCALE

    def residuals(x, *a):
        return np.concatenate([_residuals(x, *a), prior * (x - x_start)])

    def jacobian(x, *a):
        return np.vstack([_jacobian(x, *a), np.diag(prior)])

    def cost(x):
        r = residuals(x, *args)
        return float(r @ r)

    def data_cost(x):
        r = _residuals(x, *args)
        return float(r @ r)
    default = np.clip(np.array([MUJOCO_DEFAULTS["range"][0], MUJOCO_DEFAULTS["range"][1] - MUJOCO_DEFAULTS["range"][0],
                                MUJOCO_DEFAULTS["lmin"], MUJOCO_DEFAULTS["lmax"], MUJOCO_DEFAULTS["fpmax"]]),
                      _LOWER, _UPPER)
    rng = np.random.default_rng(t.seed)  # the same restarts for every muscle: same data, same fit
    starts = [x_start, default]
    for _ in range(N_RANDOM_STARTS):
        x = x_start.copy()
        x[0] = x_start[0] + rng.normal(0.0, 0.15)
        x[1] = x_start[1] * math.exp(rng.normal(0.0, 0.3))
        x[2] = rng.uniform(0.2, 0.8)
        x[3] = rng.uniform(1.2, 2.4)
        x[4] = math.exp(rng.uniform(math.log(0.1), math.log(10.0)))
        starts.append(np.clip(x, _LOWER, _UPPER))
    best, best_cost = x_start, cost(x_start)
    if ma.any() or mp.any():
        for x0 in starts:
            try:
                res = least_squares(residuals, x0, jac=jacobian, bounds=(_LOWER, _UPPER), args=args,
                                    method="trf", x_scale=_X_SCALE, max_nfev=FIT_MAX_NFEV,
                                    ftol=FIT_TOL, xtol=FIT_TOL, gtol=FIT_TOL)
            except ValueError:
                continue
            c = cost(res.x)
            if c < best_cost:
                best, best_cost = res.x, c
    return best, x_start, 100 * math.sqrt(data_cost(best) / n_fit), 100 * math.sqrt(data_cost(x_start) / n_fit)


@functools.lru_cache(maxsize=64)
def _fv_shape(u_bytes: bytes, fv_bytes: bytes) -> tuple[float, float, float]:
    """(c, fvmax, RMS) of the MuJoCo force-velocity curve FV(c u; fvmax) closest to OpenSim's
    fv(u) in least squares, u = normalized fiber velocity."""
    from scipy.optimize import least_squares

    u, fv = np.frombuffer(u_bytes), np.frombuffer(fv_bytes)
    ok = np.isfinite(fv)
    u, fv = u[ok], fv[ok]

    def res(p):
        return force_velocity(p[0] * u, p[1]) - fv

    lo, hi = np.array([0.2, 1.0]), np.array([5.0, 3.0])
    best, best_cost = None, math.inf
    for start in (np.array([1.0, MUJOCO_DEFAULTS["fvmax"]]), np.array([1.5, 1.6])):
        r = least_squares(res, start, bounds=(lo, hi), method="trf")
        cst = float(r.fun @ r.fun)
        if cst < best_cost:
            best, best_cost = r.x, cst
    return float(best[0]), float(best[1]), 100 * math.sqrt(best_cost / max(1, len(u)))


def _fit_velocity(t: MuscleSample, L0: float) -> tuple[float, float, float]:
    """vmax, fvmax and the RMS error (% of force) of MuJoCo's force-velocity curve against
    OpenSim's, over normalized fiber velocities ±FV_FIT_RANGE, taking the tendon as rigid: the MTU
    lengthens at fiber velocity / cos(pennation at optimal length)."""
    c, fvmax, rms = _fv_shape(np.ascontiguousarray(t.fv_u, dtype=float).tobytes(),
                              np.ascontiguousarray(t.fv, dtype=float).tobytes())
    mtu_vmax = t.vmax_os * t.lopt / max(math.cos(t.alpha), 1e-6)  # m/s at OpenSim's max fiber speed
    return float(mtu_vmax / max(MJMINVAL, L0 * c)), fvmax, rms


def _errors(p: MuscleParams, t: MuscleSample, cap: float) -> None:
    """``p``'s errors against OpenSim at every evaluated length, forces saturated at the fit's ``cap``."""
    fa = -mujoco_muscle_force(p, t.lengths, 0.0, 1.0) / t.force
    fp = -mujoco_muscle_force(p, t.lengths, 0.0, p.min_activation) / t.force
    ea = (np.minimum(fa, cap) - np.minimum(t.active / t.force, cap)) * 100
    ep = (np.minimum(fp, cap) - np.minimum(t.passive / t.force, cap)) * 100
    ea, ep = ea[np.isfinite(ea)], ep[np.isfinite(ep)]
    p.err_active_max_pct = float(np.max(np.abs(ea))) if ea.size else math.nan
    p.err_active_rms_pct = float(np.sqrt(np.mean(ea**2))) if ea.size else math.nan
    p.err_passive_max_pct = float(np.max(np.abs(ep))) if ep.size else math.nan
    p.err_passive_rms_pct = float(np.sqrt(np.mean(ep**2))) if ep.size else math.nan


def tendon_damping(t: MuscleSample) -> float:
    """MuJoCo tendon damping (N s/m) for OpenSim's fiber damping term ``fiber_damping · F · v_f /
    (vmax · lopt)``: with a rigid tendon the fiber moves ``cos α`` times as fast as the tendon and
    pulls on it ``cos α`` times its force, so ``b = fiber_damping · F cos²α / (vmax · lopt)``, α
    taken at the optimal fiber length (MuJoCo's muscles have no damping of their own)."""
    if t.fiber_damping <= 0.0:
        return 0.0
    return t.fiber_damping * t.force * math.cos(t.alpha) ** 2 / (t.vmax_os * t.lopt)


def _fit_one(t: MuscleSample) -> MuscleParams:
    cap = _saturation(t)
    x, x0, cost, start_cost = _fit_length(t, cap)
    notes = list(t.notes)
    if math.isfinite(cap):
        notes.append(f"OpenSim's force passes {FIT_FORCE_CAP:g} max isometric forces within the length range: the "
                     f"fit and its errors count any force above that as {FIT_FORCE_CAP:g}")
    r0, w, lmin, lmax, fpmax = (float(v) for v in x)
    rng = np.array([r0, r0 + w])
    L0 = (t.lengthrange[1] - t.lengthrange[0]) / w
    vmax, fvmax, vel_rms = _fit_velocity(t, L0)
    p = MuscleParams(
        name=t.name, type=t.type, force=t.force, timeconst=np.array(t.timeconst, dtype=float), range=rng,
        lmin=lmin, lmax=lmax, vmax=vmax, fpmax=fpmax, fvmax=fvmax, lengthrange=t.lengthrange.copy(),
        err_active_max_pct=math.nan, err_active_rms_pct=math.nan, err_passive_max_pct=math.nan,
        err_passive_rms_pct=math.nan, notes=notes, cost=cost, start_cost=start_cost,
        start={"range0": float(x0[0]), "range1": float(x0[0] + x0[1]), "lmin": float(x0[2]),
               "lmax": float(x0[3]), "fpmax": float(x0[4])},
        velocity_rms_pct=vel_rms, min_activation=t.min_activation, default_activation=t.default_activation,
        damping=tendon_damping(t), lengths=t.lengths,
        opensim_active=t.active, opensim_passive=t.passive,
    )
    _errors(p, t, cap)
    return p


# ---------------------------------------------------------------------------------------------
# The driver
# ---------------------------------------------------------------------------------------------


def _supported(pm: _PoseModel, result: FitResult) -> list[int]:
    """Indices of the muscles of ``pm`` whose types o2m maps; the others go to ``result.skipped``."""
    supported = [i for i, t in enumerate(pm.muscle_types) if t in SUPPORTED_MUSCLES]
    for i, t in enumerate(pm.muscle_types):
        if t not in SUPPORTED_MUSCLES:
            result.skipped.append(Skipped(t, pm.muscle_names[i], (
                f"muscle type {t} is not mapped to a MuJoCo muscle (o2m maps {', '.join(SUPPORTED_MUSCLES)})")))
    return supported


def _fit_all(tasks: list[MuscleSample], processes: int,
             get_pool: Callable[[], cf.ProcessPoolExecutor]) -> list[MuscleParams]:
    """The fit of every muscle, shared out on ``get_pool()`` when there are enough (the result is the same)."""
    if processes > 1 and len(tasks) >= 8:
        return list(get_pool().map(_fit_one, tasks, chunksize=max(1, len(tasks) // (4 * processes))))
    return [_fit_one(t) for t in tasks]


def fit_muscles(osim_path: str | os.PathLike, *, n_poses: int = 300, seed: int = 0, progress: bool = False,
                processes: int | None = None) -> FitResult:
    """Fit a MuJoCo muscle actuator to every muscle of the OpenSim model at ``osim_path``.

    Returns a :class:`FitResult`, a dict ``{muscle name: MuscleParams}`` in model order, whose
    ``skipped`` lists muscles of types o2m does not map (with the reason). ``n_poses`` random
    poses (seeded by ``seed``) plus the default pose, each coordinate's range ends and the range
    corners of each muscle's coordinates give the lengthranges. ``processes`` worker processes
    (default: all cores; 1 = none) share the pose sampling and the fits; the result does not
    depend on it. Raises :class:`o2m.errors.ModelFileError` when OpenSim cannot load the model.
    """
    import time

    from tqdm.auto import tqdm

    osim_path = os.fspath(osim_path)
    if not os.path.isfile(osim_path):
        raise ModelFileError(f"{osim_path}: no such file")
    processes = max(1, int(processes if processes is not None else (os.cpu_count() or 1)))
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    bar = tqdm(total=4, disable=not progress, desc=f"muscles {os.path.basename(osim_path)}")

    pm = _PoseModel(osim_path)
    result = FitResult()
    supported = _supported(pm, result)
    if not supported:
        result.timings = {"total": time.perf_counter() - t0}
        bar.close()
        return result

    pool: cf.ProcessPoolExecutor | None = None

    def get_pool() -> cf.ProcessPoolExecutor:
        nonlocal pool
        if pool is None:
            import scipy.optimize  # noqa: F401  (imported once here, inherited by forked workers)

            pool = cf.ProcessPoolExecutor(max_workers=processes, mp_context=worker_context())
        return pool

    try:
        # -- 1. MTU lengths over sampled poses ----------------------------------------------
        samples = sample_lengths(pm, osim_path, supported, n_poses, seed, processes, get_pool)
        timings["lengthrange"] = time.perf_counter() - t0
        bar.update()

        # -- 2. OpenSim's static forces on the bench, time constants, force-velocity --------
        t1 = time.perf_counter()
        tasks = measure_muscles(osim_path, pm, supported, samples, seed)
        timings["opensim_forces"] = time.perf_counter() - t1
        bar.update()

        # -- 3. fits -------------------------------------------------------------------------
        t2 = time.perf_counter()
        fitted = _fit_all(tasks, processes, get_pool)
        timings["fit"] = time.perf_counter() - t2
        bar.update()
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)

    for p in fitted:
        result[p.name] = p
    timings["total"] = time.perf_counter() - t0
    result.timings = timings
    bar.update()
    bar.close()
    return result


def error_summary(results: FitResult | dict[str, MuscleParams]) -> dict[str, float]:
    """Worst and RMS (over muscles and lengths) errors of a model's fits, % of max isometric force:
    keys ``active_max``, ``active_rms``, ``passive_max``, ``passive_rms`` and ``n``."""
    ps = list(results.values())
    if not ps:
        return {"n": 0, "active_max": math.nan, "active_rms": math.nan, "passive_max": math.nan,
                "passive_rms": math.nan}

    def agg(attr_max: str, attr_rms: str) -> tuple[float, float]:
        mx = max(getattr(p, attr_max) for p in ps)
        rms = math.sqrt(sum(getattr(p, attr_rms) ** 2 for p in ps) / len(ps))
        return float(mx), float(rms)

    am, ar = agg("err_active_max_pct", "err_active_rms_pct")
    pmx, pr = agg("err_passive_max_pct", "err_passive_rms_pct")
    return {"n": len(ps), "active_max": am, "active_rms": ar, "passive_max": pmx, "passive_rms": pr}
