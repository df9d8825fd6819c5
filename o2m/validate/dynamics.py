"""Dynamic fidelity: the same muscle excitations in OpenSim and in the converted model, compared over time.

:func:`compare_dynamics` drives both simulators with the same excitations and compares every
independent coordinate over time:

* the excitations are random sets made as for the paper (:func:`o2m.activations.generate_activations`,
  seeded), or the muscle columns of a given controls file (``.sto``/``.mot``, e.g. CMC's
  ``_controls.sto``), whose coordinate columns, if any, set the initial pose;
* OpenSim runs every set in its own process with a wall-clock limit
  (:func:`o2m.osim.simulate.run_many`): a run that fails, goes NaN or times out is reported with
  its reason and compared only up to the time it reached;
* MuJoCo starts from OpenSim's first recorded sample (coordinates, speeds and the equilibrated
  muscles' activations) and gets the excitations on the actuators of the same names
  (:func:`o2m.mj.simulate.controls_from_excitations`); OpenSim muscles without a MuJoCo actuator
  are listed in the report.

The result, a :class:`DynamicsReport`, holds both trajectories, ``summary()`` prints per
coordinate the mean absolute, maximum and final error (rad or m) and ``plot()`` draws OpenSim
against MuJoCo per coordinate.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from o2m.activations import generate_activations
from o2m.errors import ValidationError
from o2m.mj.posing import load_mjcf
from o2m.mj.schutte_plugin import with_schutte_starts
from o2m.mj.simulate import controls_from_excitations, initial_state, rollout
from o2m.osim.simulate import IntegratorSettings, ModelOutline, OpenSimRun, model_outline, run_many
from o2m.osim.storage import read_sto
from o2m.validate.jumps import trajectory_jumps

__all__ = ["DynamicsReport", "Excitations", "compare_dynamics", "motion_excitations", "random_excitations"]


@dataclass(frozen=True)
class Excitations:
    """What drives both simulators.

    Attributes:
        times: sample times, shape (T,), seconds, on MuJoCo's time step.
        values: excitations, shape (n_sets, T, len(muscles)), in [0, 1].
        muscles: the muscle each column drives.
        labels: one label per set (``"seed 0 set 1"``, or the motion file's name).
        initial_coordinates: coordinate values (rad or m) to start from, by name; empty for the
            model's default pose.
    """

    times: np.ndarray
    values: np.ndarray
    muscles: tuple[str, ...]
    labels: tuple[str, ...]
    initial_coordinates: dict[str, float] = field(default_factory=dict)


def random_excitations(muscles: Sequence[str], timestep: float, *, n_sets: int = 3, duration: float = 1.0,
                       seed: int = 0) -> Excitations:
    """``n_sets`` random sets of ``duration`` seconds sampled every ``timestep`` seconds (see
    :mod:`o2m.activations`; the same seed gives the same sets)."""
    sets = generate_activations(list(muscles), n_sets, seed=seed, duration=duration, rate=1.0 / timestep)
    return Excitations(sets.times, sets.values, tuple(muscles), tuple(f"seed {seed} set {i}" for i in range(n_sets)))


def motion_excitations(path: str | os.PathLike[str], outline: ModelOutline, timestep: float, *,
                       duration: float | None = None) -> Excitations:
    """Excitations from a controls/motion file's columns named after muscles (``BIClong`` or
    ``/forceset/BIClong``), linearly resampled every ``timestep`` seconds from its first time
    for ``duration`` seconds (default: all of it); columns named after coordinates give the
    initial pose (degrees converted when the file says ``inDegrees=yes``).

    Raises :class:`ValidationError` when no column names a muscle or a coordinate of the model.
    """
    st = read_sto(path)
    short = [c.rsplit("/", 1)[-1] for c in st.columns]
    muscle_cols = [i for i, c in enumerate(short) if c in outline.muscles]
    coord_cols = [i for i, c in enumerate(short) if c in outline.coordinates]
    if not muscle_cols and not coord_cols:
        raise ValidationError(f"{path}: no column names a muscle or coordinate of the model "
                              f"(columns: {', '.join(st.columns[:5])}...)")
    span = float(st.times[-1] - st.times[0]) if duration is None else min(duration, float(st.times[-1] - st.times[0]))
    times = st.times[0] + np.arange(int(round(span / timestep)) + 1) * timestep
    values = np.stack([np.interp(times, st.times, st.data[:, i]) for i in muscle_cols], axis=-1) if muscle_cols \
        else np.zeros((len(times), 0))
    first = {short[i]: float(st.data[0, i]) for i in coord_cols}
    if st.in_degrees:
        first = {k: np.deg2rad(v) if k in outline.rotational else v for k, v in first.items()}
    return Excitations(times, np.clip(values, 0.0, 1.0)[None], tuple(short[i] for i in muscle_cols),
                       (Path(path).name,), first)


@dataclass
class DynamicsReport:
    """OpenSim and MuJoCo trajectories of the same excitations, and their differences.

    Attributes:
        name: the OpenSim model's file stem.
        times: shape (T,), seconds.
        coordinates: the compared coordinates (independent, unlocked, in both models).
        rotational: per compared coordinate, True for rad (hinge), False for m (slide).
        opensim: OpenSim's coordinates, shape (n_sets, T, C), NaN after a failure.
        mujoco: MuJoCo's coordinates, shape (n_sets, T, C), NaN if MuJoCo diverged.
        labels: one label per set.
        status, reasons: per set, OpenSim's run status (``ok``, ``failed``, ``nan``, ``timeout``)
            and its reason.
        mujoco_diverged: per set, MuJoCo reset the simulation (the trajectory is meaningless).
        unmatched_muscles: OpenSim muscles with no MuJoCo actuator of the same name (not driven in MuJoCo).
        opensim_seconds: wall-clock seconds of each OpenSim run.
        ranges: each compared coordinate's OpenSim range (min, max), shape (C, 2), rad or m; a
            model without limit forces can leave it, and the converted model is fitted inside it.
        path_flips: MuJoCo tendon lengths that jump during the runs where OpenSim's path does not
            (a path round the wrong side of a wrap), as :func:`o2m.validate.jumps.trajectory_jumps`
            lists them (``trajectory`` is the set's index).
        path_jumps_at_opensim_failures: the same jumps where OpenSim's own path winds or loops
            round a wrap (no reference there), with that evidence.
        driven_muscles: the muscles excited in both simulators (none: the runs are passive).
    """

    name: str
    times: np.ndarray
    coordinates: list[str]
    rotational: np.ndarray
    opensim: np.ndarray
    mujoco: np.ndarray
    labels: list[str]
    status: list[str]
    reasons: list[str]
    mujoco_diverged: np.ndarray
    unmatched_muscles: list[str] = field(default_factory=list)
    opensim_seconds: list[float] = field(default_factory=list)
    ranges: np.ndarray | None = None
    path_flips: list[dict] = field(default_factory=list)
    path_jumps_at_opensim_failures: list[dict] = field(default_factory=list)
    driven_muscles: list[str] | None = None

    @property
    def error(self) -> np.ndarray:
        """|MuJoCo - OpenSim|, shape (n_sets, T, C), rad or m; NaN where either is missing."""
        return np.abs(self.mujoco - self.opensim)

    def compared(self) -> np.ndarray:
        """Per set, whether any sample can be compared, shape (n_sets,)."""
        return np.isfinite(self.error).all(axis=2).any(axis=1)

    def final_error(self) -> np.ndarray:
        """Error at each set's last comparable sample, shape (n_sets, C); NaN for sets with none."""
        err = self.error
        out = np.full(err.shape[::2], np.nan)
        for s in np.flatnonzero(self.compared()):
            last = np.flatnonzero(np.isfinite(err[s]).all(axis=1))[-1]
            out[s] = err[s, last]
        return out

    def mean_error(self) -> np.ndarray:
        """Mean absolute error per coordinate over sets and comparable samples, shape (C,)."""
        return _nan_reduce(np.nanmean, self.error.reshape(-1, len(self.coordinates)))

    def max_error(self) -> np.ndarray:
        """Largest absolute error per coordinate, shape (C,)."""
        return _nan_reduce(np.nanmax, self.error.reshape(-1, len(self.coordinates)))

    def outside_range(self) -> np.ndarray:
        """Fraction of OpenSim's samples outside the coordinate's range, per coordinate, shape (C,)."""
        if self.ranges is None:
            return np.full(len(self.coordinates), np.nan)
        q = self.opensim.reshape(-1, len(self.coordinates))
        reached = np.isfinite(q).all(axis=1)
        if not reached.any():
            return np.full(len(self.coordinates), np.nan)
        q = q[reached]
        return np.mean((q < self.ranges[:, 0]) | (q > self.ranges[:, 1]), axis=0)

    def mean_rotational_error(self) -> float:
        """Mean absolute error over the rotational coordinates, rad (NaN when nothing compares)."""
        rot = self.error[..., self.rotational]
        return float(np.nanmean(rot)) if np.isfinite(rot).any() else float("nan")

    def summary(self) -> str:
        """Readable report: one line per set (OpenSim's status), one per coordinate (errors)."""
        n = len(self.labels)
        lines = [f"{self.name}: {n} excitation set(s) of {self.times[-1] - self.times[0]:.3g} s, "
                 f"{len(self.coordinates)} compared coordinates, {int(self.compared().sum())} of {n} sets compared"]
        for s in range(n):
            reached = np.flatnonzero(np.isfinite(self.opensim[s]).all(axis=1))
            t_end = self.times[reached[-1]] if len(reached) else float("nan")
            note = " (MuJoCo diverged)" if self.mujoco_diverged[s] else ""
            why = f": {self.reasons[s]}" if self.reasons[s] else ""
            secs = f", {self.opensim_seconds[s]:.1f} s wall" if s < len(self.opensim_seconds) else ""
            rot = self.error[s][:, self.rotational]
            err = f", mean abs {np.nanmean(rot):.4f} rad" if np.isfinite(rot).any() else ""
            lines.append(f"  {self.labels[s]}: OpenSim {self.status[s]} to t={t_end:.3g} s{secs}{err}{why}{note}")
        if self.driven_muscles is not None and not self.driven_muscles:
            lines.append("  no muscle is driven: every run is passive (gravity, springs, contact), other actuators "
                         "at zero control")
        if self.unmatched_muscles:
            lines.append(f"  not driven in MuJoCo (no actuator of that name): {', '.join(self.unmatched_muscles)}")
        w = max([len("coordinate")] + [len(c) for c in self.coordinates])
        lines.append(f"  {'coordinate':<{w}}  unit  {'mean abs':>9}  {'max':>9}  {'final':>9}  OpenSim outside range")
        mean, peak, final = self.mean_error(), self.max_error(), _nan_reduce(np.nanmean, self.final_error())
        outside = self.outside_range()
        for j, c in enumerate(self.coordinates):
            unit = "rad" if self.rotational[j] else "m"
            lines.append(f"  {c:<{w}}  {unit:<4}  {mean[j]:9.4f}  {peak[j]:9.4f}  {final[j]:9.4f}  "
                         f"{100 * outside[j]:5.1f}% of samples")
        if self.rotational.any():
            lines.append(f"  mean abs error over rotational coordinates: {self.mean_rotational_error():.4f} rad")
        else:  # a model that only translates (its mean over rotations would be NaN)
            moved = mean[np.isfinite(mean)]
            lines.append(f"  mean abs error over translational coordinates: "
                         f"{float(moved.mean()) if moved.size else float('nan'):.4f} m")
        lines.append(f"  MuJoCo paths jumping where OpenSim's do not: {_flip_summary(self.path_flips)}")
        if self.path_jumps_at_opensim_failures:
            lines.append("  ... and where OpenSim's own path winds or loops round a wrap (left out): "
                         + _flip_summary(self.path_jumps_at_opensim_failures))
        return "\n".join(lines)

    def plot(self, path: str | os.PathLike[str], *, max_sets: int = 5, dpi: int = 80) -> Path:
        """OpenSim (solid) against MuJoCo (dashed) per coordinate, one colour per set, the
        coordinate's range dotted, as an image (a PNG gets a 64-colour palette)."""
        import matplotlib
        from matplotlib.figure import Figure  # not pyplot: no backend or global figure state

        n = len(self.coordinates)
        cols = max(1, min(n, 3 if n <= 6 else 4))
        rows = max(1, -(-n // cols))
        fig = Figure(figsize=(3.2 * cols, 2.3 * rows))
        axes = fig.subplots(rows, cols, squeeze=False, sharex=True)
        colours = matplotlib.rcParams["axes.prop_cycle"].by_key()["color"]
        for j, ax in enumerate(axes.flat):
            if j >= n:
                ax.axis("off")
                continue
            for s in range(min(max_sets, len(self.labels))):
                colour = colours[s % len(colours)]
                ax.plot(self.times, self.opensim[s, :, j], "-", color=colour, lw=1.2)
                ax.plot(self.times, self.mujoco[s, :, j], "--", color=colour, lw=1.2)
            low, high = ax.get_ylim()
            for bound in self.ranges[j] if self.ranges is not None else ():
                if low < bound < high:
                    ax.axhline(bound, color="0.5", lw=0.8, ls=":")
            unit = "rad" if self.rotational[j] else "m"
            ax.set_title(f"{self.coordinates[j]} ({unit})", fontsize=8)
            ax.tick_params(labelsize=7)
        for ax in axes[-1]:
            ax.set_xlabel("time (s)", fontsize=7)
        fig.suptitle(f"{self.name}: OpenSim (solid) vs MuJoCo (dashed), one colour per set; dotted: the coordinate's "
                     "range", fontsize=9)
        fig.tight_layout()
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.suffix.lower() == ".png":  # a 64-colour palette: a fifth of the size, for docs
            from io import BytesIO

            from PIL import Image

            buffer = BytesIO()
            fig.savefig(buffer, dpi=dpi, format="png")
            Image.open(buffer).convert("RGB").quantize(64).save(path, optimize=True)
        else:
            fig.savefig(path, dpi=dpi)
        return path


def _flip_summary(flips: Sequence[dict]) -> str:
    """'none', or per tendon the sets it jumps in and its largest jump, largest first."""
    if not flips:
        return "none"
    worst: dict[str, list[float]] = {}
    for f in flips:
        worst.setdefault(f["tendon"], []).append(f["mujoco"])
    order = sorted(worst, key=lambda t: -max(worst[t]))
    return ", ".join(f"{t} ({len(worst[t])} set(s), up to {1e3 * max(worst[t]):.1f} mm)" for t in order)


def _nan_reduce(fn, values: np.ndarray) -> np.ndarray:
    """``fn(values, axis=0)`` with all-NaN columns giving NaN quietly."""
    ok = np.isfinite(values).any(axis=0)
    out = np.full(values.shape[1], np.nan)
    if ok.any():
        out[ok] = fn(values[:, ok], axis=0)
    return out


def independent_joints(model: mujoco.MjModel, names: Sequence[str]) -> list[str]:
    """The names in ``names`` that are hinge/slide joints of ``model`` no active joint equality drives."""
    driven = {int(model.eq_obj1id[i]) for i in range(model.neq)
              if int(model.eq_type[i]) == int(mujoco.mjtEq.mjEQ_JOINT) and model.eq_active0[i]}
    kinds = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    out = []
    for name in names:
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if j >= 0 and j not in driven and int(model.jnt_type[j]) in kinds:
            out.append(name)
    return out


def _mujoco_start(model: mujoco.MjModel, run: OpenSimRun, outline: ModelOutline, t0: float,
                  given: Mapping[str, float]) -> np.ndarray:
    """MuJoCo's initial state: OpenSim's first sample when it has one, else the pose OpenSim was
    given (coordinate values among ``given``'s plain coordinate names, else the defaults)."""
    if np.isfinite(run.coordinates[:1]).all() and run.coordinate_names:
        return initial_state(model, dict(zip(run.coordinate_names, run.coordinates[0], strict=True)),
                             speeds=dict(zip(run.coordinate_names, run.speeds[0], strict=True)),
                             activations=dict(zip(run.muscle_names, run.activations[0], strict=True)), time=t0)
    return initial_state(model, {**outline.defaults, **{k: v for k, v in given.items() if k in outline.defaults}},
                         time=float(t0))


def compare_dynamics(osim_path: str | os.PathLike[str], mjcf_path: str | os.PathLike[str], *, n_sets: int = 3,
                     duration: float = 1.0, seed: int = 0, motion: str | os.PathLike[str] | None = None,
                     initial_state: Mapping[str, float] | None = None, timeout: float = 300.0,
                     settings: IntegratorSettings | None = None, max_workers: int | None = None, executor=None,
                     progress: bool = True) -> DynamicsReport:
    """Drive OpenSim and the converted model with the same excitations and compare (module docstring).

    Args:
        n_sets, duration, seed: the random excitation sets (ignored with ``motion``), seconds.
        motion: a controls/motion file to use instead (see :func:`motion_excitations`); its
            length is cut to ``duration`` seconds.
        initial_state: OpenSim state-variable values to start from, by name (e.g.
            :func:`o2m.osim.simulate.read_initial_state` of MoBL-ARMS' ``initial_states.sto``);
            the motion's initial pose, if any, goes on top. Default: the model's default pose,
            muscles in equilibrium.
        timeout: wall-clock limit per OpenSim run, seconds.
        settings: OpenSim's integrator settings (default: :class:`IntegratorSettings`'s).
        max_workers, executor: where the OpenSim runs go (see :func:`o2m.osim.simulate.run_many`).
    Raises:
        ValidationError: a model does not load, or the models share no coordinate.
    """
    model = load_mjcf(mjcf_path)
    outline = model_outline(osim_path)
    dt = float(model.opt.timestep)
    exc = (motion_excitations(motion, outline, dt, duration=duration) if motion is not None
           else random_excitations(outline.muscles, dt, n_sets=n_sets, duration=duration, seed=seed))
    names = independent_joints(model, [c for c in outline.coordinates if c not in outline.locked])
    if not names:
        raise ValidationError(f"{mjcf_path}: no MuJoCo joint is named after an unlocked OpenSim coordinate of "
                              f"{osim_path}")
    actuators = {model.actuator(i).name for i in range(model.nu)}
    driven = [m for m in exc.muscles if m in actuators]
    start = {**(initial_state or {}), **exc.initial_coordinates}
    runs = run_many(osim_path, exc.times, exc.values, list(exc.muscles), initial_state=start,
                    settings=settings or IntegratorSettings(), timeout=timeout, executor=executor,
                    max_workers=max_workers, progress=progress)
    keep = [exc.muscles.index(m) for m in driven]
    controls = controls_from_excitations(model, driven, exc.values[:, :, keep])
    starts = np.stack([_mujoco_start(model, run, outline, exc.times[0], start) for run in runs])
    # OpenSim's own muscles (convert --opensim-muscles) start at OpenSim's activation and fibre
    starts = with_schutte_starts(model, starts, [_muscle_starts(run) for run in runs])
    traj = rollout(model, starts, controls, joint_names=names, nthread=max_workers)
    mj = traj.coordinates.copy()
    mj[traj.diverged] = np.nan
    ref = np.stack([_opensim_columns(run, names) for run in runs])
    ran = np.flatnonzero(~traj.diverged)
    found = trajectory_jumps(osim_path, mjcf_path, traj.qpos[ran]) if len(ran) else {}
    flips, at_failures = ([{**f, "trajectory": int(ran[f["trajectory"]])} for f in found.get(key, [])]
                          for key in ("flips", "at_opensim_failures"))
    rotational = np.array([int(model.jnt_type[model.joint(n).id]) == int(mujoco.mjtJoint.mjJNT_HINGE)
                           for n in names])
    return DynamicsReport(Path(osim_path).stem, exc.times, names, rotational, ref, mj, list(exc.labels),
                          [r.status for r in runs], [r.reason for r in runs], traj.diverged.copy(),
                          [m for m in outline.muscles if m not in actuators], [r.wall_time for r in runs],
                          np.array([outline.ranges[n] for n in names], float), flips, at_failures, driven)


def _muscle_starts(run: OpenSimRun) -> dict[str, tuple[float, float]]:
    """Each muscle's (activation, fibre length m) at the run's first sample, where it has both."""
    if not len(run.initial_fibre_lengths) or not run.muscle_names:
        return {}
    return {m: (float(a), float(f)) for m, a, f in zip(run.muscle_names, run.activations[0],
                                                       run.initial_fibre_lengths, strict=True)
            if np.isfinite(a) and np.isfinite(f) and f > 0}


def _opensim_columns(run: OpenSimRun, names: Sequence[str]) -> np.ndarray:
    """The run's values of ``names``, shape (T, len(names)); all NaN when the run recorded nothing."""
    if not run.coordinate_names:
        return np.full((len(run.times), len(names)), np.nan)
    return run.coordinates[:, [run.coordinate_names.index(n) for n in names]]
