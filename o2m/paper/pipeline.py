"""The paper's experiment on MoBL-ARMS, end to end: convert, simulate, fit, correct, measure.

:func:`load_experiment` converts the bundled MoBL-ARMS model (no wrap objects, wrist locked; the
model the OpenSim references were computed with) and lays the stored dataset out for MuJoCo:
initial states, controls and OpenSim joint trajectories of every successful set.
:func:`run_paper` then runs two pipelines on the training sets. The paper's: the paper's 160
parameters fitted to the joint trajectories with CMA-ES (:mod:`o2m.fitting`), the best training
candidate kept. o2m's: first each muscle's force to OpenSim's tendon forces along the training
trajectories (:mod:`o2m.force_fit`, which the paper did not do), then each set's never-excited
elbow and forearm muscles as OpenSim's passive fibres (:mod:`o2m.paper.passive_stage`, the
``o2m.fibre`` plugin), then the same CMA-ES fit, early-stopped on the validation sets. Beside
them o2m runs the converted model with OpenSim's own muscles (:func:`schutte_stage`, the
``o2m.schutte`` plugin), which needs no fit. It fits corrective controls on the test and fresh
sets (:mod:`o2m.corrections`) for all three, measures every
stage on the training, validation, test and fresh sets (:data:`FRESH_DIR`) and writes everything
the figures need to ``<data>/results/``:

``muscle_forces.json`` the muscle force fit (:meth:`o2m.force_fit.ForceFit.save`)
``parameters.json``   the CMA-ES fit (:func:`o2m.fitting.save_fit`)
``parameters_paper.json`` the paper's pipeline: the same CMA-ES fit of the converted model (no muscle force
                      fit), the best training candidate (no early stopping)
``*_checkpoint.pkl``  CMA-ES state, to resume an interrupted fit (not kept in git)
``corrections.npz``, ``corrections_paper.npz``, ``corrections_schutte.npz`` the corrective
                      controls' results of each pipeline, reused while the corrected model, sets
                      and budget are the same;
                      ``corrections_fresh_*.npz`` the same on the fresh sets
``results.npz``       per test set and DoF, mean absolute joint error (rad) of the converted,
                      force-fitted, passive-fibre, fitted, OpenSim-muscle and corrected models; per
                      test set and muscle, mean absolute correction; joint trajectories of the first
                      test sets for the overlay
``summary.json``      the headline numbers and the settings (quick or full)

and the fitted model itself as MJCF beside the converted one: ``<model_dir>/<stem>_fitted.xml``
without the fibres (any MuJoCo opens it) and ``<stem>_fitted_fibres.xml`` with their plugin
instances, all off until a run's state switches them on (:func:`fitted_experiment`).
"""

from __future__ import annotations

import json
import os
import time
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from o2m import models
from o2m.convert import ConvertOptions, convert, convert_once
from o2m.errors import O2MError
from o2m.mj.fibre_plugin import fibre_instances
from o2m.mj.simulate import controls_from_excitations, initial_state, muscle_activations, rollout
from o2m.paper.dataset import Dataset, load_dataset
from o2m.paper.fitting import (
    FitResult,
    TrajectoryObjective,
    checkpoint_matches,
    fit_cma,
    free_coordinates,
    load_fit,
    parameter_space,
    save_fit,
)
from o2m.paper.force_fit import ForceFit, fit_forces, sample_states, static_curves
from o2m.paper.model_key import model_structure, model_values, value_difference

__all__ = ["Experiment", "FULL", "QUICK", "Settings", "joint_mae", "load_experiment", "run_paper"]

DATA_DIR = Path("data/mobl_arms")
#: Under the data folder: excitation sets drawn with another seed (2026) and their OpenSim runs,
#: never used in any fit (``make_dataset(DATA_DIR / FRESH_DIR, n_sets=8, seed=2026)``).
FRESH_DIR = "fresh_seed2026"
#: Prefix of the model's float values (o2m.paper.model_key) stored in a corrections cache.
_VALUE = "model."


