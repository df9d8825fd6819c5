"""Fitting each tendon's wrap geoms and side sites to OpenSim's lengths and moment arms.

Where a converted path only approximates OpenSim's (an ellipsoid wrapped as a sphere or a
cylinder, a wrap placed on one path segment, MuJoCo's side-site rule for which way
round a geom the tendon goes), :func:`fit_paths` adjusts, per tendon, the position and radius of
each of its wrap geoms and the position of each side site so that MuJoCo's tendon length and
moment arms match OpenSim's over sampled poses:

* Poses and targets (:mod:`o2m.convert.wrap_targets`): random poses in the coordinates' ranges,
  OpenSim's length and moment arms ``-dL/dq`` there for every coordinate the path spans (or what
  a held or designed tendon stands for), OpenSim's own failures left out.
* Objective: mean squared length error plus mean squared moment-arm error, both in mm².
  MuJoCo's lengths come from ``mj_kinematics`` + ``mj_tendon`` on a copy of the model reduced to
  that tendon (:mod:`o2m.convert.reduced`) whose ``geom_pos``, ``geom_size`` and ``site_pos`` are
  changed in place; moment arms from the tendon Jacobian projected on each coordinate's direction.
* Start: the converted geoms, except that a geom standing for a WrapEllipsoid or a WrapTorus also gets the
  sphere (or, for a cylinder, the circle about its axis) fitted by least squares to the points
  where OpenSim's path touches the ellipsoid (its wrap arcs over the fitting poses); CMA-ES
  starts from whichever of the two fits better (a mean-radius sphere misses the part of the
  ellipsoid the path runs over).
* Optimiser: CMA-ES (:mod:`cma`), two starts per tendon (seeded from its name, so that a fit does
  not change with the others; the best kept), parallel over tendons in a process pool.
* Variants: a tendon with a split segment (:mod:`o2m.convert.wrap_split`) is fitted once per
  choice of the wraps kept there (:mod:`o2m.convert.wrap_choice`), none of them included; any
  other tendon whole and straight (its wraps left out); each with its ellipsoids' stand-ins as
  converted and as the other kind, sphere or cylinder (:mod:`o2m.convert.ellipsoid_standins`,
  which also judges a swap on validation poses of OpenSim's lengths, drawn apart); the one
  nearest OpenSim over all its poses is kept.
* A fit is accepted only when it lowers the objective on the fitting poses, raises it on
  separate check poses not at all and on validation poses (lengths only, drawn apart from both)
  by at most :data:`VALIDATION_GROWTH` times, and raises the worst length error on neither the
  fitting nor the check poses; otherwise the tendon keeps its start. An ellipsoid stand-in's
  side site whose leaving out makes the tendon no further from OpenSim at the poses is then left
  out (:data:`SIDE_OPTIONAL_KINDS`). Each tendon's errors before and after go into the report.
"""

from __future__ import annotations

import os
import tempfile
import time
import zlib
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import mujoco
import numpy as np

from o2m.convert.ellipsoid_standins import apply_kinds, best_with_kinds, swap_kinds_xml, swapped_geometry, with_kinds
from o2m.convert.reduced import reduced_xml, without_unused
from o2m.convert.wrap_choice import drop_from_spec, whole_and_straight, xml_without
from o2m.convert.wrap_jumps import count_flips, segment_jumps
from o2m.convert.wrap_targets import fit_targets
from o2m.parallel import map_with_progress
from o2m.transforms import OSIM_TO_MJ

