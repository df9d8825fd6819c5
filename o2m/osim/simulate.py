"""Forward simulation in OpenSim 4.6 with prescribed muscle excitations.

OpenSim is the reference, but it can fail (integrator errors), go NaN without an exception, or
stall for many minutes on a fraction of a second. So every run gets its own process and a
wall-clock limit (:func:`run_isolated`), and :func:`run_many` spreads runs over any
:class:`concurrent.futures.Executor`: a local process pool by default, or e.g. a Dask
``distributed.Client(...).get_executor()`` for a cluster (workers need the ``.osim`` file at the
same path). A failed, NaN or timed-out run comes back as an :class:`OpenSimRun` whose
``status`` and ``reason`` say what happened; it is never dropped.

The simulation (:func:`simulate`) adds a PrescribedController with one piecewise-linear function
per muscle (zero for muscles not given), sets the initial state (coordinates, speeds, muscle
activations and fibre lengths, by OpenSim state-variable name, e.g. from MoBL-ARMS'
``initial_states.sto``), and integrates with OpenSim's Manager up to each sample time,
recording every coordinate's value (rad or m) and speed and every muscle's activation and
tendon force (N), the force the muscle pulls its path with (what :mod:`o2m.force_fit` fits
MuJoCo's muscles to).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from o2m.osim import runtime
from o2m.osim.names import opensim_coordinate_names

__all__ = ["IntegratorSettings", "ModelOutline", "OpenSimRun", "model_outline", "read_initial_state", "run_isolated",
           "run_many", "simulate", "tendon_force"]


@dataclass(frozen=True)
class IntegratorSettings:
    """OpenSim Manager settings; the defaults are MoBL-ARMS' ``setup_fd.xml``."""

    method: str = "RungeKuttaMerson"
    accuracy: float = 1e-5
    min_step: float = 1e-5
    max_step: float = 1.0


@dataclass
class OpenSimRun:
    """One OpenSim forward simulation and how it ended.

    Attributes:
        status: ``"ok"``, ``"failed"`` (OpenSim raised), ``"nan"`` (non-finite state) or
            ``"timeout"`` (killed after the wall-clock limit).
        reason: the exception text or what was non-finite; empty when ok.
        times: sample times, shape (T,), seconds.
        coordinates: coordinate values, shape (T, n_coordinates), rad or m; NaN after a failure.
        speeds: coordinate speeds, shape (T, n_coordinates), rad/s or m/s; NaN after a failure.
        activations: muscle activations, shape (T, n_muscles); NaN after a failure.
        tendon_forces: muscle tendon forces, shape (T, n_muscles), N (positive when pulling);
            NaN after a failure (and in runs stored before o2m recorded them).
        coordinate_names, muscle_names: column labels.
        initial_fibre_lengths: each muscle's fibre length at the first sample, shape
            (n_muscles,), m (empty in runs stored before o2m recorded them).
        t_reached: last time reached, seconds.
        wall_time: wall-clock seconds the run took (loading the model included).
        integration_time: wall-clock seconds spent integrating (from the Manager's start).
    """

    status: str
    reason: str
    times: np.ndarray
    coordinates: np.ndarray
    speeds: np.ndarray
    activations: np.ndarray
    tendon_forces: np.ndarray
    coordinate_names: list[str] = field(default_factory=list)
    muscle_names: list[str] = field(default_factory=list)
    t_reached: float = 0.0
    wall_time: float = 0.0
    integration_time: float = 0.0
    initial_fibre_lengths: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def to_npz(self, path: str | os.PathLike[str]) -> None:
        np.savez(path, status=self.status, reason=self.reason, times=self.times, coordinates=self.coordinates,
                 speeds=self.speeds, activations=self.activations, tendon_forces=self.tendon_forces,
                 coordinate_names=np.array(self.coordinate_names),
                 muscle_names=np.array(self.muscle_names), t_reached=self.t_reached, wall_time=self.wall_time,
                 integration_time=self.integration_time, initial_fibre_lengths=self.initial_fibre_lengths)

    @classmethod
    def from_npz(cls, path: str | os.PathLike[str]) -> OpenSimRun:
        with np.load(path) as z:
            forces = z["tendon_forces"] if "tendon_forces" in z.files else np.full(z["activations"].shape, np.nan)
            return cls(str(z["status"]), str(z["reason"]), z["times"], z["coordinates"], z["speeds"],
                       z["activations"], forces, [str(s) for s in z["coordinate_names"]],
                       [str(s) for s in z["muscle_names"]], float(z["t_reached"]), float(z["wall_time"]),
                       float(z["integration_time"]) if "integration_time" in z.files else float("nan"),
                       z["initial_fibre_lengths"] if "initial_fibre_lengths" in z.files else np.zeros(0))

    @classmethod
    def empty(cls, status: str, reason: str, times: np.ndarray, n_coordinates: int = 0, n_muscles: int = 0,
              wall_time: float = 0.0) -> OpenSimRun:
        nan = np.full((len(times), n_coordinates), np.nan)
        per_muscle = np.full((len(times), n_muscles), np.nan)
        return cls(status, reason, np.asarray(times), nan, nan.copy(), per_muscle, per_muscle.copy(),
                   wall_time=wall_time)


