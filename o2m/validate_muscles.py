"""Compare the muscle paths of a converted MuJoCo model against its OpenSim original.

Conventions of an o2m conversion (see :mod:`o2m.validate` for the skeleton): every OpenSim path
force (muscles and other PathActuators, Ligaments, PathSprings) is a MuJoCo tendon of the same
name, and every OpenSim actuator among them a MuJoCo actuator of that name transmitting through
that tendon with gear 1, so ``actuator_length == ten_length`` is OpenSim's muscle-tendon length
``getLength(state)`` (metres).

* :func:`compare_muscles` samples random poses exactly as :func:`o2m.validate.compare_kinematics`
  does and measures, per muscle, the length error (metres and percent of OpenSim's length) and,
  per (muscle, spanned coordinate), the moment-arm error (metres), returning a
  :class:`MuscleReport`.
* :func:`sweep_jumps` sweeps each coordinate over its range in small steps and reports the
  largest change of every tendon length between neighbouring steps, to catch wrapping flips.
* :func:`mujoco_moment_arms` gives MuJoCo moment arms ``-dL/dq`` (finite differences through the
  joint equalities, or the tendon Jacobian projected on the coordinate direction), the sign
  convention of OpenSim's ``computeMomentArm``.
* :func:`moment_arm_curve` / :func:`plot_moment_arms` give / plot both models' moment arm of one
  muscle about one coordinate over its range; :func:`moment_arm_sweeps` does that for every
  (path, spanned coordinate) pair and :func:`plot_moment_arm_sweeps` draws each path's worst
  pair into a small multi-page PDF (the conversion report's moment-arm plots);
  :func:`format_muscle_table` summarises reports.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import mujoco
import numpy as np

from o2m.validate import (
    JointEquality,
    MissingJointError,
    _clean,
    _load_mujoco,
    _load_opensim,
    _sample_bounds,
    joint_equality_plan,
    joint_qpos_address,
    pose_mujoco,
    text_table,
)

__all__ = [
    "MomentArmError",
    "MuscleError",
    "MuscleReport",
    "compare_muscles",
    "format_muscle_table",
    "moment_arm_curve",
    "mujoco_moment_arms",
    "moment_arm_sweeps",
    "mujoco_tendon_lengths",
    "opensim_spikes",
    "opensim_length_steps",
    "continuous_tendon_front",
    "plot_moment_arm_sweeps",
    "plot_moment_arms",
    "sweep_jumps",
]

#: Central-difference step of the MuJoCo moment arms (radians or metres).
FD_STEP = 1e-6
#: A moment arm below this (metres) in both models over all poses means "does not span".
MA_ZERO = 1e-7
#: Default tolerances of :meth:`MuscleReport.ok`.
LEN_PCT = 1.0
MA_MEDIAN_MM = 0.5
MA_P95_MM = 2.0
MA_MAX_MM = 5.0
#: OpenSim -dL/dq estimates at two steps that differ by more than this (m) are no moment arm.
DLDQ_CONSISTENCY = 1e-3
#: OpenSim spike test (see :func:`opensim_spikes`): coordinate step (radians, metres) and size (m).
SPIKE_STEP = 0.01
SPIKE_LINEAR_STEP = 1e-3
SPIKE_TOL = 1e-3

_TRANSLATIONAL = 2  # opensim Coordinate::Translational


# --------------------------------------------------------------------------------------------
# MuJoCo side
# --------------------------------------------------------------------------------------------


def mujoco_tendon_lengths(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    values: Mapping[str, float],
    *,
    plan: list[JointEquality] | None = None,
) -> np.ndarray:
    """Tendon lengths (ntendon,), metres, in the pose of joint ``values`` (see
    :func:`o2m.validate.pose_mujoco`; equality-driven joints follow their drivers).
    Leaves ``data`` posed with ``ten_length`` and ``ten_J`` computed."""
    pose_mujoco(model, data, values, plan=plan)
    mujoco.mj_tendon(model, data)
    return np.array(data.ten_length, dtype=float)


def _tendon_jacobian(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Dense tendon Jacobian (ntendon, nv) from ``data.ten_J`` (sparse in MuJoCo >= 3.3)."""
    nt, nv = model.ntendon, model.nv
    tj = np.asarray(data.ten_J, dtype=float).ravel()
    if not hasattr(model, "ten_J_rownnz"):  # dense ten_J (MuJoCo < 3.3)
        return tj.reshape(nt, nv)
    out = np.zeros((nt, nv))
    rownnz, rowadr, colind = model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind
    for t in range(nt):
        a, n = int(rowadr[t]), int(rownnz[t])
        out[t, colind[a:a + n]] = tj[a:a + n]
    return out


def _coordinate_direction(
    model: mujoco.MjModel, qpos: np.ndarray, qadr: int, plan: Sequence[JointEquality]
) -> np.ndarray:
    """d qpos / d qpos[qadr] (nq,) when the equality-driven joints follow their drivers."""
    dq = np.zeros(model.nq)
    dq[qadr] = 1.0
    for e in plan:
        if e.qadr2 is None:
            dq[e.qadr1] = 0.0
            continue
        _, c1, c2, c3, c4 = e.coef
        x = float(qpos[e.qadr2]) - e.ref2
        dq[e.qadr1] = (c1 + x * (2 * c2 + x * (3 * c3 + x * 4 * c4))) * dq[e.qadr2]
    return dq


