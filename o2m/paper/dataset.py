"""The MoBL-ARMS reference dataset: excitation sets, OpenSim trajectories, failures and the split.

Regenerate it with ``python -m o2m dataset`` (about half an hour on 2 cores); the result is
kept in ``data/mobl_arms/``:

``activations.npz``
    ``times`` (T,) s; ``values`` (n_sets, T, n_muscles) excitations in [0, 1]; ``active``,
    ``amplitude``, ``frequency`` (Hz), ``phase`` (rad), each (n_sets, n_muscles); ``muscles``;
    ``seed``. Regenerated exactly by :func:`o2m.activations.generate_activations`.
``opensim.npz``
    ``status`` (n_sets,) ``"ok"``/``"failed"``/``"nan"``/``"timeout"``; ``reason``;
    ``t_reached`` and ``wall_time`` (n_sets,) s; ``coordinates`` and ``speeds``
    (n_sets, T, n_coordinates) float32, rad or m (NaN after a failure); ``activations``
    (n_sets, T, n_muscles) float16; ``tendon_forces`` (n_sets, T, n_muscles) float16, N, each
    muscle's tendon force (positive when pulling); ``coordinate_names``; ``muscle_names``; the
    model file's registry path and sha256; OpenSim's version; the integrator settings.
``split.json``
    ``train``, ``test`` and ``validation`` set indices, drawn (seeded) from the runs that
    succeeded: the paper's 78 training and 19 test sets (of its 97 successful runs; fewer
    successes shrink both in proportion), the rest held out for validation.

Runs are saved one file each under ``<out>/runs/`` as they finish, so an interrupted
generation resumes where it stopped.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from o2m.activations import ActivationSets, generate_activations
from o2m.osim import runtime
from o2m.osim.simulate import IntegratorSettings, OpenSimRun, read_initial_state, run_many

__all__ = ["Dataset", "MOBL_MODEL", "load_dataset", "make_dataset", "make_split"]

MOBL_MODEL = "mobl_arms_no_wrap"
"""The bundled model the dataset simulates: MoBL-ARMS for testing, wrist locked, no wrap objects
(the wrapped OpenSim model stalls: 0.47 s simulated in 960 s)."""
MOBL_INITIAL_STATE = "mobl-arms/initial_states.sto"
DEFAULT_SEED = 2020
#: The paper's split: 78 training and 19 test sets of its 97 successful OpenSim runs.
PAPER_SPLIT = (78, 19)


@dataclass
class Dataset:
    """A loaded dataset (see the module docstring for the arrays and their units)."""

    activations: ActivationSets
    status: np.ndarray
    reason: np.ndarray
    t_reached: np.ndarray
    wall_time: np.ndarray
    coordinates: np.ndarray
    speeds: np.ndarray
    opensim_activations: np.ndarray
    tendon_forces: np.ndarray
    coordinate_names: list[str]
    muscle_names: list[str]
    train: list[int]
    test: list[int]
    validation: list[int]
    meta: dict

    @property
    def times(self) -> np.ndarray:
        return self.activations.times

    @property
    def ok(self) -> np.ndarray:
        return self.status == "ok"

    def failures(self) -> list[tuple[int, str, str]]:
        """``(set index, status, reason)`` of every run that did not succeed."""
        return [(i, str(self.status[i]), str(self.reason[i])) for i in np.flatnonzero(~self.ok)]


def make_split(ok: np.ndarray, *, seed: int, sizes: tuple[int, int] = PAPER_SPLIT
               ) -> tuple[list[int], list[int], list[int]]:
    """Seeded (train, test, validation) split of the successful set indices.

    ``sizes`` are the training and test counts wanted (the paper's 78 and 19); with fewer
    successful runs than their sum both shrink in proportion. What is left is validation.
    """
    good = np.flatnonzero(ok)
    perm = np.random.default_rng(seed).permutation(good)
    n_train, n_test = sizes
    if len(good) < n_train + n_test:
        n_test = int(round(len(good) * n_test / (n_train + n_test)))
        n_train = len(good) - n_test
    test, train, rest = perm[:n_test], perm[n_test:n_test + n_train], perm[n_test + n_train:]
    return sorted(int(i) for i in train), sorted(int(i) for i in test), sorted(int(i) for i in rest)


def _save_activations(path: Path, s: ActivationSets) -> None:
    np.savez_compressed(path, times=s.times, values=s.values, active=s.active, amplitude=s.amplitude,
                        frequency=s.frequency, phase=s.phase, muscles=np.array(s.muscles), seed=s.seed)


def _load_activations(path: Path) -> ActivationSets:
    with np.load(path) as z:
        return ActivationSets(z["times"], z["values"], z["active"], z["amplitude"], z["frequency"], z["phase"],
                              tuple(str(m) for m in z["muscles"]), int(z["seed"]))


def make_dataset(out_dir: str | os.PathLike[str], *, n_sets: int = 100, seed: int = DEFAULT_SEED,
                 model: str = MOBL_MODEL, timeout: float = 600.0, executor=None, max_workers: int | None = None,
                 settings: IntegratorSettings = IntegratorSettings(),  # noqa: B008 (frozen)
                 progress: bool = True, opensim_log: str | os.PathLike[str] | None = None) -> Dataset:
    """Generate excitations, run them in OpenSim (resuming from ``<out>/runs/``), write the dataset.

    Every OpenSim run appends its log to ``opensim_log`` (default ``<out>/runs/opensim.log``).
    """
    from o2m import models

    out = Path(out_dir)
    runs_dir = out / "runs"
    runs_dir.mkdir(parents=True, exist_ok=True)
    log_file = Path(opensim_log) if opensim_log is not None else runs_dir / "opensim.log"
    osim_path = models.fetch_model(model, progress=False)
    init = read_initial_state(models.fetch(MOBL_INITIAL_STATE))
    opensim = runtime.opensim()
    with runtime.opensim_log(log_file):
        m = opensim.Model(str(osim_path))
        muscles = [m.getMuscles().get(i).getName() for i in range(m.getMuscles().getSize())]
        del m
    sets = generate_activations(muscles, n_sets, seed=seed)
    _save_activations(out / "activations.npz", sets)

    runs = run_many(osim_path, sets.times, sets.values, muscles, runs_dir=runs_dir, initial_state=init,
                    settings=settings, timeout=timeout, executor=executor, max_workers=max_workers,
                    progress=progress, opensim_log=log_file)
    meta = {"model": models.bundled_model(model).osim,
            "model_sha256": models.sha256_of(osim_path), "opensim_version": opensim.__version__,
            "integrator": settings.__dict__, "seed": seed, "n_sets": n_sets, "timeout_s": timeout,
            "initial_state": MOBL_INITIAL_STATE,
            "command": f"python -m o2m dataset --out {out_dir} --sets {n_sets} --seed {seed}"}
    _write_opensim(out / "opensim.npz", runs, meta)
    ok = np.array([r.ok for r in runs])
    train, test, validation = make_split(ok, seed=seed)
    (out / "split.json").write_text(json.dumps({"seed": seed, "train": train, "test": test, "validation": validation},
                                               indent=1) + "\n")
    return load_dataset(out)


def _write_opensim(path: Path, runs: list[OpenSimRun], meta: dict) -> None:
    ref = next((r for r in runs if r.coordinate_names), None)
    if ref is None:
        raise RuntimeError("no OpenSim run produced any data; see the failure reasons in runs/")
    nc, nm, n_t = len(ref.coordinate_names), len(ref.muscle_names), len(ref.times)

    def grid(r: OpenSimRun, attr: str, width: int) -> np.ndarray:
        a = getattr(r, attr)
        return a if a.shape == (n_t, width) else np.full((n_t, width), np.nan)

    np.savez_compressed(
        path, status=np.array([r.status for r in runs]), reason=np.array([r.reason for r in runs]),
        t_reached=np.array([r.t_reached for r in runs]), wall_time=np.array([r.wall_time for r in runs]),
        coordinates=np.stack([grid(r, "coordinates", nc) for r in runs]).astype(np.float32),
        speeds=np.stack([grid(r, "speeds", nc) for r in runs]).astype(np.float32),
        activations=np.stack([grid(r, "activations", nm) for r in runs]).astype(np.float16),
        tendon_forces=np.stack([grid(r, "tendon_forces", nm) for r in runs]).astype(np.float16),
        coordinate_names=np.array(ref.coordinate_names), muscle_names=np.array(ref.muscle_names),
        meta=json.dumps(meta))


def load_dataset(directory: str | os.PathLike[str]) -> Dataset:
    """Load a dataset written by :func:`make_dataset` (e.g. ``data/mobl_arms``)."""
    d = Path(directory)
    sets = _load_activations(d / "activations.npz")
    with np.load(d / "opensim.npz") as z:
        arrays = {k: z[k] for k in z.files}
    split = json.loads((d / "split.json").read_text())
    forces = arrays.get("tendon_forces")
    if forces is None:  # a dataset written before o2m recorded tendon forces
        forces = np.full(arrays["activations"].shape, np.nan)
    return Dataset(sets, arrays["status"], arrays["reason"], arrays["t_reached"], arrays["wall_time"],
                   arrays["coordinates"].astype(float), arrays["speeds"].astype(float),
                   arrays["activations"].astype(float), forces.astype(float),
                   [str(s) for s in arrays["coordinate_names"]], [str(s) for s in arrays["muscle_names"]],
                   split["train"], split["test"], split.get("validation", []), json.loads(str(arrays["meta"])))