@dataclass(frozen=True)
class ModelOutline:
    """What a forward simulation of a model needs to know before running it.

    Attributes:
        muscles: muscle names, in the model's order.
        coordinates: coordinate names, in the model's order.
        defaults: each coordinate's default value, rad or m.
        locked: names of the coordinates locked by default (they do not move).
        rotational: names of the rotational coordinates (the others are translational, m).
        ranges: each coordinate's range (min, max), rad or m.
    """

    muscles: tuple[str, ...]
    coordinates: tuple[str, ...]
    defaults: dict[str, float]
    locked: frozenset[str]
    rotational: frozenset[str]
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)


def model_outline(osim_path: str | os.PathLike[str]) -> ModelOutline:
    """Muscles and coordinates of a model, read by OpenSim in this process (a few seconds).

    Raises :class:`o2m.errors.ValidationError` with OpenSim's message if the model does not load.
    """
    from o2m.errors import ValidationError

    osim = runtime.opensim()
    try:
        model = osim.Model(str(osim_path))
        model.initSystem()
    except Exception as exc:  # OpenSim raises RuntimeError subclasses with its own message
        raise ValidationError(f"{osim_path}: OpenSim could not load the model: {str(exc).strip()[:500]}") from exc
    muscles = model.getMuscles()
    coords = model.getCoordinateSet()
    objs = [coords.get(i) for i in range(coords.getSize())]
    rotational = osim.Coordinate.Rotational if hasattr(osim.Coordinate, "Rotational") else 1
    mj_names = opensim_coordinate_names(model)
    names = [mj_names[c.getAbsolutePathString()] for c in objs]  # MuJoCo joint names
    return ModelOutline(tuple(muscles.get(i).getName() for i in range(muscles.getSize())),
                        tuple(names), {n: float(c.getDefaultValue()) for n, c in zip(names, objs, strict=True)},
                        frozenset(n for n, c in zip(names, objs, strict=True) if c.getDefaultLocked()),
                        frozenset(n for n, c in zip(names, objs, strict=True) if c.getMotionType() == rotational),
                        {n: (float(c.getRangeMin()), float(c.getRangeMax())) for n, c in zip(names, objs, strict=True)})


def read_initial_state(path: str | os.PathLike[str]) -> dict[str, float]:
    """The first row of a states ``.sto`` file as ``{column: value}`` (e.g. ``initial_states.sto``).

    Columns are OpenSim 3 state names (``r_z``, ``r_z_u``, ``DELT1.activation``,
    ``DELT1.fiber_length``) or OpenSim 4 paths (``/jointset/j/r_z/value``); :func:`simulate`
    accepts both. Rotations in degrees (``inDegrees=yes``) are not converted: pass radians.
    """
    from o2m.osim.storage import read_sto

    st = read_sto(path)
    if st.in_degrees:
        raise ValueError(f"{path}: inDegrees=yes; o2m expects initial states in radians")
    return st.first_row()


def _state_variable_path(names: list[str], label: str) -> str | None:
    """The OpenSim 4 state-variable path a 3.x or 4.x state label stands for, or None."""
    if label.startswith("/"):
        return label if label in names else None
    if "." in label:  # muscle.state
        owner, var = label.split(".", 1)
        suffix = f"/{owner}/{var}"
    elif label.endswith("_u"):
        suffix = f"/{label[:-2]}/speed"
    else:
        suffix = f"/{label}/value"
    hits = [n for n in names if n.endswith(suffix)]
    return hits[0] if len(hits) == 1 else None


