"""Planning couplings beyond a quartic: which extra joints each coupled axis gets.

A coupled axis is a MuJoCo joint whose value (rad or m) is a non-linear function of an independent
coordinate (a skeleton transform axis, a coupled coordinate, a path-point carrier's slide). A
MuJoCo joint equality is a quartic of its driving joint; when that quartic misses its target, the
axis also gets extra joints of the same body on the same axis (inner joints, quartics of the
coordinate, and outer joints, quartics of an inner joint), whose values add to the axis's, fitted
with the coordinate's other coupled axes by :func:`o2m.convert.couplings.fit_couplings` within MuJoCo's
:data:`MAX_BODY_DOFS` degrees of freedom per body. Where a body would need more, the skeleton
builder puts its joint's slides on an intermediate body (:func:`plan_skeleton` chooses which).

Everything here is planning: the fits and the joints' names. :class:`~o2m.convert.builder.MjcfBuilder`
adds the joints and their equalities.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from o2m.convert.couplings import COUPLING_GAIN, CouplingFit, fit_couplings, polynomial_slope_errors
from o2m.convert.polyfit import FitError, fit_polynomial

#: Worst error a skeleton coupling (a coupled transform axis or a coupler) is fitted to, per
#: unit: 0.01 mm and 0.005 deg, a tenth of the skeleton's 0.1 mm / 0.05 deg budget. A plain
#: quartic within it stays a plain quartic; otherwise the coordinate's coupled axes get inner
#: and outer joints (:func:`o2m.convert.couplings.fit_couplings`) until they are within it, until more
#: joints stop helping, or until their bodies are full (:data:`MAX_BODY_DOFS`).
COUPLING_TARGET = {"m": 1e-5, "rad": float(np.deg2rad(0.005))}
#: Derivative target of a skeleton coupling (per unit of the axis, per unit of its coordinate), or
#: None: fitted to the value only (see :func:`o2m.convert.couplings.fit_couplings`'s ``slope_targets``).
#: A knee translation's derivative error is a moment-arm error of every knee muscle. None,
#: measured: with 2e-4 m/rad on the slides, Gait10dof18musc's knee translations reach 0.69 and
#: 0.51 mm/rad worst (1.16 and 1.44 fitted to the value) for 0.041 mm (0.035) and its
#: hamstrings' and gastrocnemius' moment-arm RMS falls from 0.24-0.32 to 0.19-0.24 mm (p95 of all
#: pairs 0.51 -> 0.50 mm); but Leg6Dof9Musc's plan changes (no intermediate bodies: 40 -> 33 dofs)
#: and its patella translations miss 0.1 mm (0.13 and 0.22 mm at 2e-4 and 1e-4 m/rad).
COUPLING_SLOPE_TARGET: dict[str, float | None] = {"m": None, "rad": None}
#: Skeleton couplings with extra joints are also fitted this fraction of their coordinate's range
#: beyond each end, with :data:`o2m.convert.couplings.COUPLING_MARGIN_SLACK` times the error allowed
#: there: a joint pressing into a soft limit leaves its range a little (Leg6Dof9Musc's knee,
#: swinging into its limit, went 0.026 rad past it), and a degree-16 fit of the range alone
#: leaves the spline fast (0.8 mm 0.05 rad beyond a knee's range). Farther out the extra
#: joints diverge much faster than a plain quartic: keep such coordinates within their range.
COUPLING_MARGIN = 0.02
#: How far beyond each end (a fraction of the range) their error is capped
#: (:func:`o2m.convert.couplings.fit_couplings`'s ``guard``); 0: not at all. OpenSim holds no
#: coordinate in its range (Gait10dof18musc's knee, driven by random excitations, goes 2.1 rad past
#: its 0.17 rad limit), where a fit of the range alone leaves the spline like a degree-16
#: polynomial. Measured on Gait10dof18musc (5 random-excitation sets, mean abs coordinate error /
#: right knee's): 0 gives 0.200 / 0.715 rad, 0.25 0.147 / 0.380 rad, 0.5 0.131 / 0.273 rad; but the
#: in-range poses then lose accuracy (Gait10dof18musc 0.045 -> 0.090 / 0.217 mm, Leg6Dof9Musc
#: 0.060 -> 0.23 mm, Leg39 0.062 -> 0.25 mm at 0.25), over the 0.1 mm target, so it is off.
COUPLING_GUARD = 0.0
#: Degrees of freedom MuJoCo allows one body ("more than 6 dofs in body" otherwise).
MAX_BODY_DOFS = 6
#: A coordinate's couplings are planned with a joint's translations and rotations on bodies of
#: their own (:meth:`MjcfBuilder._couplings_body`) when that brings the worst error, relative to
#: :data:`COUPLING_TARGET`, below this fraction of what the joints fit on one body reach (the
#: intermediate body weighs 1e-12 kg). 0.5 kept the one-body plans of the Jumper's and the soccer
#: kick's five-spline knees (tibia and patella each a hinge and two slides, one shared inner joint),
#: whose split plans reach 0.53-0.55 of their worst error: body frames 0.145 and 0.157 mm off
#: OpenSim; at 0.6 they split, 0.085 and 0.082 mm. The corpus models whose split plans were kept
#: or refused before (gait, Rajagopal, Hamner, ToyLanding, Leg6Dof9Musc, Leg39) have ratios
#: below 0.3 or at 1: their plans do not change.
COUPLING_SPLIT_GAIN = 0.6
#: The split plan's search (:func:`o2m.convert.couplings.fit_couplings`) is chaotic in its input's
#: round-off: Leg39's knee, its splines scaled by 1 + ε (|ε| <= 3e-14), reached 4.0 to 6.7 times its
#: target, so the split was kept in some runs and not in others. A split plan better than the
#: first that misses COUPLING_SPLIT_GAIN is searched again, up to SPLIT_RETRIES times, from the
#: axes scaled by 1 + k SPLIT_RESCALE (k = 1, 2: far below any tolerance, a 1 m axis moves by
#: 1e-13 m), and the best is kept: a restart of a non-convex search, as from other starts.
SPLIT_RETRIES = 2
SPLIT_RESCALE = 1e-13
#: Armature of each extra joint of a coupled axis, as a multiple of its main joint's own inertia
#: at the reference pose (the mass, or moment of inertia about the axis, of everything the joint
#: moves). Several joints along one axis of one body make the mass matrix singular without
#: armature, and an armature much lighter than the body makes their equalities soft: in
#: Gait2354 hanging under gravity, 0.01 kg let the knee translations sag 0.2 mm off their
#: equalities, the body's own inertia (5.3 kg) 0.01 mm, as the plain quartic's single joint.
#: The extra joints move a few millimetres (or a few hundredths of a radian) over their
#: coordinate's range, so this adds little to the coordinate's inertia (the report gives it).
COUPLING_ARMATURE = 1.0

#: Most coupled axes :func:`plan_group` plans together for path-point carriers
#: (:func:`chunks_by_key`): 8, the largest group of the corpus (Hamner's knees), whose plans stay
#: as they were. A coordinate moving more carrier slides (a model with hundreds of paths) has
#: them planned in chunks of at most :data:`CARRIER_SPLIT_CHUNK`, each chunk with inner joints of
#: its own.
CARRIER_CHUNK = 8
#: Most axes of one chunk when a coordinate's carrier axes are more than :data:`CARRIER_CHUNK`.
#: A plan's cost grows with the square of its axes (each axis that misses tries its own moves,
#: and each try refits every axis of the plan), so the cost per axis grows with the chunk size:
#: measured (CPU) on the 22 carrier axes of a 50-path synthetic model (benchmarks/scaling.py),
#: chunks of 2 axes (one carrier) 0.57 s per axis, of 4 1.7 s, of 8 3.8 s; their worst errors
#: 0.080, 0.078 and 0.078 mm, median 0.060, 0.045 and 0.041 mm, with 33, 37 and 43 extra joints.
CARRIER_SPLIT_CHUNK = 4

#: An extra joint of a coupled axis: (name, driving joint, equality coefficients, "inner" or "outer").
ExtraJoint = tuple[str, str, np.ndarray, str]


@dataclass
class CoupledAxis:
    """A skeleton axis (or coupled coordinate) that a non-linear function of a coordinate moves."""

    name: str  # its MuJoCo joint
    body: str
    kind: str  # "hinge" or "slide"
    base: str  # the independent coordinate driving it
    rel: Callable[[np.ndarray], np.ndarray]  # its value minus its reference value, of the base's value

    @property
    def units(self) -> str:
        return "rad" if self.kind == "hinge" else "m"


@dataclass
class PlannedAxis:
    """One coupled axis of a coordinate's :class:`~o2m.convert.couplings.CouplingFit`."""

    fit: CouplingFit
    index: int  # the axis's index in the fit
    axes: list[CoupledAxis]  # every axis of the fit, in order
    inner_names: list[str]  # the fit's inner joints, in order
    lo: float
    hi: float
    #: armature (kg or kg m²) of each extra joint, set when planned (path-point carriers); None:
    #: set by :func:`o2m.convert.inertials.set_extra_armature` once the skeleton is built
    armature: float | None = None