def _qpos_to_dof(model: mujoco.MjModel, dq: np.ndarray) -> np.ndarray:
    """Map a qpos-space direction of hinge/slide joints to dof space (nv,)."""
    dv = np.zeros(model.nv)
    for j in range(model.njnt):
        if int(model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
            dv[model.jnt_dofadr[j]] = dq[model.jnt_qposadr[j]]
    return dv


def mujoco_moment_arms(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    values: Mapping[str, float],
    coordinates: Sequence[str],
    *,
    plan: list[JointEquality] | None = None,
    method: str = "fd",
    h: float = FD_STEP,
) -> np.ndarray:
    """MuJoCo moment arms (ntendon, len(coordinates)), metres (or dimensionless for a
    translational coordinate): ``-dL/dq`` of every tendon about every named joint, at the pose of
    joint ``values``, with equality-driven joints following (OpenSim's sign convention).

    ``method="fd"``: central differences with step ``h`` through :func:`pose_mujoco`;
    ``method="jacobian"``: the tendon Jacobian ``ten_J`` projected on the coordinate's direction
    in joint space, whose equality-driven components come from the derivatives of the equality
    polynomials. Leaves ``data`` in a perturbed pose (fd) or at ``values`` (jacobian).
    """
    plan = joint_equality_plan(model) if plan is None else plan
    out = np.zeros((model.ntendon, len(coordinates)))
    base = {k: float(v) for k, v in values.items()}
    if method == "fd":
        for k, c in enumerate(coordinates):
            q0 = base.get(c, float(model.qpos0[joint_qpos_address(model, c)]))
            up = mujoco_tendon_lengths(model, data, {**base, c: q0 + h}, plan=plan)
            dn = mujoco_tendon_lengths(model, data, {**base, c: q0 - h}, plan=plan)
            out[:, k] = -(up - dn) / (2 * h)
        return out
    if method != "jacobian":
        raise ValueError(f"method must be 'fd' or 'jacobian', not {method!r}")
    mujoco_tendon_lengths(model, data, base, plan=plan)
    jac = _tendon_jacobian(model, data)
    qpos = np.array(data.qpos, dtype=float)
    for k, c in enumerate(coordinates):
        dv = _qpos_to_dof(model, _coordinate_direction(model, qpos, joint_qpos_address(model, c), plan))
        out[:, k] = -(jac @ dv)
    return out


# --------------------------------------------------------------------------------------------
# OpenSim side
# --------------------------------------------------------------------------------------------


def _path_forces(os_model: Any) -> list[tuple[str, str, Any]]:
    """(name, concrete class, downcast object) of every path force: PathActuators (muscles
    included), Ligaments and PathSprings."""
    import opensim

    out = []
    fs = os_model.getForceSet()
    for i in range(fs.getSize()):
        f = fs.get(i)
        for cls in (opensim.PathActuator, opensim.Ligament, opensim.PathSpring):
            obj = cls.safeDownCast(f)
            if obj is not None:
                out.append((f.getName(), f.getConcreteClassName(), obj))
                break
    return out


def _is_actuator(obj: Any) -> bool:
    import opensim

    return opensim.PathActuator.safeDownCast(obj) is not None


class _Pair:
    """An OpenSim model and its MuJoCo twin, loaded and matched (coordinates, path forces)."""

    def __init__(self, osim_path: str | os.PathLike, mjcf_path: str | os.PathLike,
                 assembly_accuracy: float | None = 1e-12):
        import opensim

        self.osim_path, self.mjcf_path = os.fspath(osim_path), os.fspath(mjcf_path)
        self.os_model, self.init_state = _load_opensim(self.osim_path, assembly_accuracy)
        self.mj_model = _load_mujoco(self.mjcf_path)
        self.mj_data = mujoco.MjData(self.mj_model)
        self.plan = joint_equality_plan(self.mj_model)
        self.opensim = opensim

        cs = self.os_model.getCoordinateSet()
        self.coords = [cs.get(i) for i in range(cs.getSize())]
        st = self.init_state
        self.locked = [c.getName() for c in self.coords if c.getLocked(st)]
        self.dependent = [c.getName() for c in self.coords if not c.getLocked(st) and c.isDependent(st)]
        skip = set(self.locked) | set(self.dependent)
        self.indep = [c for c in self.coords if c.getName() not in skip]
        self.indep_names = [c.getName() for c in self.indep]
        missing = []
        for name in self.indep_names:
            try:
                joint_qpos_address(self.mj_model, name)
            except KeyError:
                missing.append(name)
        if missing:
            raise MissingJointError(missing, self.mjcf_path)
        self.defaults = {c.getName(): float(c.getValue(st)) for c in self.indep}

        self.forces = _path_forces(self.os_model)
        m = self.mj_model
        tendon_names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_TENDON, i) or f"<tendon {i}>"
                        for i in range(m.ntendon)]
        self.tendon_names = tendon_names
        tid = {n: i for i, n in enumerate(tendon_names)}
        self.matched = [(n, k, obj) for n, k, obj in self.forces if n in tid]
        self.tendon_ids = np.array([tid[n] for n, _, _ in self.matched], dtype=int)
        self.missing_tendons = [n for n, _, _ in self.forces if n not in tid]
        os_names = {n for n, _, _ in self.forces}
        self.extra_tendons = [n for n in tendon_names if n not in os_names]

    # -- OpenSim ------------------------------------------------------------------------
    def os_state(self, values: Mapping[str, float] | None, assemble: bool = True) -> Any:
        """A realised OpenSim state: init_state when ``values`` is None, else a copy with the
        given independent coordinates set and assembled (when ``assemble``, or when some
        coordinate is dependent). Raises on assembly failure."""
        if values is None:
            state = self.init_state
        else:
            state = self.opensim.State(self.init_state)
            for c in self.indep:
                if c.getName() in values:
                    c.setValue(state, float(values[c.getName()]), False)
            if assemble or self.dependent:
                self.os_model.assemble(state)
        self.os_model.realizePosition(state)
        return state

    def os_indep_values(self, state: Any) -> dict[str, float]:
        return {c.getName(): float(c.getValue(state)) for c in self.indep}

    def os_lengths(self, state: Any) -> np.ndarray:
        return np.array([obj.getLength(state) for _, _, obj in self.matched], dtype=float)

    def coord(self, name: str) -> Any:
        for c in self.indep:
            if c.getName() == name:
                return c
        raise KeyError(f"{name!r} is not an independent OpenSim coordinate of {self.osim_path}")

    def force(self, name: str) -> Any:
        for n, _, obj in self.matched:
            if n == name:
                return obj
        raise KeyError(f"{name!r} is not an OpenSim path force with a MuJoCo tendon of that name")

    # -- MuJoCo -------------------------------------------------------------------------
    def mj_lengths(self, values: Mapping[str, float]) -> np.ndarray:
        return mujoco_tendon_lengths(self.mj_model, self.mj_data, values, plan=self.plan)

    # -- structure ----------------------------------------------------------------------
    def dependent_drivers(self) -> dict[str, set[str]]:
        """Dependent coordinate -> the independent coordinates that move it (found by moving
        each independent coordinate to two values in its range and assembling)."""
        out: dict[str, set[str]] = {d: set() for d in self.dependent}
        if not self.dependent:
            return out
        dep = [c for c in self.coords if c.getName() in out]
        ref = {c.getName(): float(c.getValue(self.init_state)) for c in dep}
        for c in self.indep:
            lo, hi = _sample_bounds(c)
            for frac in (0.2, 0.8):
                try:
                    st = self.os_state({c.getName(): lo + frac * (hi - lo)})
                except Exception:
                    continue
                for d in dep:
                    if abs(float(d.getValue(st)) - ref[d.getName()]) > 1e-10:
                        out[d.getName()].add(c.getName())
        return out

    def spanned(self) -> dict[str, set[str]]:
        """Muscle -> independent coordinates it spans in OpenSim: the coordinates of the joints
        connecting the bodies of its path points and wrap objects, those of its moving and
        conditional points, and the independent coordinates driving any of them."""
        opensim = self.opensim
        parent: dict[str, tuple[Any, str]] = {}
        js = self.os_model.getJointSet()
        for i in range(js.getSize()):
            j = js.get(i)
            child = j.getChildFrame().findBaseFrame().getName()
            parent.setdefault(child, (j, j.getParentFrame().findBaseFrame().getName()))

        def chain(body: str) -> list[str]:
            out, seen = [], set()
            while body in parent and body not in seen:
                seen.add(body)
                j, body = parent[body]
                out.append(j.getName())
            return out

        joint_coords: dict[str, list[str]] = {}
        for i in range(js.getSize()):
            j = js.get(i)
            joint_coords[j.getName()] = [j.get_coordinates(k).getName() for k in range(j.numCoordinates())]
        drivers = self.dependent_drivers()
        indep = set(self.indep_names)

        def resolve(names: set[str]) -> set[str]:
            out = set()
            for n in names:
                if n in indep:
                    out.add(n)
                elif n in drivers:
                    out |= drivers[n]
            return out

        spans: dict[str, set[str]] = {}
        for name, _, obj in self.matched:
            try:
                gp = obj.getGeometryPath()
            except Exception:  # not a GeometryPath (e.g. FunctionBasedPath): check everything
                spans[name] = set(indep)
                continue
            bodies, coords = set(), set()
            pps = gp.getPathPointSet()
            for i in range(pps.getSize()):
                p = pps.get(i)
                bodies.add(p.getParentFrame().findBaseFrame().getName())
                mp = opensim.MovingPathPoint.safeDownCast(p)
                if mp is not None:
                    for has, get in ((mp.hasXCoordinate, mp.getXCoordinate), (mp.hasYCoordinate, mp.getYCoordinate),
                                     (mp.hasZCoordinate, mp.getZCoordinate)):
                        try:
                            if has():
                                coords.add(get().getName())
                        except Exception:
                            pass
                cp = opensim.ConditionalPathPoint.safeDownCast(p)
                if cp is not None:
                    try:
                        coords.add(cp.getCoordinate().getName())
                    except Exception:
                        pass
            ws = gp.getWrapSet()
            for i in range(ws.getSize()):
                try:
                    bodies.add(ws.get(i).getWrapObject().getFrame().findBaseFrame().getName())
                except Exception:
                    pass
            chains = [set(chain(b)) for b in bodies]
            joints = set().union(*chains) - set.intersection(*chains) if chains else set()
            for j in joints:
                coords.update(joint_coords.get(j, []))
            spans[name] = resolve(coords)
        return spans

    def sweep_values(self, coordinate: Any, step: float, linear_step: float) -> np.ndarray:
        lo, hi = _sample_bounds(coordinate)
        s = linear_step if coordinate.getMotionType() == _TRANSLATIONAL else step
        n = max(int(math.ceil((hi - lo) / s - 1e-9)) + 1, 2)
        return np.linspace(lo, hi, n)