#: Poses to fit on and to check on, the CMA-ES evaluation budget per start, the starts per tendon
#: and the poses (lengths only) an ellipsoid's swapped stand-in is validated on (full, quick).
FULL = {"poses": 120, "check": 60, "evals": 1500, "starts": 2, "validate": 200}
QUICK = {"poses": 40, "check": 30, "evals": 400, "starts": 2, "validate": 100}
#: OpenSim wrap objects whose stand-in may start from the sphere or circle fitted to OpenSim's
#: contact points (their geom is not the object itself).
CONTACT_KINDS = ("WrapEllipsoid", "WrapTorus")
#: OpenSim wraps whose path never switches ways round (``WrapEllipsoid::wrapLine``): their stand-in's
#: side site, where leaving it out makes no length or moment arm at the poses worse, is left out, so
#: that MuJoCo takes the shorter way and cannot switch where OpenSim does not, between the poses
#: drawn or beyond a coordinate's range (a sphere's or cylinder's side site is OpenSim's own switch).
SIDE_OPTIONAL_KINDS = ("WrapEllipsoid",)
#: The fitting poses are drawn with the fit's seed plus this, so that they are not the poses
#: :func:`o2m.validate.muscles.compare_muscles` draws with the same seed: a comparison with a
#: small seed then measures the fit on poses it has not seen.
FIT_POSE_SEED = 104729
#: The validation poses are drawn with the fit's seed plus this, apart from the fitting poses
#: and from :func:`o2m.validate.muscles.compare_muscles`'s.
VALIDATION_SEED = 7919
#: A fit whose mean squared length error on the validation poses exceeds its start's by more than
#: this factor is not kept. Those poses have lengths only, so a fit that trades a little length
#: for much better moment arms is a little worse there; one that stops wrapping where its poses
#: are few is many times worse (docs/muscle-paths.md, "A fit not far worse on poses it never saw").
VALIDATION_GROWTH = 2.0
#: Length scale (m) of the position parameters of a geom: at least this, else its radius.
MIN_SCALE = 0.004
#: A side site is kept at least this many radii from its geom's centre (axis, for a cylinder).
MIN_SIDE_DISTANCE = 1.25
#: A tendon whose converted geoms are this near OpenSim (objective, mm², on the fitting and the
#: check poses: 0.01 mm RMS, the scale of OpenSim's own wrap iterations and finite-difference
#: moment arms) is not fitted: an improvement there is noise, and moving a geom for it can cost
#: poses no sample covers (an ellipsoid of three equal radii, an exact sphere, moved 30 % of its
#: radius for 1 micrometre put a head-neck model's eye muscle 5.6 % off at a range corner).
EXACT_OBJECTIVE = 1e-4


@dataclass
class PathFit:
    """The fit of one tendon: errors before and after (``len_rms_mm``, ``len_max_mm``,
    ``len_max_pct``, ``ma_rms_mm``, ``objective``) on the fitting poses and on the check poses,
    whether the result was accepted, and the fitted values (MuJoCo body frames, metres)."""

    tendon: str
    geoms: list[str]
    kinds: list[str]
    coordinates: list[str]
    n_params: int
    poses: int
    before: dict[str, float]
    after: dict[str, float]
    check_before: dict[str, float]
    check_after: dict[str, float]
    accepted: bool
    evaluations: int
    seconds: float
    values: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    #: the variant kept (:mod:`o2m.convert.wrap_choice`; "" when the tendon has none), the MuJoCo
    #: sites and geoms it leaves out, and every variant's errors (label -> {"objective" (mm²),
    #: "len_max_pct", "ma_rms_mm", "flips"}: :func:`~o2m.convert.wrap_choice.variant_errors`)
    variant: str = ""
    dropped: list[str] = field(default_factory=list)
    variants: dict[str, dict[str, float]] = field(default_factory=dict)
    #: the start was within :data:`EXACT_OBJECTIVE` of OpenSim: not fitted
    exact: bool = False
    #: ellipsoid geoms of the kept variant made their other stand-in -> its kind, size and quat
    #: (:mod:`o2m.convert.ellipsoid_standins`)
    swapped: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: errors after, on the validation poses (lengths only; empty without them)
    valid_after: dict[str, float] = field(default_factory=dict)
    #: jumps of the fitted tendon between consecutive fitting poses
    #: (:func:`o2m.convert.wrap_jumps.segment_jumps`), and how many OpenSim does not share
    #: (:func:`~o2m.convert.wrap_jumps.count_flips`)
    jumps: list[dict[str, Any]] = field(default_factory=list)
    flips: int = 0

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out.pop("jumps")  # poses, for the flip count only
        return out