def _inner_names(fit: CouplingFit, group: list[CoupledAxis]) -> list[str]:
    """The MuJoCo names of a fit's inner joints: ``<host joint>_inner<k>``."""
    counts: dict[str, int] = {}
    names = []
    for h in fit.hosts:
        counts[group[h].name] = counts.get(group[h].name, 0) + 1
        names.append(f"{group[h].name}_inner{counts[group[h].name]}")
    return names


def _extra_slopes(planned: PlannedAxis, x: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, int]]:
    """d joint / d coordinate at x of every extra joint of a coordinate's plan, by name, and the
    inner joint (index) each outer joint is driven by."""
    poly = np.polynomial.polynomial
    fit = planned.fit
    inner = fit.inner_values(x)
    dinner = [poly.polyval(x - fit.x0, poly.polyder(c)) for c in fit.inners]
    slopes: dict[str, np.ndarray] = {}
    driver: dict[str, int] = {}
    for i, a in enumerate(planned.axes):
        for n, (k, c) in enumerate(fit.axes[i].outers):
            name = f"{a.name}_outer{n + 1}"
            slopes[name] = poly.polyval(inner[k], poly.polyder(c)) * dinner[k]
            driver[name] = k
    for k, name in enumerate(planned.inner_names):
        slopes[name] = dinner[k]
    return slopes, driver