def _nan_rms(x: np.ndarray) -> float:
    """RMS of the finite values of ``x`` (NaN when there are none)."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def opensim_spikes(pair: _Pair, values: Mapping[str, float], muscles: Sequence[int],
                   lengths: np.ndarray | None = None) -> dict[int, dict[str, Any]]:
    """The muscles (indices into ``pair.matched``) whose OpenSim length is an isolated spike at
    the pose of independent ``values``: for some independent coordinate, moving it by
    :data:`SPIKE_STEP` radians (:data:`SPIKE_LINEAR_STEP` m) either way gives two lengths that
    agree with each other within :data:`SPIKE_TOL` while the length at the pose differs from
    their mean by more than :data:`SPIKE_TOL`. A smooth path cannot do that (its second
    difference over 0.01 rad is ~1e-5 m), nor can a conditional point's switch (a step, where
    the two neighbours differ); it is OpenSim's wrapping taking a wrong way round in a narrow band
    of poses (Arm26's BIClong round BIClonghh: 86 mm longer for shoulder elevation in 0.515-0.518
    rad). Returns muscle index -> {"coordinate", "length", "neighbours"} (m)."""
    out: dict[int, dict[str, Any]] = {}
    if not len(muscles):
        return out
    idx = np.asarray(list(muscles), dtype=int)
    base = pair.os_lengths(pair.os_state(values)) if lengths is None else np.asarray(lengths)
    for c in pair.indep:
        name = c.getName()
        h = SPIKE_LINEAR_STEP if int(c.getMotionType()) == _TRANSLATIONAL else SPIKE_STEP
        try:
            up = pair.os_lengths(pair.os_state({**values, name: values[name] + h}))
            dn = pair.os_lengths(pair.os_state({**values, name: values[name] - h}))
        except Exception:
            continue
        for i in idx:
            if int(i) in out:
                continue
            if abs(up[i] - dn[i]) < SPIKE_TOL and abs(base[i] - 0.5 * (up[i] + dn[i])) > SPIKE_TOL:
                out[int(i)] = {"coordinate": name, "length": float(base[i]),
                               "neighbours": [float(dn[i]), float(up[i])]}
    return out


# --------------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------------


@dataclass
class MomentArmError:
    """Moment-arm error of one (muscle, coordinate) pair over the moment-arm poses, metres
    (dimensionless for a translational coordinate): ``rms`` and ``max`` of MuJoCo minus
    OpenSim, and the largest magnitude in each model."""

    rms: float
    max: float
    max_abs_opensim: float
    max_abs_mujoco: float
    #: RMS of MuJoCo minus OpenSim's own -dL/dq (central differences, dependent coordinates
    #: following their couplers), and RMS of OpenSim's computeMomentArm minus that -dL/dq.
    rms_vs_dldq: float = 0.0
    opensim_compute_vs_dldq: float = 0.0


@dataclass
class MuscleError:
    """Errors of one muscle-tendon unit over all poses.

    ``max_len``/``rms_len`` (m) of the length error, ``max_len_pct``/``rms_len_pct`` of it in
    percent of OpenSim's length; ``length_range`` is OpenSim's (min, max) length (m);
    ``moment_arms`` maps each compared coordinate to its :class:`MomentArmError`.
    """

    kind: str
    max_len: float
    rms_len: float
    max_len_pct: float
    rms_len_pct: float
    length_range: tuple[float, float]
    moment_arms: dict[str, MomentArmError] = field(default_factory=dict)


@dataclass
class MuscleReport:
    """Result of :func:`compare_muscles`. Lengths and moment arms in metres.

    ``muscles`` maps each OpenSim path force that has a MuJoCo tendon of the same name to its
    :class:`MuscleError`. ``ma_median``/``ma_p95``/``ma_max`` are the median, 95th percentile
    and maximum of the per-pair RMS moment-arm errors over ``ma_pairs`` (muscle, coordinate)
    pairs (pairs where both models' moment arm stays below 1e-7 m are left out).
    ``ma_fd_vs_jacobian`` is the largest difference between MuJoCo's finite-difference and
    Jacobian moment arms (a check of the MuJoCo side). ``missing_tendons``: OpenSim path forces
    without a MuJoCo tendon; ``extra_tendons``: MuJoCo tendons without an OpenSim path force;
    ``actuator_issues``: muscle -> what is wrong with its MuJoCo actuator (missing, wrong
    transmission or gear). ``worst_length`` describes the largest length error (muscle, pose
    index, error, independent coordinate values).
    """

    osim_path: str
    mjcf_path: str
    n_poses: int
    ma_poses: int
    coordinates: list[str]
    muscles: dict[str, MuscleError]
    max_len_error: float
    max_len_pct: float
    ma_pairs: int
    ma_median: float
    ma_p95: float
    ma_max: float
    ma_fd_vs_jacobian: float = 0.0
    #: Median / 95th percentile / max of the per-pair RMS errors against OpenSim's own -dL/dq.
    ma_dldq_median: float = 0.0
    ma_dldq_p95: float = 0.0
    ma_dldq_max: float = 0.0
    missing_tendons: list[str] = field(default_factory=list)
    extra_tendons: list[str] = field(default_factory=list)
    actuator_issues: dict[str, str] = field(default_factory=dict)
    dependent_coordinates: list[str] = field(default_factory=list)
    locked_coordinates: list[str] = field(default_factory=list)
    worst_length: dict[str, Any] | None = None
    skipped_poses: int = 0
    #: (muscle, pose) samples left out because OpenSim's own length spikes there
    #: (:func:`opensim_spikes`): each {"muscle", "pose", "coordinate", "length", "neighbours"}.
    opensim_spikes: list[dict[str, Any]] = field(default_factory=list)

    @property
    def name(self) -> str:
        """Model name: the .osim file name without its extension."""
        return os.path.splitext(os.path.basename(self.osim_path))[0]

    def ok(self, len_pct: float = LEN_PCT, ma_median_mm: float = MA_MEDIAN_MM, ma_p95_mm: float = MA_P95_MM,
           ma_max_mm: float = MA_MAX_MM) -> bool:
        """True when at least one pose was compared, every OpenSim path force has its tendon
        (and, for actuators, a correct actuator), every length error is within ``len_pct``
        percent, and the median / 95th percentile / maximum RMS moment-arm errors are within
        the given millimetres."""
        return (
            self.n_poses > 0
            and not self.missing_tendons
            and not self.actuator_issues
            and self.max_len_pct <= len_pct
            and self.ma_median * 1e3 <= ma_median_mm
            and self.ma_p95 * 1e3 <= ma_p95_mm
            and self.ma_max * 1e3 <= ma_max_mm
        )

    def worst_moment_arms(self, n: int = 5) -> list[tuple[str, str, MomentArmError]]:
        """The ``n`` (muscle, coordinate, error) pairs with the largest RMS moment-arm error."""
        rows = [(m, c, e) for m, me in self.muscles.items() for c, e in me.moment_arms.items()]
        rows.sort(key=lambda r: -r[2].rms)
        return rows[:n]

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict of every field (plus ``name`` and ``ok``)."""
        d = asdict(self)
        d["name"] = self.name
        d["ok"] = self.ok()
        return _clean(d)

    def summary(self) -> str:
        """Readable report: one row per muscle (length errors in mm and %, worst moment arm),
        the aggregates, the worst pairs and the verdict."""
        lines = [
            f"{self.name}: {len(self.muscles)} muscles, {self.n_poses} poses ({self.ma_poses} for moment arms), "
            f"{len(self.coordinates)} coordinates"
            + (f", {self.skipped_poses} poses skipped (assembly failed)" if self.skipped_poses else "")
            + (f", {len(self.opensim_spikes)} (muscle, pose) samples left out where OpenSim's own length spikes"
               if self.opensim_spikes else ""),
        ]
        w = max([len("muscle")] + [len(m) for m in self.muscles])
        lines.append(f"  {'muscle':<{w}}  {'max len mm':>10}  {'rms len mm':>10}  {'max len %':>9}  "
                     f"{'MA pairs':>8}  {'worst MA rms mm':>15}  coordinate")
        for m, e in self.muscles.items():
            worst = max(e.moment_arms.items(), key=lambda kv: kv[1].rms, default=None)
            wtxt = f"{worst[1].rms * 1e3:15.3g}  {worst[0]}" if worst else f"{'-':>15}"
            lines.append(f"  {m:<{w}}  {e.max_len * 1e3:10.3g}  {e.rms_len * 1e3:10.3g}  {e.max_len_pct:9.3g}  "
                         f"{len(e.moment_arms):8d}  {wtxt}")
        lines.append(f"  length error max {self.max_len_error * 1e3:.3g} mm, {self.max_len_pct:.3g} %")
        lines.append(f"  moment-arm RMS error over {self.ma_pairs} pairs: median {self.ma_median * 1e3:.3g} mm, "
                     f"95th percentile {self.ma_p95 * 1e3:.3g} mm, max {self.ma_max * 1e3:.3g} mm "
                     f"(MuJoCo finite differences vs Jacobian: {self.ma_fd_vs_jacobian * 1e3:.2g} mm)")
        lines.append(f"  against OpenSim's own -dL/dq: median {self.ma_dldq_median * 1e3:.3g} mm, 95th percentile "
                     f"{self.ma_dldq_p95 * 1e3:.3g} mm, max {self.ma_dldq_max * 1e3:.3g} mm")
        worst = [r for r in self.worst_moment_arms(3) if r[2].rms > 0]
        if worst:
            lines.append("  worst moment arms: " + "; ".join(
                f"{m}/{c} {e.rms * 1e3:.3g} mm rms (OpenSim up to {e.max_abs_opensim * 1e3:.3g} mm)"
                for m, c, e in worst))
        if self.worst_length:
            wl = self.worst_length
            lines.append(f"  worst length: {wl['muscle']} {wl['error'] * 1e3:.3g} mm at pose #{wl['pose']}")
        if self.missing_tendons:
            lines.append(f"  no MuJoCo tendon: {', '.join(self.missing_tendons)}")
        if self.extra_tendons:
            lines.append(f"  only in MuJoCo: {', '.join(self.extra_tendons)}")
        for m, why in self.actuator_issues.items():
            lines.append(f"  actuator {m}: {why}")
        lines.append(f"  {'OK' if self.ok() else 'FAIL'}")
        return "\n".join(lines)

    def plot_moment_arms(self, muscle: str, coordinate: str, ax: Any = None, **kw: Any) -> Any:
        """:func:`plot_moment_arms` on this report's two models."""
        return plot_moment_arms(self.osim_path, self.mjcf_path, muscle, coordinate, ax=ax, **kw)


def format_muscle_table(reports: Mapping[str, MuscleReport]) -> str:
    """Plain-text table, one row per model: muscles, poses, max length error (mm and %),
    moment-arm pairs and the median / 95th percentile / max of their RMS errors (mm), ok."""
    head = ("model", "muscles", "poses", "len mm", "len %", "MA pairs", "MA med mm", "MA p95 mm", "MA max mm", "ok")
    rows = [
        (
            name,
            str(len(r.muscles)) + (f" (+{len(r.missing_tendons)} missing)" if r.missing_tendons else ""),
            str(r.n_poses),
            f"{r.max_len_error * 1e3:.3g}",
            f"{r.max_len_pct:.3g}",
            str(r.ma_pairs),
            f"{r.ma_median * 1e3:.3g}",
            f"{r.ma_p95 * 1e3:.3g}",
            f"{r.ma_max * 1e3:.3g}",
            "yes" if r.ok() else "NO",
        )
        for name, r in reports.items()
    ]
    return text_table(head, rows)


# --------------------------------------------------------------------------------------------
# Comparison
# --------------------------------------------------------------------------------------------


def _actuator_issues(pair: _Pair) -> dict[str, str]:
    m = pair.mj_model
    out = {}
    for name, _, obj in pair.matched:
        if not _is_actuator(obj):
            continue
        aid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        if aid < 0:
            out[name] = "no MuJoCo actuator of that name"
            continue
        tid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, name)
        if int(m.actuator_trntype[aid]) != int(mujoco.mjtTrn.mjTRN_TENDON) or int(m.actuator_trnid[aid, 0]) != tid:
            out[name] = "does not act through the tendon of the same name"
        elif abs(float(m.actuator_gear[aid, 0]) - 1.0) > 1e-12:
            out[name] = f"gear {float(m.actuator_gear[aid, 0]):g}, not 1 (actuator_length != tendon length)"
    return out