def simulate(osim_path: str | os.PathLike[str], times: np.ndarray, excitations: np.ndarray,
             muscles: Sequence[str], *, initial_state: Mapping[str, float] | None = None,
             settings: IntegratorSettings = IntegratorSettings(), wall_limit: float | None = None) -> OpenSimRun:
    """Run one forward simulation in this process (see the module docstring).

    Args:
        osim_path: the model.
        times: sample times, shape (T,), seconds, starting at the initial time.
        excitations: shape (T, len(muscles)), in [0, 1]; piecewise linear between samples.
        muscles: names of the muscles the columns drive; other muscles get zero excitation.
        initial_state: state-variable values by name (see :func:`read_initial_state`); names the
            model does not have are ignored, so a 3.x file fits a model with locked coordinates.
            Without fibre lengths among them, the muscles start in equilibrium.
        settings: integrator settings.
        wall_limit: stop with status ``"timeout"`` after this many wall-clock seconds (checked
            between samples; :func:`run_isolated` also kills a run stuck inside one sample).
    """
    osim = runtime.opensim()
    t0 = time.perf_counter()
    times = np.asarray(times, float)
    excitations = np.asarray(excitations, float)
    if excitations.shape != (len(times), len(muscles)):
        raise ValueError(f"excitations shape {excitations.shape} != ({len(times)}, {len(muscles)})")
    model = osim.Model(str(osim_path))
    model.setUseVisualizer(False)
    all_muscles = model.getMuscles()
    muscle_names = [all_muscles.get(i).getName() for i in range(all_muscles.getSize())]
    unknown = sorted(set(muscles) - set(muscle_names))
    if unknown:
        raise ValueError(f"{osim_path}: no muscles named {unknown}")
    column = {name: i for i, name in enumerate(muscles)}
    controller = osim.PrescribedController()
    controller.setName("o2m_excitations")
    for name in muscle_names:
        controller.addActuator(all_muscles.get(name))
        fn = osim.PiecewiseLinearFunction()
        series = excitations[:, column[name]] if name in column else np.zeros(len(times))
        for t, u in zip(times, series, strict=False):
            fn.addPoint(float(t), float(u))
        if len(times) == 1:
            fn.addPoint(float(times[0]) + 1.0, float(series[0]))
        controller.prescribeControlForActuator(name, fn)
    model.addController(controller)
    state = model.initSystem()
    coords = model.getCoordinateSet()
    mj_names = opensim_coordinate_names(model)
    coord_names = [mj_names[coords.get(i).getAbsolutePathString()] for i in range(coords.getSize())]
    given: set[str] = set()
    if initial_state:
        sv_names = list(model.getStateVariableNames().to_numpy()) if hasattr(
            model.getStateVariableNames(), "to_numpy") else [
            model.getStateVariableNames().get(i) for i in range(model.getNumStateVariables())]
        for label, value in initial_state.items():
            path = _state_variable_path(sv_names, label)
            if path is not None:
                model.setStateVariableValue(state, path, float(value))
                given.add(path)
    state.setTime(float(times[0]))
    if not any(p.endswith("/fiber_length") for p in given):
        # no fibre lengths given: start the muscles in equilibrium (OpenSim's ForwardTool does the
        # same), not at OpenSim's default fibre length, which can start a muscle at many times its
        # max isometric force
        model.equilibrateMuscles(state)
    model.realizeVelocity(state)

    n, nc, nm = len(times), len(coord_names), len(muscle_names)
    q, u = np.full((n, nc), np.nan), np.full((n, nc), np.nan)
    act, force = np.full((n, nm), np.nan), np.full((n, nm), np.nan)
    coord_objs = [coords.get(i) for i in range(nc)]
    muscle_objs = [all_muscles.get(i) for i in range(nm)]

    def record(k: int, s) -> bool:
        q[k] = [c.getValue(s) for c in coord_objs]
        u[k] = [c.getSpeedValue(s) for c in coord_objs]
        act[k] = [m.getActivation(s) for m in muscle_objs]
        force[k] = [tendon_force(m, s) for m in muscle_objs]  # valid: the state is realized to Dynamics
        return bool(np.isfinite(q[k]).all() and np.isfinite(u[k]).all())

    t_integrate = [float("nan")]

    def result(status: str, reason: str, t_reached: float) -> OpenSimRun:
        now = time.perf_counter()
        return OpenSimRun(status, reason, times, q, u, act, force, coord_names, muscle_names, t_reached, now - t0,
                          now - t_integrate[0], fibres)

    model.realizeDynamics(state)
    fibres = np.array([_fibre_length(m, state) for m in muscle_objs], dtype=float)
    if not record(0, state):
        return result("nan", f"non-finite initial state at t={times[0]:g} s", float(times[0]))
    manager = osim.Manager(model)
    manager.setIntegratorMethod(getattr(osim.Manager.IntegratorMethod, settings.method)
                                if hasattr(osim.Manager, "IntegratorMethod")
                                else getattr(osim.Manager, f"IntegratorMethod_{settings.method}"))
    manager.setIntegratorAccuracy(settings.accuracy)
    manager.setIntegratorMinimumStepSize(settings.min_step)
    manager.setIntegratorMaximumStepSize(settings.max_step)
    manager.setRecordStatesTrajectory(False) if hasattr(manager, "setRecordStatesTrajectory") else None
    t_integrate[0] = time.perf_counter()
    manager.initialize(state)
    for k in range(1, n):
        if wall_limit is not None and time.perf_counter() - t0 > wall_limit:
            return result("timeout", f"wall-clock limit {wall_limit:g} s reached at t={times[k - 1]:g} s",
                          float(times[k - 1]))
        try:
            state = manager.integrate(float(times[k]))
            model.realizeDynamics(state)
        except Exception as exc:  # OpenSim raises RuntimeError subclasses with SimTK's message
            return result("failed", f"at t={times[k - 1]:g}..{times[k]:g} s: {str(exc).strip()[:500]}",
                          float(times[k - 1]))
        if not record(k, state):
            bad = [coord_names[j] for j in np.flatnonzero(~np.isfinite(q[k]) | ~np.isfinite(u[k]))]
            return result("nan", f"non-finite state at t={times[k]:g} s in {bad[:5]}", float(times[k]))
    return result("ok", "", float(times[-1]))