def planned_axes(fit: CouplingFit, group: list[CoupledAxis], lo: float, hi: float,
                 armature: float | None = None) -> dict[str, PlannedAxis]:
    """Each axis of ``group`` with its place in the coordinate's ``fit``, by MuJoCo joint name."""
    inner_names = _inner_names(fit, group)
    return {a.name: PlannedAxis(fit, i, group, inner_names, lo, hi, armature) for i, a in enumerate(group)}


def extra_joints(joint: str, planned: PlannedAxis) -> list[ExtraJoint]:
    """The extra joints of coupled joint ``joint``: (name, driving joint, equality
    coefficients, role) for each inner joint it carries (``<joint>_inner<k>``, driven by the
    coordinate) and each outer joint (``<joint>_outer<k>``, driven by an inner joint)."""
    fit, i = planned.fit, planned.index
    base = planned.axes[i].base
    out = [(planned.inner_names[k], base, fit.inners[k], "inner") for k in range(fit.n_inner) if fit.hosts[k] == i]
    out += [(f"{joint}_outer{n + 1}", planned.inner_names[k], c, "outer")
            for n, (k, c) in enumerate(fit.axes[i].outers)]
    return out


def added_inertia(planned: PlannedAxis, joints: list[str]) -> float:
    """The most (over the coordinate's range) that extra joints ``joints`` of ``planned``, each
    with its planned armature, add to the coordinate's inertia: Σ armature (d joint / d coordinate)²."""
    x = np.linspace(planned.lo, planned.hi, 2001)
    slopes = _extra_slopes(planned, x)[0]
    return float(np.max(sum(planned.armature * slopes[n] ** 2 for n in joints)))