def compare_muscles(
    osim_path: str | os.PathLike,
    mjcf_path: str | os.PathLike,
    *,
    n_poses: int = 200,
    seed: int = 0,
    ma_poses: int | None = None,
    progress: bool = False,
    assembly_accuracy: float | None = 1e-12,
    ma_method: str = "fd",
) -> MuscleReport:
    """Compare muscle-tendon lengths and moment arms of an OpenSim model and its MuJoCo twin.

    Poses are those of :func:`o2m.validate.compare_kinematics` with the same ``n_poses`` and
    ``seed``: pose 0 is the default pose, the others draw every independent coordinate uniformly
    in its range from ``numpy.random.default_rng(seed)``; OpenSim assembles (accuracy
    ``assembly_accuracy``), its independent values go to the MuJoCo joints of the same name and
    MuJoCo's joint equalities drive the rest. Lengths: OpenSim ``getLength(state)`` against
    MuJoCo ``ten_length``.

    Moment arms, on the first ``ma_poses`` compared poses (default ``min(n_poses, 50)``):
    OpenSim ``computeMomentArm(state, coordinate)`` against MuJoCo ``-dL/dq`` (central
    differences, ``ma_method="fd"``, or the projected tendon Jacobian, ``"jacobian"``; both
    are computed and their largest difference reported), for each muscle and each independent
    coordinate it spans in OpenSim (joints between its bodies, moving/conditional points,
    through couplings) or whose MuJoCo moment arm is not zero.

    Raises :class:`o2m.errors.ModelFileError` / :class:`o2m.validate.ValidationError` when a
    model cannot be loaded and :class:`o2m.validate.MissingJointError` when an independent
    coordinate has no MuJoCo joint.
    """
    if n_poses < 1:
        raise ValueError("n_poses must be at least 1")
    if ma_method not in ("fd", "jacobian"):
        raise ValueError(f"ma_method must be 'fd' or 'jacobian', not {ma_method!r}")
    from tqdm.auto import tqdm

    pair = _Pair(osim_path, mjcf_path, assembly_accuracy)
    n_ma = min(n_poses, 50) if ma_poses is None else max(0, min(int(ma_poses), n_poses))
    names = [n for n, _, _ in pair.matched]
    nm, nc = len(names), len(pair.indep_names)
    tids = pair.tendon_ids

    rng = np.random.default_rng(seed)
    bounds = np.array([_sample_bounds(c) for c in pair.indep], dtype=float).reshape(-1, 2)
    samples = rng.uniform(bounds[:, 0], bounds[:, 1], size=(max(n_poses - 1, 0), nc))

    err_sq = np.zeros(nm)
    pct_sq = np.zeros(nm)
    max_err = np.zeros(nm)
    max_pct = np.zeros(nm)
    len_min = np.full(nm, np.inf)
    len_max = np.full(nm, -np.inf)
    worst: dict[str, Any] | None = None
    n_done = skipped = 0
    n_valid = np.zeros(nm, dtype=int)
    spikes: list[dict[str, Any]] = []
    ma_states: list[Any] = []
    ma_mj: list[np.ndarray] = []  # (nm, nc) per moment-arm pose
    ma_valid: list[np.ndarray] = []  # (nm,) bool per moment-arm pose: not an OpenSim spike
    fd_vs_jac = 0.0

    desc = f"muscles {os.path.basename(pair.osim_path)}"
    for k in tqdm(range(n_poses), disable=not progress, desc=desc):
        try:
            state = pair.os_state(None if k == 0 else dict(zip(pair.indep_names, samples[k - 1], strict=True)))
        except Exception:  # assembly failure: skip this pose
            skipped += 1
            continue
        values = pair.os_indep_values(state)
        l_os = pair.os_lengths(state)
        l_mj = pair.mj_lengths(values)[tids]
        err = np.abs(l_mj - l_os)
        valid = np.ones(nm, dtype=bool)
        suspects = np.flatnonzero(err > SPIKE_TOL)
        if suspects.size:  # only a sample whose error is over SPIKE_TOL can be an OpenSim spike
            for i, info in opensim_spikes(pair, values, suspects, l_os).items():
                valid[i] = False
                spikes.append({"muscle": names[i], "pose": k, **info})
        err = np.where(valid, err, 0.0)
        n_valid += valid
        pct = 100.0 * err / np.maximum(np.abs(l_os), 1e-12)
        err_sq += err**2
        pct_sq += pct**2
        np.maximum(max_err, err, out=max_err)
        np.maximum(max_pct, pct, out=max_pct)
        np.minimum(len_min, np.where(valid, l_os, np.inf), out=len_min)
        np.maximum(len_max, np.where(valid, l_os, -np.inf), out=len_max)
        if nm:
            i = int(np.argmax(err))
            if worst is None or err[i] > worst["error"]:
                worst = {"muscle": names[i], "pose": k, "error": float(err[i]), "values": values}
        if n_done < n_ma:
            m_ma = pair.mj_model, pair.mj_data
            fd = mujoco_moment_arms(*m_ma, values, pair.indep_names, plan=pair.plan, method="fd")[tids]
            jac = mujoco_moment_arms(*m_ma, values, pair.indep_names, plan=pair.plan, method="jacobian")[tids]
            if fd.size:
                fd_vs_jac = max(fd_vs_jac, float(np.max(np.abs(fd - jac))))
            ma_mj.append(fd if ma_method == "fd" else jac)
            ma_states.append(state)
            ma_valid.append(valid)
        n_done += 1

    # Moment arms: pairs OpenSim spans, or MuJoCo moves.
    spans = pair.spanned()
    mj_nonzero = np.max(np.abs(np.stack(ma_mj)), axis=0) > MA_ZERO if ma_mj else np.zeros((nm, nc), bool)
    coord_objs = pair.indep
    moment_arms: dict[str, dict[str, MomentArmError]] = {n: {} for n in names}
    rms_all: list[float] = []
    rms_fd_all: list[float] = []
    dldq_cache: dict[tuple[int, int], np.ndarray] = {}

    def os_dldq(k: int, j: int) -> np.ndarray:
        """OpenSim's own -dL/dq of every path at moment-arm pose k about coordinate j: central
        differences with steps of 10 and 100 FD_STEP, NaN where the two differ by more than
        DLDQ_CONSISTENCY (a step of OpenSim's own length, e.g. a conditional point switching,
        or an assembly that had to relax its tolerance, inside the step)."""
        if (k, j) not in dldq_cache:
            values = pair.os_indep_values(ma_states[k])
            c = pair.indep_names[j]
            try:
                est = []
                for h in (FD_STEP * 10, FD_STEP * 100):
                    up = pair.os_lengths(pair.os_state({**values, c: values[c] + h}, assemble=bool(pair.dependent)))
                    dn = pair.os_lengths(pair.os_state({**values, c: values[c] - h}, assemble=bool(pair.dependent)))
                    est.append(-(up - dn) / (2 * h))
                dldq_cache[(k, j)] = np.where(np.abs(est[0] - est[1]) <= DLDQ_CONSISTENCY, est[0], np.nan)
            except Exception:
                dldq_cache[(k, j)] = np.full(nm, np.nan)
        return dldq_cache[(k, j)]

    for i, (name, _, obj) in enumerate(pair.matched):
        for j, cname in enumerate(pair.indep_names):
            if not ma_mj or not (cname in spans.get(name, set()) or mj_nonzero[i, j]):
                continue
            use = [k for k, v in enumerate(ma_valid) if v[i]]
            if not use:
                continue
            r_os = np.array([obj.computeMomentArm(ma_states[k], coord_objs[j]) for k in use], dtype=float)
            r_mj = np.array([ma_mj[k][i, j] for k in use])
            r_fd = np.array([os_dldq(k, j)[i] for k in use])
            if np.max(np.abs(r_os)) <= MA_ZERO and np.max(np.abs(r_mj)) <= MA_ZERO:
                continue
            d = r_mj - r_os
            e = MomentArmError(
                rms=float(np.sqrt(np.mean(d**2))),
                max=float(np.max(np.abs(d))),
                max_abs_opensim=float(np.max(np.abs(r_os))),
                max_abs_mujoco=float(np.max(np.abs(r_mj))),
                rms_vs_dldq=_nan_rms(r_mj - r_fd),
                opensim_compute_vs_dldq=_nan_rms(r_os - r_fd),
            )
            moment_arms[name][cname] = e
            rms_all.append(e.rms)
            rms_fd_all.append(e.rms_vs_dldq)

    nd = np.maximum(n_valid, 1)
    muscles = {
        n: MuscleError(
            kind=kind,
            max_len=float(max_err[i]),
            rms_len=float(np.sqrt(err_sq[i] / nd[i])),
            max_len_pct=float(max_pct[i]),
            rms_len_pct=float(np.sqrt(pct_sq[i] / nd[i])),
            length_range=(float(len_min[i]), float(len_max[i])),
            moment_arms=moment_arms[n],
        )
        for i, (n, kind, _) in enumerate(pair.matched)
    }
    rms_arr = np.array(rms_all)
    rms_fd = np.array([v for v in rms_fd_all if np.isfinite(v)])
    return MuscleReport(
        osim_path=pair.osim_path,
        mjcf_path=pair.mjcf_path,
        n_poses=n_done,
        ma_poses=len(ma_states),
        coordinates=pair.indep_names,
        muscles=muscles,
        max_len_error=float(max_err.max()) if nm else 0.0,
        max_len_pct=float(max_pct.max()) if nm else 0.0,
        ma_pairs=len(rms_all),
        ma_median=float(np.median(rms_arr)) if rms_all else 0.0,
        ma_p95=float(np.percentile(rms_arr, 95)) if rms_all else 0.0,
        ma_max=float(rms_arr.max()) if rms_all else 0.0,
        ma_fd_vs_jacobian=fd_vs_jac,
        ma_dldq_median=float(np.median(rms_fd)) if rms_fd.size else 0.0,
        ma_dldq_p95=float(np.percentile(rms_fd, 95)) if rms_fd.size else 0.0,
        ma_dldq_max=float(rms_fd.max()) if rms_fd.size else 0.0,
        missing_tendons=pair.missing_tendons,
        extra_tendons=pair.extra_tendons,
        actuator_issues=_actuator_issues(pair),
        dependent_coordinates=pair.dependent,
        locked_coordinates=pair.locked,
        worst_length=worst,
        skipped_poses=skipped,
        opensim_spikes=spikes,
    )