# --------------------------------------------------------------------------- isolation


def _worker_main(argv: list[str]) -> int:
    """``python -m o2m.osim.simulate IN.npz OUT.npz``: run :func:`simulate` on a job file
    (inside :func:`~o2m.osim.runtime.opensim_log` when the job names a log file)."""
    job, out = argv
    with np.load(job, allow_pickle=False) as z:
        init = dict(zip([str(s) for s in z["init_names"]], z["init_values"].tolist(), strict=False))
        settings = IntegratorSettings(str(z["method"]), float(z["accuracy"]), float(z["min_step"]),
                                      float(z["max_step"]))
        log_file = str(z["opensim_log"])
        with runtime.opensim_log(log_file) if log_file else contextlib.nullcontext():
            run = simulate(str(z["osim"]), z["times"], z["excitations"], [str(s) for s in z["muscles"]],
                           initial_state=init, settings=settings, wall_limit=float(z["wall_limit"]))
    run.to_npz(out)
    return 0


def run_isolated(osim_path: str | os.PathLike[str], times: np.ndarray, excitations: np.ndarray,
                 muscles: Sequence[str], *, initial_state: Mapping[str, float] | None = None,
                 settings: IntegratorSettings = IntegratorSettings(), timeout: float = 600.0,
                 opensim_log: str | os.PathLike[str] | None = None) -> OpenSimRun:
    """:func:`simulate` in a fresh Python process, killed after ``timeout`` wall-clock seconds.

    ``opensim_log``: a file the process appends OpenSim's log to (info level); None keeps it at
    error level, in the captured output.

    Any way the process can end (a crash, a kill, an exception) comes back as an
    :class:`OpenSimRun` with a status and reason; this function itself does not raise for
    OpenSim's failures.
    """
    init = dict(initial_state or {})
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="o2m-osim-") as tmp:
        job, out = Path(tmp) / "job.npz", Path(tmp) / "out.npz"
        np.savez(job, osim=str(Path(osim_path).resolve()), times=np.asarray(times, float),
                 excitations=np.asarray(excitations, float), muscles=np.array(list(muscles)),
                 init_names=np.array(list(init), dtype=str), init_values=np.array(list(init.values()), float),
                 method=settings.method, accuracy=settings.accuracy, min_step=settings.min_step,
                 max_step=settings.max_step, wall_limit=float(timeout),
                 opensim_log=str(Path(opensim_log).resolve()) if opensim_log else "")
        try:
            proc = subprocess.run([sys.executable, "-m", "o2m.osim.simulate", str(job), str(out)], cwd=tmp,
                                  capture_output=True, text=True, timeout=timeout + 30.0)
        except subprocess.TimeoutExpired:
            return OpenSimRun.empty("timeout", f"killed after {timeout + 30:g} s wall clock", times,
                                    wall_time=time.perf_counter() - t0)
        if proc.returncode != 0 or not out.exists():
            tail = (proc.stderr or proc.stdout or "").strip().splitlines()[-3:]
            return OpenSimRun.empty("failed", f"worker exited with status {proc.returncode}: {' | '.join(tail)}",
                                    times, wall_time=time.perf_counter() - t0)
        return OpenSimRun.from_npz(out)