def quartic_coupling(rel: Callable[[np.ndarray], np.ndarray], lo: float, hi: float, x0: float, joint: str,
                     base: str, units: str, base_units: str) -> tuple[np.ndarray, dict]:
    """The plain quartic by which joint ``joint`` (``rel``: its value relative to its reference, in
    ``units``) follows coordinate ``base`` (in ``base_units``), fitted over [lo, hi] and exact at
    ``x0``: its equality coefficients, and its approximation's fields (what, errors, units)."""
    slope_units = f"{units}/{base_units}"
    fit = fit_polynomial(rel, lo, hi, x0, degree=4, exact_at_x0=True)
    coef = np.asarray(fit.coef, dtype=float)
    s_max, s_rms = polynomial_slope_errors(rel, coef, lo, hi, x0)
    return coef, dict(
        what=f"MuJoCo joint '{joint}' follows '{base}' by a quartic fitted over [{lo:.4g}, {hi:.4g}]",
        max_error=float(fit.max_error), units=units,
        detail=f"rms {fit.rms_error:.3g} {units}; slope error {s_max:.3g} (rms {s_rms:.3g}) {slope_units}",
        joint=joint, slope_error=s_max, slope_rms=s_rms, slope_units=slope_units)


def planned_coupling(planned: PlannedAxis, joint: str, base: str, lo: float, hi: float, units: str,
                     base_units: str) -> tuple[np.ndarray, list[ExtraJoint], dict]:
    """The planned main quartic by which joint ``joint`` follows coordinate ``base``: its equality
    coefficients, its extra joints (:func:`extra_joints`), and its approximation's fields."""
    slope_units = f"{units}/{base_units}"
    cfit, ax = planned.fit, planned.fit.axes[planned.index]
    coef = np.asarray(ax.main, dtype=float)
    what = f"MuJoCo joint '{joint}' follows '{base}' by a quartic fitted over [{lo:.4g}, {hi:.4g}]"
    detail = f"rms {ax.rms_error:.3g} {units}; slope error {ax.slope_error:.3g} (rms {ax.slope_rms:.3g}) " \
             f"{slope_units}"
    extra = extra_joints(joint, planned)
    if extra:
        what = (f"MuJoCo joint '{joint}' and its extra joints {', '.join(e[0] for e in extra)} follow "
                f"'{base}' by a {cfit.structure(planned.index)}, fitted over [{lo:.4g}, {hi:.4g}]"
                + (f" to {ax.target:.3g} {units} and a slope error of {ax.slope_target:.3g} {slope_units}"
                   if np.isfinite(ax.slope_target) else ""))
        margin = planned.fit.margin
        detail += (f"; a plain quartic: {ax.quartic_error:.3g} {units}, slope error "
                   f"{ax.quartic_slope_error:.3g} (rms {ax.quartic_slope_rms:.3g}) {slope_units}; up to "
                   f"{margin:.3g} {base_units} beyond the range: {ax.margin_error:.3g} {units}; the extra "
                   f"joints move through at most {ax.amplitude:.3g} {units}")
    return coef, extra, dict(what=what, max_error=float(ax.max_error), units=units, detail=detail, joint=joint,
                             slope_error=float(ax.slope_error), slope_rms=float(ax.slope_rms),
                             slope_units=slope_units)


def extra_armature(planned: Mapping[str, PlannedAxis], extras_of: Mapping[str, list[str]],
                   own_inertia: Mapping[str, float]) -> tuple[dict[str, float], dict[str, float]]:
    """The armature (kg or kg m²) of every extra joint of the skeleton's coupled joints, and how
    much each main joint's extra joints add to its coordinate's inertia at most (Σ armature
    (d joint / d coordinate)² over the coordinate's range), by main joint.

    ``extras_of``: each main joint's extra joints; ``own_inertia``: each main joint's own inertia
    at the reference pose (its armature left out). Each extra joint gets :data:`COUPLING_ARMATURE`
    times it, and an inner joint at least the largest armature of the outer joints it drives
    (MuJoCo softens their equalities by the inner joint's inverse weight; see :func:`plan_group`)."""
    armature: dict[str, float] = {}
    for main, names in extras_of.items():
        for name in names:
            armature[name] = COUPLING_ARMATURE * own_inertia[main]
    slopes: dict[str, np.ndarray] = {}  # each extra joint's d joint / d coordinate over the range
    for p in {id(p.axes): p for p in planned.values()}.values():  # each coordinate's once
        own, driver = _extra_slopes(p, np.linspace(p.lo, p.hi, 2001))
        slopes.update(own)
        driven = [0.0] * p.fit.n_inner  # the largest armature of each inner joint's outer joints
        for name, k in driver.items():
            driven[k] = max(driven[k], armature[name])
        for k, name in enumerate(p.inner_names):
            armature[name] = max(armature[name], driven[k])
    added = {main: float(np.max(sum(armature[n] * slopes[n] ** 2 for n in names)))
             for main, names in extras_of.items()}
    return armature, added