# --------------------------------------------------------------------------------------------
# Sweeps
# --------------------------------------------------------------------------------------------


def sweep_jumps(
    osim_path: str | os.PathLike,
    mjcf_path: str | os.PathLike,
    *,
    step: float = float(np.deg2rad(1)),
    linear_step: float = 1e-3,
    opensim: bool = True,
    jump_factor: float = 2.0,
    jump_atol: float = 1e-3,
    progress: bool = False,
    assembly_accuracy: float | None = 1e-12,
) -> dict[str, Any]:
    """Sweep each independent coordinate over its range (steps of ``step`` radians, or
    ``linear_step`` metres for a translational coordinate; the others at their defaults) and
    report the largest change of each tendon length between neighbouring steps.

    Returns a JSON-safe dict::

        {"osim_path", "mjcf_path", "step", "linear_step",
         "coordinates": {coordinate: {"range": [lo, hi], "steps": n, "opensim_swept": bool,
             "tendons": {tendon: {"mujoco": max |dL| (m), "mujoco_at": [q0, q1],
                                  "opensim": max |dL| (m) or None, "opensim_at": [q0, q1] or None}}}},
         "worst": {tendon: {"coordinate", "mujoco", "opensim"}},   # each tendon's largest MuJoCo jump
         "jumps": [{"tendon", "coordinate", "mujoco", "opensim", "at"}, ...]}

    ``jumps`` lists, largest first, the (tendon, coordinate) pairs whose MuJoCo jump exceeds
    ``jump_factor`` times OpenSim's plus ``jump_atol`` metres (without OpenSim, with
    ``opensim=False`` or for a tendon OpenSim lacks: ``jump_atol`` alone): wrapping flips and
    other discontinuities. OpenSim steps that fail to assemble are left out. OpenSim is swept
    only along coordinates that some OpenSim path spans or that change some MuJoCo tendon length
    (``opensim_swept``); along the others every OpenSim jump is 0 (e.g. a free base's
    translations, which would take thousands of 1 mm steps).
    """
    from tqdm.auto import tqdm

    pair = _Pair(osim_path, mjcf_path, assembly_accuracy)
    tnames = pair.tendon_names
    os_index = {n: i for i, (n, _, _) in enumerate(pair.matched)}
    out: dict[str, Any] = {"osim_path": pair.osim_path, "mjcf_path": pair.mjcf_path, "step": float(step),
                           "linear_step": float(linear_step), "coordinates": {}, "worst": {}, "jumps": []}
    spans = pair.spanned() if opensim else {}
    desc = f"sweep {os.path.basename(pair.osim_path)}"
    for c in tqdm(pair.indep, disable=not progress, desc=desc):
        cname = c.getName()
        qs = pair.sweep_values(c, step, linear_step)
        l_mj = np.array([pair.mj_lengths({**pair.defaults, cname: float(q)}) for q in qs]).reshape(len(qs), -1)
        l_os = np.full((len(qs), len(pair.matched)), np.nan)
        # OpenSim only where a length can change: a path spans the coordinate in OpenSim, or a
        # MuJoCo tendon length changes; elsewhere every OpenSim length is constant (jump 0).
        os_needed = opensim and bool(pair.matched) and (
            any(cname in s for s in spans.values()) or bool(l_mj.size and np.ptp(l_mj, axis=0).max() > 1e-12))
        if os_needed:
            for k, q in enumerate(qs):
                try:
                    l_os[k] = pair.os_lengths(pair.os_state({cname: float(q)}, assemble=False))
                except Exception:
                    pass
        elif opensim:
            l_os[:] = 0.0
        d_mj = np.abs(np.diff(l_mj, axis=0))
        d_os = np.abs(np.diff(l_os, axis=0))
        tend: dict[str, Any] = {}
        for t, tn in enumerate(tnames):
            k = int(np.argmax(d_mj[:, t])) if len(d_mj) else 0
            row: dict[str, Any] = {"mujoco": float(d_mj[k, t]) if len(d_mj) else 0.0,
                                   "mujoco_at": [float(qs[k]), float(qs[k + 1])],
                                   "opensim": None, "opensim_at": None}
            i = os_index.get(tn)
            if opensim and i is not None and np.isfinite(d_os[:, i]).any():
                ko = int(np.nanargmax(d_os[:, i]))
                row["opensim"] = float(d_os[ko, i])
                row["opensim_at"] = [float(qs[ko]), float(qs[ko + 1])]
            tend[tn] = row
            limit = jump_factor * (row["opensim"] or 0.0) + jump_atol
            if row["mujoco"] > limit:
                out["jumps"].append({"tendon": tn, "coordinate": cname, "mujoco": row["mujoco"],
                                     "opensim": row["opensim"], "at": row["mujoco_at"]})
            w = out["worst"].get(tn)
            if w is None or row["mujoco"] > w["mujoco"]:
                out["worst"][tn] = {"coordinate": cname, "mujoco": row["mujoco"], "opensim": row["opensim"]}
        lo, hi = _sample_bounds(c)
        out["coordinates"][cname] = {"range": [lo, hi], "steps": int(len(qs)), "opensim_swept": os_needed,
                                     "tendons": tend}
    out["jumps"].sort(key=lambda j: -j["mujoco"])
    return _clean(out)