def _fibre_length(muscle, state) -> float:
    """A muscle's fibre length (m) in a realised ``state``; NaN where its class has none."""
    try:
        return float(muscle.getFiberLength(state))
    except Exception:  # OpenSim raises RuntimeError subclasses
        return float("nan")


def tendon_force(muscle, state) -> float:
    """A muscle's tendon force (N) in ``state``; its actuation where OpenSim 4.6 does not implement
    the muscle's dynamics (Delp1990Muscle_Deprecated: "calcActiveForce() NOT IMPLEMENTED"), which
    its static equilibrium and its forward dynamics set. Raises RuntimeError where OpenSim has
    neither for this state."""
    try:
        return float(muscle.getTendonForce(state))
    except RuntimeError:
        return float(muscle.getActuation(state))


def run_many(osim_path: str | os.PathLike[str], times: np.ndarray, excitation_sets: np.ndarray,
             muscles: Sequence[str], *, sets: Sequence[int] | None = None,
             runs_dir: str | os.PathLike[str] | None = None,
             initial_state: Mapping[str, float] | None = None,
             settings: IntegratorSettings = IntegratorSettings(), timeout: float = 600.0,
             executor: cf.Executor | None = None, max_workers: int | None = None,
             progress: bool = True, desc: str = "OpenSim runs",
             opensim_log: str | os.PathLike[str] | None = None) -> list[OpenSimRun]:
    """Run sets of ``excitation_sets`` (shape (n_sets, T, n_muscles)) with :func:`run_isolated`.

    Args:
        sets: the set indices to run, in the order they are started (default: all, in order).
        runs_dir: resume there: a set whose ``set_NNN.npz`` exists is read, not run, and every
            new run is written there as soon as it finishes (so an interrupted batch loses at
            most the runs in flight).
        executor: any :class:`concurrent.futures.Executor` (a Dask client's ``get_executor()``
            works); by default a local process pool with ``max_workers`` (all cores) workers.
        opensim_log: the file every run appends OpenSim's log to (see :func:`run_isolated`).

    Returns:
        One run per entry of ``sets``, in that order. A failure in one set never stops the
        others; it is reported under the progress bar.
    """
    from tqdm.auto import tqdm

    order = list(range(len(excitation_sets)) if sets is None else sets)
    saved = Path(runs_dir) if runs_dir is not None else None
    if saved is not None:
        saved.mkdir(parents=True, exist_ok=True)
    done: dict[int, OpenSimRun] = {i: OpenSimRun.from_npz(saved / f"set_{i:03d}.npz") for i in order
                                   if saved is not None and (saved / f"set_{i:03d}.npz").exists()}
    todo = [i for i in order if i not in done]
    own = executor is None and bool(todo)
    if own:
        executor = cf.ProcessPoolExecutor(max_workers=max_workers or os.cpu_count())
    bar = tqdm(total=len(order), initial=len(done), desc=desc, unit="run", disable=not progress)
    try:
        futures = {executor.submit(run_isolated, str(osim_path), times, excitation_sets[i], list(muscles),
                                   initial_state=dict(initial_state or {}), settings=settings, timeout=timeout,
                                   opensim_log=opensim_log): i
                   for i in todo}
        failed = 0
        for fut in cf.as_completed(futures):
            i = futures[fut]
            try:
                run = fut.result()
            except Exception as exc:  # the executor itself failed (lost worker, pickling)
                run = OpenSimRun.empty("failed", f"executor error: {exc!r}", times)
            if saved is not None:
                run.to_npz(saved / f"set_{i:03d}.npz")
            if not run.ok:
                failed += 1
                bar.write(f"set {i}: {run.status}: {run.reason}")
                bar.set_postfix(failed=failed)
            done[i] = run
            bar.update()
        return [done[i] for i in order]
    finally:
        bar.close()
        if own:
            executor.shutdown()


if __name__ == "__main__":
    raise SystemExit(_worker_main(sys.argv[1:]))