@dataclass
class _Task:
    tendon: str
    xml: str
    geoms: list[str]
    sites: list[str]
    kinds: list[str]
    qpos: np.ndarray  # (N, nq) fitting poses, then check poses
    dv: np.ndarray  # (N, nc, nv) coordinate directions in dof space
    length: np.ndarray  # (N,) OpenSim
    arm: np.ndarray  # (N, nc) OpenSim -dL/dq
    n_fit: int
    coordinates: list[str]
    seed: int
    evals: int
    #: per geom: OpenSim's wrap-arc points on the object it stands for (MuJoCo body frame, (n, 3)), or None
    contacts: list[np.ndarray | None] = field(default_factory=list)
    #: via sites whose positions are fitted too (:mod:`o2m.convert.wrap_split`'s)
    vias: list[str] = field(default_factory=list)
    variant: str = ""
    dropped: list[str] = field(default_factory=list)
    starts: int = 1
    swapped: dict[str, dict[str, Any]] = field(default_factory=dict)
    n_valid: int = 0  # the last rows of qpos: validation poses, lengths only


# --------------------------------------------------------------------------------------------
# MuJoCo side (runs in the workers)
# --------------------------------------------------------------------------------------------


class _Evaluator:
    """A reduced MuJoCo model of one tendon and the poses it is evaluated in."""

    def __init__(self, task: _Task):
        self.t = task
        self.m = mujoco.MjModel.from_xml_string(task.xml)
        self.d = mujoco.MjData(self.m)
        self.gid = [self.m.geom(g).id for g in task.geoms]
        self.sid = [self.m.site(s).id if s else -1 for s in task.sites]  # -1: no side site (quadrant 'all')
        self.has_side = np.array([i >= 0 for i in self.sid])
        self.pos0 = self.m.geom_pos[self.gid].copy()
        self.rad0 = self.m.geom_size[self.gid, 0].copy()
        side_ids = np.maximum(np.asarray(self.sid, dtype=int), 0)  # int also when there is no geom
        self.side0 = np.where(self.has_side[:, None], self.m.site_pos[side_ids], self.pos0)
        self.cyl = [int(self.m.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_CYLINDER) for g in self.gid]
        self.scale = np.maximum(self.rad0, MIN_SCALE)
        self.vid = [self.m.site(s).id for s in task.vias]
        self.via0 = self.m.site_pos[self.vid].copy()
        self.n_params = 7 * len(self.gid) + 3 * len(self.vid)
        self.evaluations = 0
        adr, num = int(self.m.tendon_adr[0]), int(self.m.tendon_num[0])
        geom_wraps = (int(mujoco.mjtWrap.mjWRAP_SPHERE), int(mujoco.mjtWrap.mjWRAP_CYLINDER))
        self.wrap_of = {int(self.m.wrap_objid[w]): w for w in range(adr, adr + num)
                        if int(self.m.wrap_type[w]) in geom_wraps}  # geom id -> its path element

    def via_positions(self, theta: np.ndarray) -> np.ndarray:
        """Positions (body frames, (n vias, 3)) of the fitted via sites for parameters ``theta``."""
        tail = np.asarray(theta, dtype=float)[7 * len(self.gid):].reshape(len(self.vid), 3)
        return self.via0 + MIN_SCALE * tail

    def values(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Geom positions, radii and side-site positions (body frames) of parameters ``theta``."""
        th = np.asarray(theta, dtype=float)[:7 * len(self.gid)].reshape(len(self.gid), 7)
        pos = self.pos0 + self.scale[:, None] * th[:, 0:3]
        rad = self.rad0 * np.exp(np.clip(th[:, 3], -3.0, 3.0))
        side = self.side0 + self.scale[:, None] * th[:, 4:7]
        for k, g in enumerate(self.gid):  # keep each side site outside its geom (its axis, for a cylinder)
            rot = np.zeros(9)
            mujoco.mju_quat2Mat(rot, self.m.geom_quat[g])
            rot = rot.reshape(3, 3)
            rel = rot.T @ (side[k] - pos[k])
            mask = np.array([1.0, 1.0, 0.0]) if self.cyl[k] else np.ones(3)
            radial, axial = rel * mask, rel * (1.0 - mask)
            dist, need = float(np.linalg.norm(radial)), MIN_SIDE_DISTANCE * rad[k]
            if dist < need:
                radial = radial / dist * need if dist > 1e-12 else np.array([need, 0.0, 0.0])
                side[k] = pos[k] + rot @ (radial + axial)
        return pos, rad, side

    def contact_start(self) -> np.ndarray | None:
        """Parameters putting each geom with contact points on the sphere (cylinder: the circle
        about its axis) fitted to them by least squares, its side site kept in its direction from
        the centre at its distance in radii; None when no geom has enough points."""
        th = np.zeros((len(self.gid), 7))
        changed = False
        tail = np.zeros(3 * len(self.vid))
        for k, pts in enumerate(self.t.contacts or []):
            if pts is None or len(pts) < 8:
                continue
            rot = np.zeros(9)
            mujoco.mju_quat2Mat(rot, self.m.geom_quat[self.gid[k]])
            rot = rot.reshape(3, 3)
            local = (np.asarray(pts) - self.pos0[k]) @ rot  # in the geom frame
            dims = 2 if self.cyl[k] else 3
            fit = _least_squares_sphere(local[:, :dims])
            if fit is None:
                continue
            centre, radius = fit
            c_local = np.zeros(3)
            c_local[:dims] = centre
            pos = self.pos0[k] + rot @ c_local
            rel = self.side0[k] - self.pos0[k]
            side = pos + rel * (radius / self.rad0[k])
            th[k, 0:3] = (pos - self.pos0[k]) / self.scale[k]
            th[k, 3] = np.log(radius / self.rad0[k])
            th[k, 4:7] = (side - self.side0[k]) / self.scale[k]
            changed = True
        return np.clip(np.concatenate([th.ravel(), tail]), -4.0, 4.0) if changed else None

    def apply(self, theta: np.ndarray) -> None:
        pos, rad, side = self.values(theta)
        self.m.geom_pos[self.gid] = pos
        self.m.geom_size[self.gid, 0] = rad
        real = np.flatnonzero(self.has_side)
        self.m.site_pos[np.array(self.sid, dtype=int)[real]] = side[real]
        if self.vid:
            self.m.site_pos[self.vid] = self.via_positions(theta)

    def errors(self, theta: np.ndarray, rows: slice) -> tuple[np.ndarray, np.ndarray]:
        """Length errors (n,) and moment-arm errors (n, nc), metres, MuJoCo minus OpenSim."""
        self.apply(theta)
        m, d, t = self.m, self.d, self.t
        qs = t.qpos[rows]
        n = len(qs)
        length = np.empty(n)
        adr, nnz = int(m.ten_J_rowadr[0]), int(m.ten_J_rownnz[0])  # the pattern is the model's
        rows_j = np.empty((n, nnz))
        for k in range(n):
            d.qpos[:] = qs[k]
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            mujoco.mj_tendon(m, d)
            length[k] = d.ten_length[0]
            rows_j[k] = d.ten_J[adr:adr + nnz]
        jac = np.zeros((n, m.nv))
        jac[:, m.ten_J_colind[adr:adr + nnz]] = rows_j
        arm = -np.matmul(t.dv[rows], jac[:, :, None])[:, :, 0]  # (n, nc): each pose's dv @ jac
        self.evaluations += 1
        return length - t.length[rows], arm - t.arm[rows]

    def unneeded_side_sites(self, theta: np.ndarray, rows: slice) -> list[str]:
        """The side sites of :data:`SIDE_OPTIONAL_KINDS` stand-ins whose leaving out makes
        neither the objective nor the worst length error worse at the poses ``rows`` (each left
        out in turn, kept out where nothing got worse): a side site that makes the tendon go the
        long way round only where that is no nearer OpenSim would still switch it there, and
        beyond the poses (a range's end) a switch OpenSim's ellipsoid never makes."""
        le, me = self.errors(theta, rows)
        length = self.t.length[rows]
        out = []
        for k, g in enumerate(self.gid):
            if not self.has_side[k] or self.t.kinds[k] not in SIDE_OPTIONAL_KINDS:
                continue
            w = self.wrap_of[g]
            side = self.m.wrap_prm[w]
            self.m.wrap_prm[w] = -1
            le_without, me_without = self.errors(theta, rows)
            if (_objective(le_without, me_without) <= _objective(le, me)
                    and _worst_pct(le_without, length) <= _worst_pct(le, length)):
                out.append(self.t.sites[k])
                le, me = le_without, me_without
            else:
                self.m.wrap_prm[w] = side
        return out

    def jumps(self, theta: np.ndarray, rows: slice) -> list[dict[str, Any]]:
        """Jumps of the tendon with parameters ``theta`` (its side sites as they are now) between
        consecutive poses ``rows`` (:func:`o2m.convert.wrap_jumps.segment_jumps`)."""
        self.apply(theta)
        return segment_jumps(self.m, self.t.qpos[rows])

    def objective(self, theta: np.ndarray, rows: slice) -> float:
        le, me = self.errors(theta, rows)
        return _objective(le, me)

    def summary(self, theta: np.ndarray, rows: slice) -> dict[str, float]:
        le, me = self.errors(theta, rows)
        L = self.t.length[rows]
        ok = np.isfinite(me)
        return {"len_rms_mm": float(np.sqrt(np.mean(le**2)) * 1e3), "len_max_mm": float(np.max(np.abs(le)) * 1e3),
                "len_max_pct": _worst_pct(le, L),
                "ma_rms_mm": float(np.sqrt(np.mean(me[ok] ** 2)) * 1e3) if ok.any() else 0.0,
                "objective": _objective(le, me), "poses": len(le)}


def _least_squares_sphere(pts: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Centre and radius of the sphere (circle, for 2-D points) nearest ``pts`` in the algebraic
    least-squares sense, or None when the points do not determine one."""
    a = np.c_[2.0 * pts, np.ones(len(pts))]
    b = np.sum(pts**2, axis=1)
    sol, _, rank, _ = np.linalg.lstsq(a, b, rcond=None)
    if rank < a.shape[1]:
        return None
    centre = sol[:-1]
    r2 = float(sol[-1] + centre @ centre)
    return (centre, float(np.sqrt(r2))) if r2 > 0 else None


def _objective(le: np.ndarray, me: np.ndarray) -> float:
    """Mean squared length error plus mean squared moment-arm error (mm²); NaN targets left out."""
    ok = np.isfinite(me)
    return float(np.mean(le**2) * 1e6 + (np.mean(me[ok] ** 2) * 1e6 if ok.any() else 0.0))


def _worst_pct(le: np.ndarray, length: np.ndarray) -> float:
    """Largest length error (%) of errors ``le`` against OpenSim's lengths ``length`` (m)."""
    return float(np.max(np.abs(le) / np.maximum(length, 1e-9)) * 100)


def _no_worse(a: dict[str, float], b: dict[str, float]) -> bool:
    """Errors ``a`` (:meth:`_Evaluator.summary`) no worse than ``b``: objective and worst length."""
    return a["objective"] <= b["objective"] and a["len_max_pct"] <= b["len_max_pct"]


def _fit_one(task: _Task) -> PathFit:
    import cma

    t0 = time.perf_counter()
    ev = _Evaluator(task)
    n_arms = len(task.qpos) - task.n_valid
    fit, check, valid = slice(0, task.n_fit), slice(task.n_fit, n_arms), slice(n_arms, len(task.qpos))
    x0 = np.zeros(ev.n_params)
    f0 = ev.objective(x0, fit)
    exact = f0 <= EXACT_OBJECTIVE and ev.objective(x0, check) <= EXACT_OBJECTIVE
    best_x, best_f = x0, f0
    start = None if exact else ev.contact_start()
    if start is not None:
        f_start = ev.objective(start, fit)
        if f_start < best_f:
            best_x, best_f = start, f_start
    x_start = best_x
    for start in range(task.starts if ev.n_params and task.evals > 0 and not exact else 0):
        # each start from the same point with its own seed: the best of them kept (one seed alone
        # left MoBL-ARMS's SUP at 32 % or 59 %)
        es = cma.CMAEvolutionStrategy(x_start, 0.3, {"seed": int(task.seed) + 1 + start, "maxfevals": int(task.evals),
                                                 "verbose": -9, "bounds": [-4.0, 4.0], "tolfun": 1e-9})
        while not es.stop():
            xs = es.ask()
            fs = [ev.objective(x, fit) for x in xs]
            es.tell(xs, fs)
            k = int(np.argmin(fs))
            if fs[k] < best_f:
                best_x, best_f = np.array(xs[k]), float(fs[k])
    before, after = ev.summary(x0, fit), ev.summary(best_x, fit)
    cb, ca = ev.summary(x0, check), ev.summary(best_x, check)
    # better overall, on both pose sets, without a larger worst length error on either, and not
    # far worse on the validation poses it never saw (a fit better at its few poses where a wrap
    # acts may stop wrapping between them: RajagopalLaiUhlrich2023's recfem_l at deep knee flexion)
    unseen = task.n_valid == 0 or ev.objective(best_x, valid) <= VALIDATION_GROWTH * ev.objective(x0, valid)
    accepted = bool(after["objective"] < before["objective"] and _no_worse(ca, cb)
                    and after["len_max_pct"] <= before["len_max_pct"] and unseen)
    if not accepted:
        best_x, after, ca = x0, before, cb
    unneeded = ev.unneeded_side_sites(best_x, slice(0, n_arms))
    jumps = ev.jumps(best_x, fit)
    pos, rad, side = ev.values(best_x)
    values = {g: {"pos": pos[k].tolist(), "radius": [float(rad[k])]} for k, g in enumerate(task.geoms)}
    values.update({s: {"pos": side[k].tolist()} for k, s in enumerate(task.sites) if s and s not in unneeded})
    values.update({s: {"pos": p.tolist()} for s, p in zip(task.vias, ev.via_positions(best_x), strict=True)})
    return PathFit(task.tendon, list(task.geoms), list(task.kinds), list(task.coordinates), ev.n_params, task.n_fit,
                   before, after, cb, ca, accepted, ev.evaluations, time.perf_counter() - t0, values,
                   task.variant, list(task.dropped) + unneeded, exact=exact, swapped=dict(task.swapped),
                   valid_after=ev.summary(best_x, valid) if task.n_valid else {}, jumps=jumps)


# --------------------------------------------------------------------------------------------
# The driver (OpenSim's targets: o2m.convert.wrap_targets)
# --------------------------------------------------------------------------------------------


def fit_paths(osim_path: str | os.PathLike, xml: str, path_geoms: Sequence[Any], *, seed: int = 0,
              quick: bool = False, workers: int | None = None, progress: bool = False,
              n_poses: int | None = None, evals: int | None = None,
              held: dict[str, dict] | None = None, designed: dict[str, list] | None = None,
              vias: dict[str, list[str]] | None = None,
              variants: dict[str, list[Any]] | None = None, starts: int | None = None) -> list[PathFit]:
    """Fit the wrap geoms and side sites of every tendon in ``path_geoms`` (each a
    :class:`o2m.tendons.PathGeom`) of the model ``xml`` (MJCF text) to OpenSim ``osim_path``.

    ``quick``: :data:`QUICK` sizes, not :data:`FULL` (``n_poses``/``evals``/``starts`` override
    them). ``workers`` processes (default: every core) fit the tendons in parallel. ``held``
    (:attr:`o2m.tendons.TendonBuilder.held`): the tendons whose same-body segments are held, and
    how; ``designed`` (tendon -> its
    :class:`o2m.lengthvia.LengthVia` records) the tendons whose lengths are designed there (their
    targets are those lengths); ``vias`` (tendon -> site names) the via sites fitted with a
    tendon's geoms (:mod:`o2m.convert.wrap_split`'s); ``variants`` (tendon -> its
    :class:`o2m.convert.wrap_choice.PathVariant` s) the choices of wraps fitted for a tendon (any
    other: whole and straight, :func:`~o2m.convert.wrap_choice.whole_and_straight`), the one
    :func:`~o2m.convert.wrap_choice.best_variant` picks kept (an ellipsoid's swapped stand-in also
    checked on the ``validate`` extra poses of :data:`QUICK` / :data:`FULL`, on which no fit may
    be over :data:`VALIDATION_GROWTH` times worse than its start). Each tendon's CMA-ES
    seed follows from ``seed`` and its name alone. Returns one :class:`PathFit` per tendon, in
    ``path_geoms`` order.
    """
    sizes = QUICK if quick else FULL
    n_fit = int(n_poses or sizes["poses"])
    n_check = max(10, n_fit // 2) if n_poses else sizes["check"]
    budget = int(sizes["evals"] if evals is None else evals)
    n_valid = int(sizes["validate"])  # lengths only: no fit kept that is far worse there
    by_tendon: dict[str, list[Any]] = {}
    for g in path_geoms:
        by_tendon.setdefault(g.tendon, []).append(g)
    if not by_tendon:
        return []
    with tempfile.TemporaryDirectory(prefix="o2m-wrapfit-") as tmp:
        path = os.path.join(tmp, "model.xml")
        with open(path, "w") as fh:
            fh.write(reduced_xml(xml))
        ellipsoids = {t: {g.source for g in gs if g.kind in CONTACT_KINDS} for t, gs in by_tendon.items()}
        _, targets = fit_targets(os.fspath(osim_path), path, list(by_tendon), n_fit + n_check,
                                 seed + FIT_POSE_SEED, held, ellipsoids, n_fit, designed)
        if n_valid:
            _, extra = fit_targets(os.fspath(osim_path), path, list(by_tendon), n_valid, seed + VALIDATION_SEED,
                                   held, None, 0, designed, n_arms=0)
            targets = with_validation(targets, extra)
        tasks = []
        for tendon, geoms in by_tendon.items():
            tg = targets.get(tendon)
            if tg is None or tg.get("n_arms", len(tg["qpos"])) < 2:
                continue
            for variant in with_kinds((variants or {}).get(tendon) or whole_and_straight(geoms), geoms):
                tasks.append(_task(tendon, xml, geoms, tg, variant, min(n_fit, tg.get("n_arms", len(tg["qpos"])) - 1),
                                   tendon_seed(seed, tendon), budget, list((vias or {}).get(tendon, [])),
                                   int(sizes["starts"] if starts is None else starts)))
        fitted = map_with_progress(_fit_one, tasks, workers=workers, desc="wrap fit", progress=progress)
        count_flips(osim_path, path, fitted)  # the reduced model the targets were drawn on
    results: dict[str, list[PathFit]] = {}
    for res in fitted:
        results.setdefault(res.tendon, []).append(res)
    return [best_with_kinds(results[t]) for t in by_tendon if t in results]


def with_validation(targets: dict[str, dict], extra: dict[str, dict]) -> dict[str, dict]:
    """Each tendon's targets with the poses of ``extra`` (lengths only, NaN moment arms) appended
    as validation rows; ``n_arms`` counts the rows before them."""
    out = {}
    for t, tg in targets.items():
        more = extra.get(t)
        if more is None or not len(more["qpos"]):
            out[t] = tg
            continue
        joined = {k: np.concatenate([tg[k], more[k]]) for k in ("qpos", "dv", "length", "arm")}
        out[t] = {**tg, **joined, "n_arms": len(tg["qpos"])}
    return out


def tendon_seed(seed: int, tendon: str) -> int:
    """The CMA-ES seed of ``tendon``'s fit: from ``seed`` and its name only, so that it does not
    change with the order or number of the tendons fitted (MoBL-ARMS's SUP: 32 % with one seed,
    59 % with another)."""
    return (int(seed) * 1_000_003 + zlib.crc32(tendon.encode())) % 2**31


def _task(tendon: str, xml: str, geoms: list[Any], tg: dict[str, Any], variant: Any, n_fit: int, seed: int,
          budget: int, vias: list[str], starts: int) -> _Task:
    """The fit of ``tendon`` (its :class:`PathGeom` s ``geoms`` and targets ``tg``), without the
    sites and geoms ``variant`` leaves out (None: every one)."""
    dropped = set(variant.dropped) if variant is not None else set()
    geoms = [g for g in geoms if g.geom not in dropped]
    contacts = []
    for g in geoms:
        pts = tg["contacts"].get(g.source) if g.kind in CONTACT_KINDS else None
        if pts:
            pts = np.array(pts)
            pts = pts @ OSIM_TO_MJ.T if g.body == "ground" else pts  # MuJoCo's ground is Z-up
        contacts.append(pts if pts is not None and len(pts) else None)
    named = [g.geom for g in geoms] + [g.sidesite for g in geoms if g.sidesite] + list(vias)
    swapped = swapped_geometry(geoms, variant.swapped if variant is not None else ())
    task_xml = swap_kinds_xml(without_unused(xml_without(reduced_xml(xml, tendon), tendon, dropped), keep=named),
                              swapped)
    return _Task(tendon, task_xml, [g.geom for g in geoms],
                 [g.sidesite for g in geoms], [g.kind for g in geoms], tg["qpos"], tg["dv"], tg["length"], tg["arm"],
                 n_fit, tg["coordinates"], seed, budget, contacts, [v for v in vias if v not in dropped],
                 variant.label if variant is not None else "", sorted(dropped), starts, swapped,
                 len(tg["qpos"]) - tg.get("n_arms", len(tg["qpos"])))


def apply_fits(spec: mujoco.MjSpec, fits: Sequence[PathFit], site_exact: dict, geom_exact: dict) -> None:
    """Write accepted fits into ``spec`` and into the exact-value tables the MJCF writer uses, and
    leave out of it the sites and geoms each tendon's kept variant drops; an ellipsoid's stand-in
    the kept variant swapped becomes its other kind, fitted or not."""
    drop_from_spec(spec, {f.tendon: f.dropped for f in fits})
    apply_kinds(spec, fits, geom_exact)
    for f in fits:
        if not f.accepted:
            continue
        for name, vals in f.values.items():
            if name in f.geoms:
                g = spec.geom(name)
                pos, radius = np.array(vals["pos"]), float(vals["radius"][0])
                g.pos = pos
                size = np.array(g.size, dtype=float)
                size[0] = radius
                g.size = size
                ex = geom_exact.setdefault(("geom", name), {})
                ex["pos"] = pos
                ex["size"] = np.concatenate([[radius], np.asarray(ex.get("size", [radius]))[1:]])
            else:
                s = spec.site(name)
                s.pos = np.array(vals["pos"])
                site_exact[("site", name)] = {"pos": np.array(vals["pos"])}


def format_fits(fits: Sequence[PathFit]) -> list[str]:
    """Report lines, one per fitted tendon."""
    lines = []
    for f in fits:
        b, a = f.before, f.after
        lines.append(f"  {f.tendon:16s} {'+'.join(sorted(set(f.kinds))):34s} length rms {b['len_rms_mm']:.3g} -> "
                     f"{a['len_rms_mm']:.3g} mm (max {b['len_max_pct']:.3g} -> {a['len_max_pct']:.3g} %), moment arm "
                     f"rms {b['ma_rms_mm']:.3g} -> {a['ma_rms_mm']:.3g} mm"
                     + ("" if f.accepted else " (within OpenSim's noise: not fitted)" if f.exact
                        else " (not better: start kept)") + f", {f.seconds:.1f} s"
                     + (f"; flips round a wrap where OpenSim does not on {f.flips} of the lines between its poses"
                        if f.flips else ""))
        if f.variants:
            tried = "; ".join(f"{label} {v['objective']:.3g} mm², {v['len_max_pct']:.3g} %, {v['ma_rms_mm']:.3g} mm"
                              + (f", {v['flips']} flips" if v.get("flips") else "")
                              for label, v in f.variants.items())
            lines.append(f"    wraps kept: {f.variant} (objective and worst length error over all poses, "
                         f"moment-arm RMS over the fitting and check poses: {tried})")
    return lines


__all__ = ["FULL", "QUICK", "PathFit", "apply_fits", "fit_paths", "format_fits", "reduced_xml", "tendon_seed"]