def opensim_length_steps(
    osim_path: str | os.PathLike,
    mjcf_path: str | os.PathLike,
    *,
    step: float = float(np.deg2rad(0.5)),
    linear_step: float = 5e-4,
    min_step: float = 5e-4,
    bisections: int = 40,
    assembly_accuracy: float | None = 1e-12,
) -> list[dict[str, Any]]:
    """Discontinuities of OpenSim's own path lengths, and what they cost any continuous tendon.

    Each independent coordinate is swept over its range (the others at their defaults) in steps
    of ``step`` radians (``linear_step`` m); a neighbour interval whose length change stands out
    from its neighbours' by more than ``min_step`` / 2 is bisected ``bisections`` times towards
    the larger change. What is left (an interval of width ``range / 2**bisections``) changing by
    more than ``min_step`` metres is a step of OpenSim's length (a wrap switching on or off, a
    conditional point): a continuous function (a MuJoCo tendon without a matching flip) is at
    least half of it away from OpenSim on one side of it.

    Returns, largest ``floor_pct`` first, one dict per step::

        {"path", "coordinate", "at": q (rad or m), "height": L(after) - L(before) (m),
         "length": [L before, L after] (m),
         "floor_pct": 100 * |height| / 2 / max(length)}  # a lower bound on any continuous
                                                          # tendon's worst length error, in %

    Only steps at the sweep's poses are found (a step that a narrow spike makes, or one away
    from the other coordinates' defaults, can be missed): the floors are lower bounds.
    """
    from .lengthvia import outlying_changes

    pair = _Pair(osim_path, mjcf_path, assembly_accuracy)
    names = [n for n, _, _ in pair.matched]
    out: list[dict[str, Any]] = []
    spans = pair.spanned()

    def lengths(cname: str, q: float) -> np.ndarray:
        return pair.os_lengths(pair.os_state({**pair.defaults, cname: float(q)}, assemble=False))

    for c in pair.indep:
        cname = c.getName()
        paths = [i for i, n in enumerate(names) if cname in spans.get(n, set())]
        if not paths:
            continue
        qs = pair.sweep_values(c, step, linear_step)
        L = np.array([lengths(cname, q) for q in qs])[:, paths]
        dL = np.diff(L, axis=0)
        for col, i in enumerate(paths):
            for k in np.flatnonzero(outlying_changes(dL[:, col], min_step / 2)):
                a, b = float(qs[k]), float(qs[k + 1])
                la, lb = float(L[k, col]), float(L[k + 1, col])
                for _ in range(bisections):
                    mid = 0.5 * (a + b)
                    lm = float(lengths(cname, mid)[i])
                    if abs(lm - la) >= abs(lb - lm):
                        b, lb = mid, lm
                    else:
                        a, la = mid, lm
                if abs(lb - la) > min_step:
                    out.append({"path": names[i], "coordinate": cname, "at": 0.5 * (a + b),
                                "height": lb - la, "length": [la, lb],
                                "floor_pct": 100.0 * abs(lb - la) / 2.0 / max(la, lb)})
    out.sort(key=lambda s: -s["floor_pct"])
    return out