@dataclass(frozen=True)
class Settings:
    """Budgets of one run of the paper's pipeline."""

    generations: int
    popsize: int | None
    train_sets: int | None  # None: all training sets
    test_sets: int | None
    correction_generations: int  # CMA-ES generations per spline block (the paper's column, and o2m's with "cma")
    correction_sweeps: int = 3  # passes over the spline blocks (each block re-fitted after its successors moved)
    correction_method: str = "lm"  # o2m's column: Levenberg-Marquardt per block ("lm") or CMA-ES ("cma")
    correction_iterations: int = 6  # Levenberg-Marquardt iterations per block
    fresh_corrections: bool = True  # corrections on the fresh sets too (both columns)
    force_stride: int = 2  # every force_stride-th OpenSim sample (2 ms apart) enters the muscle force fit
    force_nfev: int = 600  # least-squares evaluations per muscle
    overlay_sets: int = 3
    seed: int = 0
    quick_conversion: bool = False  # the converter's quick wrap-fit sizes (ConvertOptions.quick)
    paper_generations: int | None = None  # CMA-ES generations of the paper's pipeline (None: generations)
    paper_correction_sets: int | None = None  # the first so many test sets get the paper pipeline's corrections
    force_weighting: str = "moment_arm"  # the force fit's residual weights (o2m.paper.force_fit.sample_states)
    force_settle: int = 0  # steps of run-up before each force-fit sample (sample_states(settle=...))
    sigma0: float = 0.1  # o2m's CMA-ES step in the unit box of the parameters (fitting.fit_cma)
    paper_sigma0: float = 0.1  # the paper's column's


#: The budget of the stored result: the muscle force fit on every other sample of the training
#: sets; 40 generations of 12 candidates, each simulated on all training sets (early-stopped on the
#: validation sets); corrections with 3 passes over the spline blocks, each block searched by 6
#: Levenberg-Marquardt iterations in o2m's column and by 12 CMA-ES generations in the paper's (the
#: budget study in docs/paper.md: more passes or generations stop paying past these). The paper's
#: pipeline gets the same CMA-ES budget.
FULL = Settings(generations=40, popsize=12, train_sets=None, test_sets=None, correction_generations=12)
#: How the paper's column searches its corrections' spline blocks: the paper's optimiser, CMA-ES.
PAPER_CORRECTION_METHOD = "cma"
QUICK = Settings(generations=3, popsize=8, train_sets=8, test_sets=2, correction_generations=2, correction_sweeps=1,
                 correction_iterations=1, fresh_corrections=False,
                 force_stride=10, force_nfev=60, quick_conversion=True)


@dataclass
class Experiment:
    """The dataset laid out for MuJoCo.

    Attributes:
        model: the converted MoBL-ARMS model; xml: its file.
        dataset: the stored OpenSim dataset.
        dofs: the free DoFs compared (rad).
        muscles: muscle names, in excitation column order.
        init: shape (n_sets, nstate); controls: (n_sets, T - 1, nu); reference: (n_sets, T, n_dofs).
        Rows of failed sets are NaN.
    """

    model: mujoco.MjModel
    xml: Path
    dataset: Dataset
    dofs: list[str]
    muscles: list[str]
    init: np.ndarray
    controls: np.ndarray
    reference: np.ndarray


def load_experiment(data_dir: str | os.PathLike[str] = DATA_DIR, model_dir: str | os.PathLike[str] = "out/paper",
                    *, options: ConvertOptions = ConvertOptions(), reconvert: bool = False) -> Experiment:  # noqa: B008
    """Convert the dataset's model into ``model_dir`` (unless that conversion, with ``options``, is
    already there: :func:`o2m.convert.convert_once`); lay out the data."""

    ds = load_dataset(data_dir)
    fetched = models.fetch_model_with_geometry(ds.meta["model"], progress=False)
    if models.sha256_of(fetched.osim) != ds.meta["model_sha256"]:
        raise ValueError(f"the dataset was made with another version of {ds.meta['model']}")
    if reconvert:
        xml = convert(fetched.osim, model_dir, options, geometry_dirs=[fetched.geometry_dir]).xml
    else:
        xml = convert_once(fetched.osim, model_dir, options, geometry_dirs=[fetched.geometry_dir])
    model = mujoco.MjModel.from_xml_path(str(xml))
    dofs = free_coordinates(model, ds.coordinate_names)
    muscles = list(ds.activations.muscles)
    cols = [ds.coordinate_names.index(d) for d in dofs]
    n, n_t = len(ds.status), len(ds.times)
    init = np.full((n, mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)), np.nan)
    for i in np.flatnonzero(ds.ok):
        init[i] = initial_state(model, dict(zip(ds.coordinate_names, ds.coordinates[i, 0], strict=False)),
                                speeds=dict(zip(ds.coordinate_names, ds.speeds[i, 0], strict=False)),
                                activations=dict(zip(ds.muscle_names, ds.opensim_activations[i, 0], strict=False)))
    controls = controls_from_excitations(model, muscles, ds.activations.values)
    reference = ds.coordinates[:, :, cols]
    assert reference.shape == (n, n_t, len(dofs))
    return Experiment(model, xml, ds, dofs, muscles, init, controls, reference)