def plan_skeleton(axes: list[CoupledAxis], dofs: Mapping[tuple[str, str], int], weights: Mapping[str, float],
                  ranges: Mapping[str, tuple[float, float]], refs: Mapping[str, float], *,
                  targets: Mapping[str, float], slope_targets: Mapping[str, float | None],
                  cache: dict | None = None) -> tuple[dict[str, PlannedAxis], dict[str, tuple[int, int]]]:
    """Fit every coordinate's non-linear skeleton couplings together (they may share inner
    joints) and choose their joints, within :data:`MAX_BODY_DOFS` per body; then choose the
    bodies whose joint's translations get a body of their own.

    ``axes``: the coupled axes in build order; ``dofs``: each body's moving axes by (body,
    ``"slide"`` or ``"hinge"``); ``weights``: each axis's own inertia (:func:`plan_group`);
    ``ranges``, ``refs``: each coordinate's fitting range and reference value; ``targets`` and
    ``slope_targets``: by unit (``"m"``, ``"rad"``). Returns the plan of each axis by MuJoCo
    joint name, and the bodies to split with the (slides, hinges) their joint then has.

    Each coordinate is planned first with every body's joints on that body
    (:func:`plan_group`). When an axis then still misses its target, it is planned again with
    a joint's translations and its rotations counted apart, each within :data:`MAX_BODY_DOFS`
    (an intermediate body would then carry the translations), and that plan is kept when its
    worst error relative to the target is below :data:`COUPLING_SPLIT_GAIN` times the first
    plan's. A joint whose body then has more than :data:`MAX_BODY_DOFS` is split."""
    by_base: dict[str, list[CoupledAxis]] = {}
    for a in axes:
        by_base.setdefault(a.base, []).append(a)
    used: dict[tuple[str, str], int] = {}  # extra joints planned so far, per (body, joint kind)
    planned: dict[str, PlannedAxis] = {}
    for base, group in by_base.items():
        lo, hi = ranges[base]

        def room(split: bool, group=group) -> tuple[list[object], dict[object, int]]:
            keys: list[object] = [(a.body, a.kind) if split else a.body for a in group]
            free = {}
            for a, key in zip(group, keys, strict=True):
                kinds = (a.kind,) if split else ("slide", "hinge")
                free[key] = MAX_BODY_DOFS - sum(dofs.get((a.body, k), 0) + used.get((a.body, k), 0) for k in kinds)
            return keys, free

        weight = [weights.get(a.name, 1.0) for a in group]
        slopes = [slope_targets[a.units] for a in group]
        slopes = None if all(v is None for v in slopes) else [math.inf if v is None else v for v in slopes]
        aims = [targets[a.units] for a in group]

        def worst_of(f: CouplingFit, group=group, slopes=slopes) -> float:
            return max(max(ax.max_error / targets[a.units], ax.slope_error / slopes[i] if slopes else 0.0)
                       for i, (ax, a) in enumerate(zip(f.axes, group, strict=True)))

        try:
            best = plan_group(group, *room(False), lo, hi, refs[base], weight, aims, slope_targets=slopes,
                              cache=cache)
        except FitError as exc:
            raise FitError(str(exc), coordinate=base) from None
        worst = worst_of(best)
        if worst > 1:
            split, split_worst = None, math.inf
            for k in range(SPLIT_RETRIES + 1):
                scaled = group if k == 0 else [replace(a, rel=lambda x, f=a.rel, s=1 + k * SPLIT_RESCALE: f(x) * s)
                                               for a in group]
                trial = plan_group(scaled, *room(True), lo, hi, refs[base], weight, aims, slope_targets=slopes,
                                   cache=cache)
                trial_worst = worst_of(trial)
                if trial_worst < split_worst:
                    split, split_worst = trial, trial_worst
                if split_worst < COUPLING_SPLIT_GAIN * worst or split_worst >= worst:
                    break  # kept, or splitting does not help at all
            if split_worst < COUPLING_SPLIT_GAIN * worst:
                best = split
        for i, a in enumerate(group):
            used[a.body, a.kind] = used.get((a.body, a.kind), 0) + best.extra_joints(i)
        planned.update(planned_axes(best, group, lo, hi))
    split_bodies: dict[str, tuple[int, int]] = {}
    for body in {b for b, _ in dofs}:
        total = sum(dofs.get((body, k), 0) + used.get((body, k), 0) for k in ("slide", "hinge"))
        if total > MAX_BODY_DOFS:
            split_bodies[body] = (dofs.get((body, "slide"), 0) + used.get((body, "slide"), 0),
                                  dofs.get((body, "hinge"), 0) + used.get((body, "hinge"), 0))
    return planned, split_bodies