def continuous_tendon_front(
    osim_path: str | os.PathLike,
    mjcf_path: str | os.PathLike,
    muscle: str,
    coordinate: str,
    *,
    pcts: Sequence[float] = (LEN_PCT,),
    n: int = 600,
    assembly_accuracy: float | None = 1e-12,
) -> dict[str, Any]:
    """What any continuous tendon can reach against OpenSim, for one path along one coordinate.

    A MuJoCo tendon has one length, and its moment arm is ``-dL/dq`` of it. OpenSim's length can
    step (wraps switching), and its ``computeMomentArm`` need not be ``-dL/dq`` of its length
    (several wraps on one segment; a MovingPathPoint next to a point of its own body). Sweeping
    ``coordinate`` (``n`` poses over its range, the others at their defaults), this finds, for
    each length tolerance p in ``pcts`` (% of OpenSim's length at every pose), the least RMS and
    the largest moment-arm error against ``computeMomentArm`` of any continuous length within it
    (a bounded least-squares problem over the length at the sweep poses,
    :func:`scipy.optimize.lsq_linear`), or None where OpenSim's largest step leaves none within p
    (:func:`opensim_length_steps`). OpenSim's one-pose spikes (two opposite outlying changes, as
    :func:`o2m.lengthvia.outlying_changes` finds them) are no target. These are lower bounds for
    the issue's errors, which sample every coordinate.

    Returns ``{"q", "length", "moment_arm"`` (computeMomentArm) ``: (n,) arrays; "steps": the
    path's steps along the coordinate; "spikes": [q]; "inconsistency_rms", "inconsistency_max":
    computeMomentArm - (-dL/dq) away from outlying length changes (steps, spikes) (m);
    "floor_pct": the largest step's floor; "front": {p: {"rms", "max"} (m) or None}}``.
    """
    from scipy.optimize import lsq_linear

    from .lengthvia import one_pose_spikes, outlying_changes

    pair = _Pair(osim_path, mjcf_path, assembly_accuracy)
    c = pair.coord(coordinate)
    force = pair.force(muscle)
    lo, hi = _sample_bounds(c)
    qs = np.linspace(lo, hi, n)
    h = float(qs[1] - qs[0])
    length, arm = [], []
    for q in qs:
        state = pair.os_state({**pair.defaults, coordinate: float(q)}, assemble=False)
        length.append(force.getLength(state))
        arm.append(force.computeMomentArm(state, c))
    length_a, arm_a = np.array(length), np.array(arm)
    arm_mid = 0.5 * (arm_a[1:] + arm_a[:-1])
    d = np.diff(length_a)
    odd = outlying_changes(d)
    spike = one_pose_spikes(d, odd)
    spiky = spike[:-1] | spike[1:]
    steps = [s for s in opensim_length_steps(osim_path, mjcf_path, assembly_accuracy=assembly_accuracy)
             if s["path"] == muscle and s["coordinate"] == coordinate]
    diff = (arm_mid + d / h)[~odd]  # away from every outlying change: steps, spikes, kinks
    floor = max((st["floor_pct"] for st in steps), default=0.0)
    D = (np.eye(n, k=1) - np.eye(n))[:-1] / h
    front: dict[float, dict[str, float] | None] = {}
    for p in pcts:
        if p <= floor:
            front[float(p)] = None
            continue
        lo_b = np.where(spike, 0.0, length_a * (1 - p / 100))
        hi_b = np.where(spike, 2.0 * length_a, length_a * (1 + p / 100))
        r = lsq_linear(-D[~spiky], arm_mid[~spiky], bounds=(lo_b, hi_b))
        res = -D[~spiky] @ r.x - arm_mid[~spiky]
        front[float(p)] = {"rms": float(np.sqrt(np.mean(res**2))), "max": float(np.max(np.abs(res)))}
    return {"q": qs, "length": length_a, "moment_arm": arm_a, "steps": steps, "spikes": qs[spike].tolist(),
            "inconsistency_rms": float(np.sqrt(np.mean(diff**2))) if diff.size else 0.0,
            "inconsistency_max": float(np.max(np.abs(diff))) if diff.size else 0.0, "floor_pct": floor,
            "front": front}