def joint_mae(exp: Experiment, model: mujoco.MjModel, sets: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Mean absolute joint error of ``model`` per set and DoF, shape (len(sets), n_dofs), rad; and the trajectories."""
    tr = rollout(model, exp.init[sets], exp.controls[sets], joint_names=exp.dofs)
    err = np.mean(np.abs(tr.coordinates - exp.reference[sets]), axis=1)
    err[tr.diverged] = np.nan
    return err, tr.coordinates


def run_paper(data_dir: str | os.PathLike[str] = DATA_DIR, *, settings: Settings = FULL,
              model_dir: str | os.PathLike[str] = "out/paper", results_dir: str | os.PathLike[str] | None = None,
              refit: bool = False, progress: bool = True, executor=None) -> dict:
    """Fit parameters and corrections and write ``results/`` (see the module docstring); returns the summary.

    ``executor`` (any :class:`concurrent.futures.Executor`, e.g. a Dask client's ``get_executor()``)
    evaluates the CMA-ES candidates, one task each; by default they run here on all cores.
    """
    options = ConvertOptions(quick=settings.quick_conversion)
    exp = load_experiment(data_dir, model_dir, options=options)
    out = Path(results_dir) if results_dir else Path(data_dir) / "results"
    out.mkdir(parents=True, exist_ok=True)
    train = exp.dataset.train[: settings.train_sets] if settings.train_sets else exp.dataset.train
    test = exp.dataset.test[: settings.test_sets] if settings.test_sets else exp.dataset.test
    t_force = time.perf_counter()
    forces = fit_muscle_forces(exp, train, out / "muscle_forces.json", settings=settings, refit=refit,
                               progress=progress)
    force_model = forces.apply(exp.model)
    force_seconds = time.perf_counter() - t_force
    forces_xml = write_forces_xml(exp, forces)
    fibre_exp = passive_fibre_stage(exp, forces_xml)
    held = [i for i in exp.dataset.validation if exp.dataset.ok[i]]
    paper_settings = replace(settings, generations=settings.paper_generations or settings.generations,
                             sigma0=settings.paper_sigma0)
    paper_space, paper_fit = fit_parameters(exp, exp.model, train, held, out / "parameters_paper.json",
                                            settings=paper_settings, refit=refit, progress=progress,
                                            executor=executor, early_stopping=False)
    space, fit = fit_parameters(fibre_exp, fibre_exp.model, train, held, out / "parameters.json", settings=settings,
                                refit=refit, progress=progress, executor=executor, early_stopping=True)
    fitted = space.apply(fibre_exp.model, fit.x)
    fitted_xml = exp.xml.with_name(exp.xml.stem + "_fitted.xml")  # beside the converted model: its meshes
    forces.write_mjcf(exp.xml, fitted_xml)  # without the plugin, which any MuJoCo opens
    space.write_mjcf(force_model, fit.x, fitted_xml, fitted_xml)
    space.write_mjcf(fibre_exp.model, fit.x, fibre_exp.xml, fitted_xml.with_name(fitted_xml.stem + "_fibres.xml"))

    paper_fitted = paper_space.apply(exp.model, paper_fit.x)
    schutte_exp = schutte_stage(exp)
    # each stage's model with the experiment laid out for it (o2m's plugins carry their initial states)
    stage_runs = {"converted": (exp, exp.model), "force_fitted": (exp, force_model),
                  "fibres": (fibre_exp, fibre_exp.model), "fitted": (fibre_exp, fitted),
                  "paper_fitted": (exp, paper_fitted), "schutte": (schutte_exp, schutte_exp.model)}
    errors, trajectories = {}, {}
    for name, (e, m) in stage_runs.items():
        errors[name], trajectories[name] = joint_mae(e, m, test)
    t1 = time.perf_counter()
    k = min(settings.overlay_sets, len(test))
    corrected = correct_sets(fibre_exp, fitted, test, settings=settings, force_start=True, progress=progress,
                             cache=out / "corrections.npz", refit=refit, keep=k, method=settings.correction_method)
    corr_seconds = time.perf_counter() - t1
    paper_test = test[: settings.paper_correction_sets] if settings.paper_correction_sets else test
    paper_corrected = correct_sets(exp, paper_fitted, paper_test, settings=settings, force_start=False,
                                   progress=progress, cache=out / "corrections_paper.npz", refit=refit, keep=k,
                                   method=PAPER_CORRECTION_METHOD)
    schutte_corrected = correct_sets(schutte_exp, schutte_exp.model, test, settings=settings, force_start=False,
                                     progress=progress, cache=out / "corrections_schutte.npz", refit=refit, keep=k,
                                     method=settings.correction_method)
    errors["corrected"] = corrected[0]
    errors["schutte_corrected"] = schutte_corrected[0]
    # NaN rows for test sets the paper's pipeline was not corrected on (a smaller budget)
    errors["paper_corrected"] = np.full_like(corrected[0], np.nan)
    errors["paper_corrected"][: len(paper_test)] = paper_corrected[0]
    fresh_exp = load_fresh_experiment(Path(data_dir), model_dir, options=options)
    fresh, fresh_sizes = {}, {}
    if fresh_exp:
        fresh_fibres = passive_fibre_stage(fresh_exp[0], forces_xml)
        fresh_schutte = schutte_stage(fresh_exp[0], like=schutte_exp)
        fresh_stage = {id(fibre_exp): fresh_fibres, id(schutte_exp): fresh_schutte}
        fresh = {name: joint_mae(fresh_stage.get(id(e), fresh_exp[0]), m, fresh_exp[1])[0]
                 for name, (e, m) in stage_runs.items()}
    if fresh_exp and settings.fresh_corrections:
        columns = {"corrected": (fresh_fibres, fitted, True, settings.correction_method),
                   "paper_corrected": (fresh_exp[0], paper_fitted, False, PAPER_CORRECTION_METHOD),
                   "schutte_corrected": (fresh_schutte, schutte_exp.model, False, settings.correction_method)}
        for name, (err, size) in correct_fresh_sets(fresh_exp[1], columns, out, settings=settings, refit=refit,
                                                    progress=progress).items():
            fresh[name], fresh_sizes[name] = err, float(np.mean(size))
    # every stage's error off the test sets too: does a fit generalise, or only fit its training sets?
    split_errors = {split: {name: float(np.nanmean(joint_mae(e, m, sets)[0])) for name, (e, m) in stage_runs.items()}
                    for split, sets in (("train", train), ("validation", held)) if sets}
    split_errors["test"] = {name: float(np.nanmean(errors[name])) for name in stage_runs}
    split_errors.update({"fresh": {k: float(np.nanmean(fresh[k])) for k in stage_runs if k in fresh}} if fresh else {})
    np.savez_compressed(
        out / "results.npz", dofs=np.array(exp.dofs), muscles=np.array(exp.muscles), test=np.array(test),
        times=exp.dataset.times, err_converted=errors["converted"], err_forces=errors["force_fitted"],
        err_fitted=errors["fitted"], err_corrected=corrected[0], correction_mae=corrected[1],
        err_paper_fitted=errors["paper_fitted"], err_paper_corrected=paper_corrected[0],
        correction_mae_paper=paper_corrected[1], paper_corrected_sets=np.array(paper_test),
        overlay_sets=np.array(test[:k]),
        overlay_opensim=exp.reference[test[:k]], overlay_converted=trajectories["converted"][:k],
        overlay_forces=trajectories["force_fitted"][:k], overlay_fitted=trajectories["fitted"][:k],
        overlay_corrected=corrected[2], overlay_paper_fitted=trajectories["paper_fitted"][:k],
        overlay_paper_corrected=paper_corrected[2],
        err_fibres=errors["fibres"], overlay_fibres=trajectories["fibres"][:k],
        err_schutte=errors["schutte"], overlay_schutte=trajectories["schutte"][:k],
        err_schutte_corrected=schutte_corrected[0], correction_mae_schutte=schutte_corrected[1],
        overlay_schutte_corrected=schutte_corrected[2],
        **{f"fresh_err_{name}": e for name, e in fresh.items()})
    summary = {
        "settings": settings.__dict__, "n_train": len(train), "n_test": len(test),
        "mean_error_rad": {k: float(np.nanmean(v)) for k, v in errors.items()},
        "per_joint_error_rad": {d: {k: float(np.nanmean(v[:, j])) for k, v in errors.items()}
                                for j, d in enumerate(exp.dofs)},
        "diverged_test_sets": {k: int(np.isnan(v).any(axis=1).sum()) for k, v in errors.items()
                               if "corrected" not in k},
        "split_error_rad": split_errors,
        "mean_abs_correction": float(np.mean(corrected[1])),
        "mean_abs_correction_paper": float(np.mean(paper_corrected[1])),
        "mean_abs_correction_schutte": float(np.mean(schutte_corrected[1])),
        "paper_corrected_sets": len(paper_test),
        "corrected_on_paper_sets": float(np.mean(corrected[0][: len(paper_test)])),
        "mean_abs_correction_on_paper_sets": float(np.mean(corrected[1][: len(paper_test)])),
        "fresh_sets": {"n": int(next(iter(fresh.values())).shape[0]) if fresh else 0,
                       "mean_error_rad": {k: float(np.nanmean(v)) for k, v in fresh.items()},
                       "per_joint_error_rad": {d: {k: float(np.nanmean(v[:, j])) for k, v in fresh.items()}
                                               for j, d in enumerate(exp.dofs)} if fresh else {},
                       "mean_abs_correction": fresh_sizes},
        "muscle_forces": forces.summary(),
        "fitted_xml": str(fitted_xml),
        "passive_fibres": {"xml": str(fitted_xml.with_name(fitted_xml.stem + "_fibres.xml")),
                           "muscles": sorted(fibre_instances(fibre_exp.model).values())},
        "schutte": {"xml": str(schutte_exp.xml), "plugin": "o2m.schutte", "muscles": len(exp.muscles)},
        "fit": fit_summary(fit),
        "paper_fit": fit_summary(paper_fit),
        # the fits' own times (stored with them); the others only when computed here, so a run
        # from stored fits rewrites no timing
        "seconds": {"fit": fit.wall_time, "paper_fit": paper_fit.wall_time,
                    **({"muscle_forces": force_seconds, "corrections": corr_seconds} if refit else {})},
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary


def write_forces_xml(exp: Experiment, forces: ForceFit) -> Path:
    """Write the converted model with the muscle force fit ``forces`` beside it, as
    ``<stem>_forces.xml``; returns that file."""
    return forces.write_mjcf(exp.xml, exp.xml.with_name(exp.xml.stem + "_forces.xml"))


def passive_fibre_stage(exp: Experiment, forces_xml: Path) -> Experiment:
    """o2m's passive-fibre stage on ``exp`` (:func:`o2m.paper.passive_stage.fibre_experiment`): the
    force-fitted model ``forces_xml`` with each set's never-excited elbow and forearm muscles pulling
    as OpenSim's passive fibres (the plugin built beside it). Raises :class:`O2MError` where the
    plugin cannot be built (no C compiler)."""
    from o2m.paper.passive_stage import fibre_experiment

    try:
        return fibre_experiment(exp, forces_xml, forces_xml.parent)
    except O2MError as err:
        raise O2MError(f"o2m's pipeline runs its passive fibres in the o2m.fibre MuJoCo plugin: {err}") from err


def schutte_stage(exp: Experiment, like: Experiment | None = None) -> Experiment:
    """o2m's Schutte stage on ``exp`` (:func:`o2m.paper.schutte_stage.schutte_experiment`): the
    converted model with each muscle OpenSim's own, the ``o2m.schutte`` plugin (built beside the
    model); ``like``: that stage of another dataset of the same model, whose model it reuses.
    Raises :class:`O2MError` where the plugin cannot be built (no C compiler)."""
    from o2m.paper.schutte_stage import schutte_experiment

    try:
        return schutte_experiment(exp, exp.xml.parent, like)
    except O2MError as err:
        raise O2MError(f"o2m's pipeline runs OpenSim's muscles in the o2m.schutte MuJoCo plugin: {err}") from err


def fit_summary(fit: FitResult) -> dict:
    """The numbers of a CMA-ES fit the summary keeps (costs in rad²)."""
    return {"cost0": fit.cost0, "cost": fit.cost, "evaluations": fit.evaluations, "wall_time_s": fit.wall_time,
            "generations": len(fit.history), "validation_cost0": fit.validation_cost0,
            "validation_cost": fit.validation_cost,
            "best_training_cost": fit.settings.get("best_training_cost", fit.cost),
            "early_stopping": fit.settings.get("early_stopping", True)}


def correct_sets(exp: Experiment, model: mujoco.MjModel, sets: list[int], *, settings: Settings = FULL,
                 force_start: bool = True, progress: bool = True, cache: str | os.PathLike[str] | None = None,
                 refit: bool = False, keep: int | None = None, method: str = "cma",
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Corrective controls (:func:`o2m.corrections.fit_corrections`) for each of ``sets``.

    ``force_start``: start each from the force-matching correction when it is better (o2m's
    addition) instead of from no correction (the paper). ``method``: each spline block searched
    by CMA-ES (``"cma"``, the paper's, ``settings.correction_generations``) or Levenberg-Marquardt
    (``"lm"``, ``settings.correction_iterations``). Returns the joint error per set and DoF
    (n_sets, n_dofs) rad, the mean absolute correction per set and muscle (n_sets, n_muscles),
    and the corrected trajectories of the first ``keep`` sets (all if None), (keep, T, n_dofs).
    With ``cache`` (an .npz file) they are
    loaded from there when it holds the corrections of this model (its structure hashed, its
    float values the same up to rounding: :mod:`o2m.paper.model_key`), sets and budget, unless
    ``refit``; otherwise computed and saved there, with the model's values.
    """
    from tqdm.auto import tqdm

    from o2m.paper.corrections import fit_corrections

    key = correction_key(model, sets, settings, force_start, keep, method)
    values = model_values(model)
    if cache is not None and Path(cache).exists() and not refit:
        with np.load(cache) as z:
            stored = {k[len(_VALUE):]: z[k] for k in z.files if k.startswith(_VALUE)}
            why = "another model structure, sets or budget" if str(z["key"]) != key else \
                value_difference(stored, values)
            if why is None:
                return z["err"], z["size"], z["q"]
        warnings.warn(f"{cache} holds the corrections of another model or budget ({why}): computing them "
                      f"again for {len(sets)} sets", stacklevel=2)
    err, size, q = [], [], []
    for i in tqdm(sets, desc="corrections", unit="set", disable=not progress):
        r = fit_corrections(model, exp.init[i], exp.dataset.activations.values[i], exp.muscles, exp.reference[i],
                            exp.dofs, method=method, generations=settings.correction_generations,
                            iterations=settings.correction_iterations, sweeps=settings.correction_sweeps,
                            seed=settings.seed + i, start=correction_start(exp, model, i) if force_start else None)
        err.append(np.mean(np.abs(r.coordinates - exp.reference[i]), axis=0))
        size.append(np.mean(np.abs(r.correction), axis=0))
        q.append(r.coordinates)
    # float32 trajectories, as cached, so a run that computes them writes what a run that loads them does
    out = np.array(err), np.array(size), np.array(q[:keep], dtype=np.float32)
    if cache is not None:
        np.savez_compressed(cache, key=key, err=out[0], size=out[1], q=out[2],
                            **{_VALUE + k: v for k, v in values.items()})
    return out


def correction_key(model: mujoco.MjModel, sets: list[int], settings: Settings, force_start: bool,
                   keep: int | None = None, method: str = "cma") -> str:
    """What a set of corrections depends on, but the model's float values (:mod:`o2m.paper.model_key`):
    the compiled model's structure, the sets, the method and the budget."""
    budget = (list(map(int, sets)), settings.correction_generations, settings.correction_sweeps, settings.seed,
              force_start, keep)
    if method != "cma":  # CMA-ES's keys are those written before the method was a choice
        budget = (*budget[:1], method, settings.correction_iterations, *budget[2:])
    return model_structure(model) + json.dumps(budget)


def load_fresh_experiment(data_dir: Path, model_dir: str | os.PathLike[str], *,
                          options: ConvertOptions = ConvertOptions(),  # noqa: B008
                          ) -> tuple[Experiment, list[int]] | None:
    """The fresh sets of ``<data_dir>/FRESH_DIR`` (excitations drawn with another seed, never fitted
    on) laid out for MuJoCo, and the sets OpenSim ran; None if that dataset is not there."""
    fresh_dir = data_dir / FRESH_DIR
    if not (fresh_dir / "opensim.npz").exists():
        return None
    exp = load_experiment(fresh_dir, model_dir, options=options)
    return exp, [int(i) for i in np.flatnonzero(exp.dataset.ok)]


def correct_fresh_sets(sets: list[int], columns: dict[str, tuple[Experiment, mujoco.MjModel, bool, str]],
                       out: Path, *, settings: Settings = FULL, refit: bool = False, progress: bool = True,
                       ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Corrective controls on the fresh ``sets`` (:func:`load_fresh_experiment`), as :func:`correct_sets`
    on the test sets, per column ``name: (experiment, model, force_start, method)`` (the experiment
    laid out for that model), cached in ``out/corrections_fresh_<name>.npz``. Returns per column
    the joint error (n_sets, n_dofs) rad and the mean absolute correction per set and muscle."""
    result = {}
    for name, (exp, model, force_start, method) in columns.items():
        err, size, _ = correct_sets(exp, model, sets, settings=settings, force_start=force_start, progress=progress,
                                    cache=out / f"corrections_fresh_{name}.npz", refit=refit, keep=0, method=method)
        result[name] = err, size
    return result


def fit_parameters(exp: Experiment, model: mujoco.MjModel, train: list[int], held: list[int],
                   fit_file: str | os.PathLike[str], *, settings: Settings = FULL, refit: bool = False,
                   progress: bool = True, executor=None, early_stopping: bool = True):
    """The paper's CMA-ES fit (:func:`o2m.fitting.fit_cma`) of ``model`` on the ``train`` sets, scored on
    the ``held`` validation sets; loaded from ``fit_file`` unless ``refit`` (then saved there, with a
    checkpoint beside it). ``early_stopping``: choose the candidate by the validation sets (o2m) or
    take the best training candidate (the paper). Returns the parameter space and the fit."""
    fit_file = Path(fit_file)
    space = parameter_space(model, exp.dofs, exp.muscles)
    if fit_file.exists() and not refit:
        fit = load_fit(fit_file)
        if fit.names != space.names or fit.settings.get("xml", exp.xml.name) != exp.xml.name:
            raise ValueError(f"{fit_file} was fitted on another model ({fit.settings.get('xml')}, not {exp.xml.name}) "
                             "or has other parameters; rerun with refit=True")
        return space, fit
    objective = TrajectoryObjective(model, space, exp.init[train], exp.controls[train], exp.reference[train],
                                    exp.dofs, executor=executor)
    validation = TrajectoryObjective(model, space, exp.init[held], exp.controls[held], exp.reference[held],
                                     exp.dofs) if held else None
    ckpt = fit_file.with_name(fit_file.stem + "_checkpoint.pkl")
    if ckpt.exists() and not checkpoint_matches(ckpt, space, settings.seed, exp.xml.name):
        print(f"{ckpt}: left by a fit from another start or model (an earlier run); starting afresh")
        ckpt.unlink()
    fit = fit_cma(objective, seed=settings.seed, sigma0=settings.sigma0, generations=settings.generations,
                  popsize=settings.popsize,
                  checkpoint=ckpt, progress=progress, validation=validation, early_stopping=early_stopping,
                  settings={"train_sets": list(map(int, train)), "validation_sets": list(map(int, held)),
                            "xml": exp.xml.name})
    save_fit(fit_file, fit, space)
    return space, fit


def correction_start(exp: Experiment, model: mujoco.MjModel, i: int) -> np.ndarray | None:
    """:func:`o2m.corrections.force_matching_start` for set ``i`` (None when the dataset has no tendon forces)."""
    from o2m.paper.corrections import force_matching_start

    ds = exp.dataset
    if not np.isfinite(ds.tendon_forces[i]).all():
        return None
    s = sample_states(model, ds.coordinates[[i]], ds.speeds[[i]], ds.opensim_activations[[i]], ds.tendon_forces[[i]],
                      ds.coordinate_names, ds.muscle_names, stride=1)
    cols = [ds.muscle_names.index(m) for m in exp.muscles]
    return force_matching_start(model, ds.activations.values[i], exp.muscles, s.length[:, cols], s.velocity[:, cols],
                                s.force[:, cols])


def fit_muscle_forces(exp: Experiment, sets: list[int], path: str | os.PathLike[str], *, settings: Settings = FULL,
                      refit: bool = False, progress: bool = True) -> ForceFit:
    """The muscle force fit on ``sets`` (:mod:`o2m.force_fit`), loaded from ``path`` unless ``refit``; saved there."""
    path = Path(path)
    if path.exists() and not refit:
        forces = ForceFit.load(path)
        if set(forces.muscles) != set(exp.muscles):
            raise ValueError(f"{path} fits other muscles than this model; rerun with refit=True")
        return forces
    ds = exp.dataset
    if not np.isfinite(ds.tendon_forces[sets]).any():
        raise ValueError("the dataset has no OpenSim tendon forces (it predates them): regenerate it with "
                         "`python -m o2m dataset`")

    # MuJoCo's own activations for the sets' excitations, not OpenSim's: the fit then also absorbs
    # what MuJoCo's activation dynamics cannot copy (and, in part, an elastic tendon's lag)
    cols = [list(ds.activations.muscles).index(n) for n in ds.muscle_names]
    activations = muscle_activations(exp.model, ds.muscle_names, ds.activations.values[sets][..., cols],
                                     ds.opensim_activations[sets][:, 0, :])
    samples = sample_states(exp.model, ds.coordinates[sets], ds.speeds[sets], activations, ds.tendon_forces[sets],
                            ds.coordinate_names, ds.muscle_names, stride=settings.force_stride,
                            excitations=ds.activations.values[sets][..., cols], weight_coordinates=exp.dofs,
                            weighting=settings.force_weighting, settle=settings.force_settle)
    osim = models.fetch_model(ds.meta["model"], progress=False)
    forces = fit_forces(exp.model, samples, static=static_curves(osim, exp.model), max_nfev=settings.force_nfev,
                        progress=progress)
    forces.settings.update(sets=list(map(int, sets)), stride=settings.force_stride, max_nfev=settings.force_nfev,
                           settle=settings.force_settle)
    forces.save(path)
    return forces


def fitted_experiment(exp: Experiment, forces: ForceFit, fit: FitResult) -> Experiment:
    """``exp`` laid out for o2m's fitted model, which is its ``model``: the converted model with the
    muscle force fit, the passive fibres (:func:`passive_fibre_stage`) and the CMA-ES parameters."""
    fibre_exp = passive_fibre_stage(exp, write_forces_xml(exp, forces))
    space = parameter_space(fibre_exp.model, exp.dofs, exp.muscles)
    if fit.names != space.names:
        raise ValueError("the CMA-ES fit has other parameters than this model; rerun `python -m o2m paper --refit`")
    return replace(fibre_exp, model=space.apply(fibre_exp.model, fit.x))