def chunks_by_key(keys: list[object], size: int = CARRIER_CHUNK, split: int = CARRIER_SPLIT_CHUNK) -> list[list[int]]:
    """Indices 0..len(keys)-1: one chunk of all, in order, when there are at most ``size``; else in
    consecutive chunks of at most ``split`` (more only when one key has more axes), the axes of
    one key (one body's degrees of freedom) always in one chunk, each chunk in index order."""
    if len(keys) <= size:
        return [list(range(len(keys)))]
    by_key: dict[object, list[int]] = {}
    for i, key in enumerate(keys):
        by_key.setdefault(key, []).append(i)
    chunks: list[list[int]] = [[]]
    for members in by_key.values():
        if chunks[-1] and len(chunks[-1]) + len(members) > split:
            chunks.append([])
        chunks[-1].extend(members)
    return [sorted(c) for c in chunks if c]


def plan_group(group: list[CoupledAxis], keys: list[object], room: Mapping[object, int], lo: float, hi: float,
               x0: float, weight: list[float], targets: list[float], slope_targets: list[float] | None = None,
               cheaper_too: bool = False, cache: dict | None = None) -> CouplingFit:
    """The coupling fit of one coordinate's coupled axes ``group`` (fitted over [lo, hi], exact
    at the coordinate's reference value ``x0``), axis i's extra joints counted against
    ``room[keys[i]]`` (the degrees of freedom left where they would go).

    MuJoCo softens a joint equality by the sum of its two joints' inverse weights
    (``dof_invweight0``, whatever their units), so an inner joint needs at least the
    armature of the outer joints it drives (:func:`extra_armature`): an outer slide of
    the tibia driven by an inner hinge of the light patella sagged 1.5 mm under the tibia's
    weight. That costs little on a slide, which moves millimetres (6 kg on a knee's inner
    slide adds 1e-5 kg m² to the knee), but much on a hinge, which moves a tenth of a radian:
    so an axis drives outer joints only from inner slides or from inner hinges of axes at
    least as heavy (``weight``: each main joint's own inertia, :func:`o2m.convert.inertials.main_inertias`).

    Start (when a plain quartic misses its target): one inner joint on the heaviest axis that
    misses and has room (the most room on ties) and one outer joint for each axis that misses,
    worst first, while there is room. Then, while an axis still misses and has room: a new inner
    joint on it with an outer joint (two joints), else an outer joint of an inner joint it has
    none of yet (one joint); kept only if that axis's error drops below COUPLING_GAIN times what
    it was and no axis of the coordinate gets worse than the worst was. An axis whose move is not
    kept is given up until a new inner joint is added (it may then take an outer joint of it:
    Leg39's tibia tx, whose body was full when the patella's inner joint came, stayed at 0.057 mm
    where one more outer joint brings it to 0.019 mm).

    ``targets`` (each axis's; the skeleton's: :data:`COUPLING_TARGET` by unit) and
    ``slope_targets`` (derivative targets, None: the value only): an axis misses when its value
    error exceeds its target or its derivative error its slope target, by the larger ratio (the
    fits are then derivative-aware, :func:`o2m.convert.couplings.fit_couplings`). With ``cheaper_too``, an
    axis whose new inner/outer pair is not kept tries an outer joint of an inner joint it has none
    of yet before it is given up (path-point carriers; the skeleton's plans stay as they were)."""
    plan = _GroupPlan(group, keys, room, lo, hi, x0, weight, targets, slope_targets, cache)
    best, uses, hosts = plan.start()
    return plan.grow(best, uses, hosts, cheaper_too)