def _moment_arm_curve(pair: _Pair, muscle: str, coordinate: str, n: int, method: str
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    c = pair.coord(coordinate)
    obj = pair.force(muscle)
    tid = int(pair.tendon_ids[[nm for nm, _, _ in pair.matched].index(muscle)])
    lo, hi = _sample_bounds(c)
    qs = np.linspace(lo, hi, n)
    r_os = np.full(n, np.nan)
    r_mj = np.empty(n)
    for k, q in enumerate(qs):
        values = {**pair.defaults, coordinate: float(q)}
        try:
            st = pair.os_state(values)
            r_os[k] = obj.computeMomentArm(st, c)
            values = pair.os_indep_values(st)
        except Exception:  # assembly failure: OpenSim NaN, MuJoCo at the requested value
            pass
        r_mj[k] = mujoco_moment_arms(pair.mj_model, pair.mj_data, values, [coordinate], plan=pair.plan,
                                     method=method)[tid, 0]
    return qs, r_os, r_mj


def moment_arm_curve(
    osim_path: str | os.PathLike,
    mjcf_path: str | os.PathLike,
    muscle: str,
    coordinate: str,
    *,
    n: int = 101,
    method: str = "fd",
    assembly_accuracy: float | None = 1e-12,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Moment arm of ``muscle`` about the independent ``coordinate`` over the coordinate's range
    (``n`` values, the other coordinates at their defaults): (values, OpenSim, MuJoCo), in
    radians or metres and metres (dimensionless for a translational coordinate). OpenSim steps
    that fail to assemble give NaN. KeyError for an unknown muscle or coordinate."""
    pair = _Pair(osim_path, mjcf_path, assembly_accuracy)
    return _moment_arm_curve(pair, muscle, coordinate, n, method)


def plot_moment_arms(
    osim_path: str | os.PathLike,
    mjcf_path: str | os.PathLike,
    muscle: str,
    coordinate: str,
    ax: Any = None,
    *,
    n: int = 101,
) -> Any:
    """Plot OpenSim's and MuJoCo's moment arm of ``muscle`` about ``coordinate`` (mm; for a
    translational coordinate the dimensionless -dL/dq) against the coordinate (degrees, or mm)
    swept over its range, the other coordinates at their defaults. Draws on the matplotlib
    ``ax`` (a new figure when None) and returns it."""
    import matplotlib.pyplot as plt

    pair = _Pair(osim_path, mjcf_path)
    linear = int(pair.coord(coordinate).getMotionType()) == _TRANSLATIONAL
    qs, r_os, r_mj = _moment_arm_curve(pair, muscle, coordinate, n, "fd")
    x = qs * 1e3 if linear else np.rad2deg(qs)
    scale = 1.0 if linear else 1e3
    if ax is None:
        _, ax = plt.subplots(figsize=(5, 3.5), layout="constrained")
    ax.plot(x, r_os * scale, "-", lw=2.5, color="0.6", label="OpenSim")
    ax.plot(x, r_mj * scale, "--", lw=1.2, color="C0", label="MuJoCo")
    ax.set_xlabel(f"{coordinate} ({'mm' if linear else 'deg'})")
    ax.set_ylabel("-dL/dq" if linear else "moment arm (mm)")
    ax.set_title(f"{muscle} about {coordinate}")
    ax.legend(frameon=False)
    return ax


def moment_arm_sweeps(
    osim_path: str | os.PathLike,
    mjcf_path: str | os.PathLike,
    *,
    n: int = 41,
    assembly_accuracy: float | None = 1e-12,
) -> list[dict[str, Any]]:
    """For every OpenSim path force with a MuJoCo tendon and every independent coordinate it
    spans, sweep the coordinate over its range (``n`` values, the others at their defaults) and
    record OpenSim's ``computeMomentArm``, OpenSim's own ``-dL/dq`` (central differences,
    10 * :data:`FD_STEP`, NaN where a step 10 times larger disagrees) and MuJoCo's ``-dL/dq``
    (metres; dimensionless for a translational coordinate). Returns one JSON-safe dict per pair:
    ``{"muscle", "coordinate", "linear", "q", "opensim", "opensim_dldq", "mujoco", "max_error",
    "max_error_vs_dldq"}`` (the last two: max |MuJoCo - OpenSim| over the sweep, NaN-free values
    only), largest ``max_error`` first. OpenSim values at steps that fail to assemble are NaN."""
    pair = _Pair(osim_path, mjcf_path, assembly_accuracy)
    spans = pair.spanned()
    names = [nm for nm, _, _ in pair.matched]
    out = []
    h = FD_STEP * 10
    for c in pair.indep:
        cname = c.getName()
        users = [i for i, nm in enumerate(names) if cname in spans.get(nm, set())]
        if not users:
            continue
        lo, hi = _sample_bounds(c)
        qs = np.linspace(lo, hi, n)
        r_os = np.full((n, len(users)), np.nan)
        r_fd = np.full((n, len(users)), np.nan)
        r_mj = np.empty((n, len(users)))
        for k, q in enumerate(qs):
            values = {**pair.defaults, cname: float(q)}
            try:
                st = pair.os_state(values)
                values = pair.os_indep_values(st)
                r_os[k] = [pair.matched[i][2].computeMomentArm(st, c) for i in users]
                asm = bool(pair.dependent)
                est = []
                for step in (h, 10 * h):  # two steps: a step of OpenSim's own length inside is no moment arm
                    up = pair.os_lengths(pair.os_state({**values, cname: values[cname] + step}, assemble=asm))
                    dn = pair.os_lengths(pair.os_state({**values, cname: values[cname] - step}, assemble=asm))
                    est.append(-(up - dn)[users] / (2 * step))
                r_fd[k] = np.where(np.abs(est[0] - est[1]) <= DLDQ_CONSISTENCY, est[0], np.nan)
            except Exception:  # assembly failure: OpenSim NaN, MuJoCo at the requested value
                pass
            ma = mujoco_moment_arms(pair.mj_model, pair.mj_data, values, [cname], plan=pair.plan)
            r_mj[k] = ma[pair.tendon_ids[users], 0]
        linear = int(c.getMotionType()) == _TRANSLATIONAL
        for col, i in enumerate(users):
            d = np.abs(r_mj[:, col] - r_os[:, col])
            dd = np.abs(r_mj[:, col] - r_fd[:, col])
            out.append({"muscle": names[i], "coordinate": cname, "linear": linear, "q": qs.tolist(),
                        "opensim": r_os[:, col].tolist(), "opensim_dldq": r_fd[:, col].tolist(),
                        "mujoco": r_mj[:, col].tolist(),
                        "max_error": float(np.nanmax(d)) if np.isfinite(d).any() else float("nan"),
                        "max_error_vs_dldq": float(np.nanmax(dd)) if np.isfinite(dd).any() else float("nan")})
    out.sort(key=lambda r: -(r["max_error"] if np.isfinite(r["max_error"]) else np.inf))
    return out


def plot_moment_arm_sweeps(sweeps: Sequence[Mapping[str, Any]], pdf_path: str | os.PathLike, *,
                           per_page: int = 12, title: str = "") -> list[dict[str, Any]]:
    """Draw, for each path in ``sweeps`` (from :func:`moment_arm_sweeps`), its pair with the
    largest error against ``computeMomentArm``: OpenSim's ``computeMomentArm`` (grey), OpenSim's
    ``-dL/dq`` (dotted, where it differs) and MuJoCo's ``-dL/dq`` (blue dashed), mm against the
    coordinate in degrees (mm for a translational one), ``per_page`` panels a page, worst
    first, into a multi-page PDF. Returns the pairs drawn."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    worst: dict[str, Mapping[str, Any]] = {}
    for r in sweeps:
        e = r["max_error"] if np.isfinite(r["max_error"]) else np.inf
        w = worst.get(r["muscle"])
        if w is None or e > (w["max_error"] if np.isfinite(w["max_error"]) else np.inf):
            worst[r["muscle"]] = r
    rows = sorted(worst.values(), key=lambda r: -(r["max_error"] if np.isfinite(r["max_error"]) else np.inf))
    cols = 4
    with PdfPages(os.fspath(pdf_path)) as pdf:
        for start in range(0, max(len(rows), 1), per_page):
            chunk = rows[start:start + per_page]
            nrow = max(1, math.ceil(len(chunk) / cols))
            fig, axes = plt.subplots(nrow, cols, figsize=(11, 2.3 * nrow + 0.6), squeeze=False)
            for ax in axes.ravel()[len(chunk):]:
                ax.axis("off")
            for ax, r in zip(axes.ravel(), chunk, strict=False):
                q = np.asarray(r["q"])
                x = q * 1e3 if r["linear"] else np.rad2deg(q)
                k = 1.0 if r["linear"] else 1e3
                os_ma, fd, mj = (np.asarray(r[key], dtype=float) * k for key in ("opensim", "opensim_dldq", "mujoco"))
                ax.plot(x, os_ma, "-", lw=2.2, color="0.65", label="OpenSim computeMomentArm")
                if np.nanmax(np.abs(fd - os_ma), initial=0.0) > 0.1:
                    ax.plot(x, fd, ":", lw=1.2, color="k", label="OpenSim -dL/dq")
                ax.plot(x, mj, "--", lw=1.1, color="C0", label="MuJoCo -dL/dq")
                ax.set_title(f"{r['muscle']} / {r['coordinate']}: max {r['max_error'] * k:.2g}"
                             f"{'' if r['linear'] else ' mm'}", fontsize=8)
                ax.tick_params(labelsize=7)
                ax.set_xlabel("mm" if r["linear"] else "deg", fontsize=7)
            axes.ravel()[0].legend(fontsize=6, frameon=False)
            fig.suptitle(title or "moment arms (mm): each path's worst coordinate, the others at their defaults",
                         fontsize=9)
            fig.tight_layout()
            pdf.savefig(fig)
            plt.close(fig)
    return list(rows)
