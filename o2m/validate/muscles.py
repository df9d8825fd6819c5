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

import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import mujoco
import numpy as np

from o2m.mj.tendons import FD_STEP, mujoco_moment_arms
from o2m.osim.pair import ModelPair, is_actuator
from o2m.osim.runtime import sample_bounds
from o2m.osim.spikes import DLDQ_CONSISTENCY, SPIKE_TOL, band_suspects, opensim_failures
from o2m.validate.kinematics import jsonable, text_table
from o2m.validate.sweeps import plot_moment_arms

__all__ = [
    "compare_muscles",
    "format_muscle_table",
    "MomentArmError",
    "MuscleError",
    "MuscleReport",
]

#: A moment arm below this (metres) in both models over all poses means "does not span".
MA_ZERO = 1e-7
#: Default tolerances of :meth:`MuscleReport.ok`.
LEN_PCT = 1.0
MA_MEDIAN_MM = 0.5
MA_P95_MM = 2.0
MA_MAX_MM = 5.0


def _nan_rms(x: np.ndarray) -> float:
    """RMS of the finite values of ``x`` (NaN when there are none)."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


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
    #: Moment-arm poses left out where OpenSim's computeMomentArm is NaN (a path of length 0
    #: there, as a muscle whose two points meet at the default pose).
    opensim_nan: int = 0


@dataclass
class MuscleError:
    """Errors of one muscle-tendon unit over all poses.

    ``max_len``/``rms_len`` (m) of the length error, ``max_len_pct``/``rms_len_pct`` of it in
    percent of OpenSim's length; ``length_range`` is OpenSim's (min, max) length (m);
    ``moment_arms`` maps each compared coordinate to its :class:`MomentArmError`; ``worst_pose``
    the independent coordinate values (rad, m) of the pose of ``max_len_pct``.
    """

    kind: str
    max_len: float
    rms_len: float
    max_len_pct: float
    rms_len_pct: float
    length_range: tuple[float, float]
    moment_arms: dict[str, MomentArmError] = field(default_factory=dict)
    worst_pose: dict[str, float] | None = None


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
    #: (muscle, coordinate, pose) moment-arm samples left out where OpenSim's computeMomentArm is
    #: NaN (a pair with none left is not compared).
    ma_opensim_nan: int = 0
    #: (muscle, pose) samples left out because OpenSim's own length spikes there
    #: (:func:`~o2m.osim.spikes.opensim_spikes`): each {"muscle", "pose", "coordinate", "length",
    #: "neighbours"}; or because its path runs past a path point to a wrap and back
    #: (:func:`~o2m.osim.spikes.opensim_detours`): {"muscle", "pose", "test": "detour", "wrap",
    #: "segment", "beyond", "length"}; or loops round a wrap, its runs crossing
    #: (:func:`~o2m.osim.spikes.opensim_loops`): {..., "test": "loop", "wrap", "kind", "length"}; or
    #: winds over a full turn round one (:func:`~o2m.osim.spikes.opensim_windings`): {..., "test":
    #: "winding", "wrap", "kind", "turn", "length"}; or its length is not that of the path it draws
    #: (:func:`~o2m.osim.spikes.opensim_inconsistencies`): {..., "test": "inconsistent", "length", "drawn"}.
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
        return jsonable(d)

    def summary(self) -> str:
        """Readable report: one row per muscle (length errors in mm and %, worst moment arm),
        the aggregates, the worst pairs and the verdict."""
        lines = [
            f"{self.name}: {len(self.muscles)} muscles, {self.n_poses} poses ({self.ma_poses} for moment arms), "
            f"{len(self.coordinates)} coordinates"
            + (f", {self.skipped_poses} poses skipped (assembly failed)" if self.skipped_poses else "")
            + (f", {len(self.opensim_spikes)} (muscle, pose) samples left out where OpenSim's own length spikes "
               "or detours, loops, winds or is not its drawn path's" if self.opensim_spikes else "")
            + (f", {self.ma_opensim_nan} moment-arm samples left out where OpenSim's computeMomentArm is NaN"
               if self.ma_opensim_nan else ""),
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


def _actuator_issues(pair: ModelPair) -> dict[str, str]:
    m = pair.mj_model
    out = {}
    for name, _, obj in pair.matched:
        if not is_actuator(obj):
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

    pair = ModelPair(osim_path, mjcf_path, assembly_accuracy)
    n_ma = min(n_poses, 50) if ma_poses is None else max(0, min(int(ma_poses), n_poses))
    names = [n for n, _, _ in pair.matched]
    nm, nc = len(names), len(pair.indep_names)
    tids = pair.tendon_ids

    rng = np.random.default_rng(seed)
    bounds = np.array([sample_bounds(c) for c in pair.indep], dtype=float).reshape(-1, 2)
    samples = rng.uniform(bounds[:, 0], bounds[:, 1], size=(max(n_poses - 1, 0), nc))

    err_sq = np.zeros(nm)
    pct_sq = np.zeros(nm)
    max_err = np.zeros(nm)
    max_pct = np.zeros(nm)
    len_min = np.full(nm, np.inf)
    len_max = np.full(nm, -np.inf)
    worst: dict[str, Any] | None = None
    worst_poses: dict[int, dict[str, float]] = {}
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
            for i, info in opensim_failures(pair, values, suspects, l_os, band_suspects(l_mj, l_os)).items():
                valid[i] = False
                spikes.append({"muscle": names[i], "pose": k, **info})
        err = np.where(valid, err, 0.0)
        n_valid += valid
        pct = 100.0 * err / np.maximum(np.abs(l_os), 1e-12)
        err_sq += err**2
        pct_sq += pct**2
        np.maximum(max_err, err, out=max_err)
        for i in np.flatnonzero(pct > max_pct):
            worst_poses[int(i)] = values
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
    ma_nan = 0
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
            finite = np.isfinite(r_os)
            n_nan = int(np.sum(~finite))
            ma_nan += n_nan
            use, r_os = [k for k, ok in zip(use, finite, strict=True) if ok], r_os[finite]
            if not use:
                continue
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
                opensim_nan=n_nan,
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
            worst_pose=worst_poses.get(i),
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
        ma_opensim_nan=ma_nan,
        opensim_spikes=spikes,
    )


# --------------------------------------------------------------------------------------------
# Sweeps
# --------------------------------------------------------------------------------------------