class _GroupPlan:
    """One coordinate's coupled axes while :func:`plan_group` plans them: the room left and the fits."""

    def __init__(self, group: list[CoupledAxis], keys: list[object], room: Mapping[object, int], lo: float,
                 hi: float, x0: float, weight: list[float], targets: list[float], slope_targets: list[float] | None,
                 cache: dict | None = None):
        self.group, self.keys, self.room, self.weight = group, keys, dict(room), weight
        self.cache = cache
        self.fns = [a.rel for a in group]
        self.lo, self.hi, self.x0 = lo, hi, x0
        self.targets, self.slope_targets = targets, slope_targets

    def may_use(self, i: int, host: int) -> bool:
        return self.group[host].kind == "slide" or self.weight[host] >= (1 - 1e-6) * self.weight[i]

    def fit(self, uses, hosts, start=()) -> CouplingFit:
        return fit_couplings(self.fns, self.lo, self.hi, self.x0, targets=self.targets, uses=uses, hosts=hosts,
                             start_shapes=start, margin=COUPLING_MARGIN, guard=COUPLING_GUARD,
                             slope_targets=self.slope_targets, cache=self.cache)

    def ratios(self, f: CouplingFit) -> list[float]:
        if self.slope_targets is None:
            return [ax.max_error / tg for ax, tg in zip(f.axes, self.targets, strict=True)]
        return [max(ax.max_error / tg, ax.slope_error / st)
                for ax, tg, st in zip(f.axes, self.targets, self.slope_targets, strict=True)]

    def start(self) -> tuple[CouplingFit, list[list[int]], list[int]]:
        """The plain quartics, or the first inner joint and its outer joints: (fit, uses, hosts)."""
        room, keys, weight = self.room, self.keys, self.weight
        best = self.fit([[] for _ in self.group], [])
        uses: list[list[int]] = [[] for _ in self.group]
        hosts: list[int] = []
        missing = sorted((i for i, r in enumerate(self.ratios(best)) if r > 1), key=lambda i: -self.ratios(best)[i])
        candidates = [i for i in missing if room[keys[i]] >= 1]
        if candidates:
            need = {b: sum(keys[i] == b for i in missing) for b in room}
            heaviest = max(weight[i] for i in candidates)
            candidates = [i for i in candidates if weight[i] >= (1 - 1e-6) * heaviest]
            host = max(candidates, key=lambda i: room[keys[i]] - need[keys[i]])  # the worst on ties
            hosts.append(host)
            room[keys[host]] -= 1
            for i in missing:
                if room[keys[i]] >= 1 and self.may_use(i, host):
                    uses[i].append(0)
                    room[keys[i]] -= 1
            if any(uses):
                best = self.fit(uses, hosts)
            else:
                hosts = []
        return best, uses, hosts

    def grow(self, best: CouplingFit, uses: list[list[int]], hosts: list[int], cheaper_too: bool) -> CouplingFit:
        """More extra joints, one axis at a time, while they bring a gain (:func:`plan_group`)."""
        room, keys = self.room, self.keys
        done: set[int] = set()
        while hosts:
            r = self.ratios(best)
            order = sorted((i for i in range(len(self.group)) if r[i] > 1 and i not in done), key=lambda i: -r[i])
            moves: list[tuple[int, list[int], int, int]] = []
            for i in order:
                b = keys[i]
                if room[b] >= 2:
                    moves.append((i, [*hosts, i], len(hosts), 2))
                unused = [k for k in range(len(hosts)) if k not in uses[i] and self.may_use(i, hosts[k])]
                if room[b] >= 1 and unused:
                    moves.append((i, hosts, unused[0], 1))
                if moves:
                    break
            if not moves:
                break
            for i, new_hosts, k, cost in moves if cheaper_too else moves[:1]:
                new_uses = [list(u) + ([k] if j == i else []) for j, u in enumerate(uses)]
                trial = self.fit(new_uses, new_hosts, best.shapes)
                if self.ratios(trial)[i] <= COUPLING_GAIN * r[i] and max(self.ratios(trial)) <= max(r):
                    if len(new_hosts) > len(hosts):
                        done.clear()  # a new inner joint: axes given up may now use it
                    best, uses, hosts = trial, new_uses, list(new_hosts)
                    room[keys[i]] -= cost
                    break
            else:
                done.add(i)
        return best
