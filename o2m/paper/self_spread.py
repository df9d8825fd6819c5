"""OpenSim against itself: how far OpenSim's own trajectories move under changes that should not matter.

The paper's dataset (``data/mobl_arms``) was made with OpenSim's RungeKuttaMerson at accuracy
1e-5. This module reruns the 19 test sets with one change at a time (a *variant*, :data:`VARIANTS`):
a tighter integrator accuracy, every muscle's max isometric force scaled by 1 + 1e-3 (or 1e-2),
BRA's optimal fibre length 0.1 mm longer, or the initial elbow angle moved by 1e-4 rad, and
measures each run's mean absolute difference (rad) from the stored trajectory per set and joint.
Where OpenSim's self-spread is as large as MuJoCo's error, no converter can be judged below it on
those sets.

``python -m o2m.paper.self_spread [--variants NAME ...] [--max-workers 1]`` runs the variants
(each run in its own process through :func:`o2m.osim.simulate.run_isolated`; every finished run
is kept under ``--runs``, so an interrupted command resumes), prints the table next to MuJoCo's
per-set errors (``results/results.npz``) and writes ``<data>/self_spread.npz``:

``variants``, ``descriptions``, ``accuracy`` (V,); ``muscle_edits`` (V,) JSON ``[[muscle,
property, factor, added], ...]``; ``initial_offsets`` (V,) JSON ``{state name: added value}``;
``sets`` (S,) test set indices; ``dofs`` (D,);
``spread`` and ``spread_max`` (V, S, D) rad, mean and max absolute difference from the stored
trajectory over the 1 s (NaN where a variant was not run on a set or failed); ``trajectories``
(V, S, T, D) float32 rad; ``status`` (V, S); ``wall_time`` (V, S) s; ``mujoco_fitted`` (S, D)
rad, the fitted MuJoCo model's error on the same sets (``results/results.npz``); with
``--mujoco-model`` (default the fitted model of ``python -m o2m paper``), ``mujoco_variants`` (V',)
and ``mujoco_spread`` (V', S, D) rad, that model's own spread under the same changes
(:func:`mujoco_self_spread`); ``meta`` JSON (model, sha256, settings of every variant, command).
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import copy
import json
import sys
import tempfile
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import mujoco
import numpy as np
from lxml import etree

from o2m import models
from o2m.osim.simulate import IntegratorSettings, OpenSimRun, read_initial_state, run_many
from o2m.paper.dataset import MOBL_INITIAL_STATE, MOBL_MODEL, Dataset, load_dataset

__all__ = ["VARIANTS", "Variant", "compare_runs", "edit_muscles", "load_spread", "mujoco_errors", "mujoco_self_spread",
           "print_table", "run_variant", "scale_muscle_forces", "spread_table", "write_spread"]

DATA_DIR = Path("data/mobl_arms")
#: The test sets with MuJoCo's largest elbow errors (the floor section of docs/paper.md).
FIRST = (30, 62, 54)
FITTED_XML = "out/paper/MoBL_ARMS_model_for_testing_opensim_no_wrap_fitted.xml"
"""The fitted MuJoCo model ``python -m o2m paper`` writes."""
DOFS = ("elv_angle", "shoulder_elv", "shoulder_rot", "elbow_flexion", "pro_sup")


@dataclass(frozen=True)
class Variant:
    """One change to the dataset's OpenSim run.

    Attributes:
        name: short label (a folder name).
        description: what changed, in words.
        settings: the integrator settings.
        muscle_edits: ``(muscle, property, factor, added)`` changes to the model file: the
            muscle's ``property`` element becomes ``value * factor + added`` (SI units); muscle
            ``"*"`` means every muscle. Empty: the model as it is.
        initial_offsets: ``(state name, added value)`` pairs on the initial state (rad, rad/s).
        sets: the test sets to run (None: all of them).
    """

    name: str
    description: str
    settings: IntegratorSettings = field(default_factory=IntegratorSettings)
    muscle_edits: tuple[tuple[str, str, float, float], ...] = ()
    initial_offsets: tuple[tuple[str, float], ...] = ()
    sets: tuple[int, ...] | None = None


#: The variants, cheapest questions first. ``rerun`` is the dataset's own run repeated.
VARIANTS = (
    Variant("accuracy_1e-6", "integrator accuracy 1e-6", IntegratorSettings(accuracy=1e-6)),
    Variant("force_1e-3", "every muscle's max_isometric_force x (1 + 1e-3)",
            muscle_edits=(("*", "max_isometric_force", 1.001, 0.0),)),
    Variant("elbow_1e-4", "initial elbow_flexion + 1e-4 rad", initial_offsets=(("elbow_flexion", 1e-4),)),
    Variant("rerun", "the dataset's settings, run again", sets=FIRST),
    # the FIRST sets and the two sets that moved most at 1e-6
    Variant("accuracy_1e-7", "integrator accuracy 1e-7", IntegratorSettings(accuracy=1e-7),
            sets=(*FIRST, 88, 29)),
    Variant("bra_fiber_0.1mm", "BRA's optimal_fiber_length + 0.1 mm",
            muscle_edits=(("BRA", "optimal_fiber_length", 1.0, 1e-4),)),
    Variant("force_1e-2", "every muscle's max_isometric_force x (1 + 1e-2)",
            muscle_edits=(("*", "max_isometric_force", 1.01, 0.0),)),
)


def edit_muscles(src: str | Path, dst: str | Path, edits: tuple[tuple[str, str, float, float], ...]) -> int:
    """Write ``src`` to ``dst`` with muscle properties changed (see :attr:`Variant.muscle_edits`).

    A muscle is any element with a ``name`` attribute and the property as a child (the model's
    defaults section included). Returns the number of values changed; raises ``KeyError`` when
    an edit changes nothing. The rest of the document is left as it is, so OpenSim reads the
    same model but for the edits.
    """
    tree = etree.parse(str(src))
    count = 0
    for muscle, prop, factor, added in edits:
        path = f".//*[@name]/{prop}" if muscle == "*" else f".//*[@name='{muscle}']/{prop}"
        found = tree.getroot().findall(path)
        if not found:
            raise KeyError(f"{src}: no {prop} of muscle {muscle}")
        for el in found:
            el.text = repr(float(el.text) * factor + added)
        count += len(found)
    tree.write(str(dst), xml_declaration=True, encoding="UTF-8")
    return count


def scale_muscle_forces(src: str | Path, dst: str | Path, scale: float) -> int:
    """Write ``src`` to ``dst`` with every ``max_isometric_force`` (N) multiplied by ``scale``;
    returns the number of values changed."""
    return edit_muscles(src, dst, (("*", "max_isometric_force", scale, 0.0),))


def _initial_state(variant: Variant) -> dict[str, float]:
    """The dataset's initial state with the variant's offsets added."""
    init = read_initial_state(models.fetch(MOBL_INITIAL_STATE))
    for name, offset in variant.initial_offsets:
        if name not in init:
            raise KeyError(f"{name} is not in {MOBL_INITIAL_STATE}")
        init[name] += offset
    return init


def run_variant(variant: Variant, dataset: Dataset, runs_dir: Path, *, max_workers: int = 1,
                timeout: float = 1200.0, progress: bool = True) -> dict[int, OpenSimRun]:
    """Run ``variant`` on its test sets in OpenSim, each in its own process; ``{set: run}``.

    Finished runs are read from ``runs_dir/<variant>/set_NNN.npz`` and new ones written there as
    they finish. A perturbed model is written to a temporary folder and deleted afterwards.
    """
    sets = list(variant.sets if variant.sets is not None else dataset.test)
    # the sets where MuJoCo is farthest first, so that a partial run answers the question
    first = sorted(sets, key=lambda i: (i not in FIRST, FIRST.index(i) if i in FIRST else i))
    with tempfile.TemporaryDirectory(prefix="o2m-self-spread-") as tmp:
        osim = models.fetch_model(MOBL_MODEL, progress=False)
        if variant.muscle_edits:
            osim = Path(tmp) / osim.name
            edit_muscles(models.fetch_model(MOBL_MODEL, progress=False), osim, variant.muscle_edits)
        # threads suffice: every run is its own OpenSim process
        with cf.ThreadPoolExecutor(max_workers=max_workers) as pool:
            runs = run_many(osim, dataset.times, dataset.activations.values, list(dataset.activations.muscles),
                            sets=first, runs_dir=runs_dir / variant.name, initial_state=_initial_state(variant),
                            settings=variant.settings, timeout=timeout, executor=pool, progress=progress,
                            desc=variant.name, opensim_log=runs_dir / "opensim.log")
    return dict(zip(first, runs, strict=True))


def compare_runs(reference: np.ndarray, other: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and max absolute difference over time of two trajectories.

    Args:
        reference, other: (..., T, D) joint angles, rad.
    Returns:
        (mean, max), each (..., D) rad; NaN where ``other`` has no finite sample.
    """
    diff = np.abs(np.asarray(other, float) - np.asarray(reference, float))
    with warnings.catch_warnings():  # an all-NaN slice (a run missing) is NaN, as wanted
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(diff, axis=-2), np.nanmax(diff, axis=-2)


def _dof_columns(dataset: Dataset, dofs: tuple[str, ...] = DOFS) -> list[int]:
    return [dataset.coordinate_names.index(d) for d in dofs]


def spread_table(dataset: Dataset, variants: tuple[Variant, ...], runs: dict[str, dict[int, OpenSimRun]],
                 dofs: tuple[str, ...] = DOFS) -> dict[str, np.ndarray]:
    """Every variant's self-spread on the test sets, as the arrays of ``self_spread.npz``.

    A failed run (status not ``"ok"``) counts as not run: NaN, with its status kept.
    """
    sets, cols = list(dataset.test), _dof_columns(dataset, dofs)
    shape = (len(variants), len(sets))
    traj = np.full((*shape, len(dataset.times), len(dofs)), np.nan, np.float32)
    status = np.full(shape, "not run", dtype=object)
    wall = np.full(shape, np.nan)
    for v, variant in enumerate(variants):
        for s, i in enumerate(sets):
            run = runs.get(variant.name, {}).get(i)
            if run is None:
                continue
            status[v, s], wall[v, s] = run.status, run.wall_time
            if run.ok:
                traj[v, s] = run.coordinates[:, [run.coordinate_names.index(d) for d in dofs]]
    spread, spread_max = compare_runs(dataset.coordinates[sets][:, :, cols], traj)
    return {"variants": np.array([v.name for v in variants]),
            "descriptions": np.array([v.description for v in variants]),
            "accuracy": np.array([v.settings.accuracy for v in variants]),
            "muscle_edits": np.array([json.dumps(v.muscle_edits) for v in variants]),
            "initial_offsets": np.array([json.dumps(dict(v.initial_offsets)) for v in variants]),
            "sets": np.array(sets), "dofs": np.array(dofs), "spread": spread, "spread_max": spread_max,
            "trajectories": traj, "status": status.astype(str), "wall_time": wall}


def mujoco_errors(data_dir: Path, sets: np.ndarray, dofs: tuple[str, ...] = DOFS, key: str = "err_fitted"
                  ) -> np.ndarray:
    """MuJoCo's per-set mean absolute error (S, D) rad from ``results/results.npz`` (``key``)."""
    with np.load(data_dir / "results" / "results.npz") as z:
        rows = [list(z["test"]).index(i) for i in sets]
        cols = [list(z["dofs"]).index(d) for d in dofs]
        return z[key][np.ix_(rows, cols)]


def _perturbed_initial_states(exp, model, sets: list[int], offsets: dict[str, float]) -> np.ndarray:
    """MuJoCo initial states (B, nstate) of ``sets`` as :func:`o2m.paper.load_experiment` builds
    them, with ``offsets`` (rad) added to the named coordinates."""
    from o2m.mj.simulate import initial_state

    ds = exp.dataset
    states = []
    for i in sets:
        coords = dict(zip(ds.coordinate_names, ds.coordinates[i, 0], strict=True))
        for name, offset in offsets.items():
            coords[name] += offset
        states.append(initial_state(model, coords, speeds=dict(zip(ds.coordinate_names, ds.speeds[i, 0], strict=True)),
                                    activations=dict(zip(ds.muscle_names, ds.opensim_activations[i, 0], strict=True))))
    return np.stack(states)


def mujoco_self_spread(exp, model, sets: list[int], variants: tuple[Variant, ...]) -> dict[str, np.ndarray]:
    """The same question asked of a MuJoCo model: its own spread under the variants' changes.

    ``exp`` is :func:`o2m.paper.load_experiment`'s, ``model`` e.g. the fitted model. A variant's
    ``max_isometric_force`` factor on every muscle scales each muscle actuator's force (gain and
    bias parameter 2, so MuJoCo's active and passive muscle force; the fitted tendon springs are
    left as they are); its ``initial_offsets`` move the initial coordinates; variants with other
    changes (integrator, one muscle's fibre) are skipped. Returns ``mujoco_variants`` (V',) and
    ``mujoco_spread`` (V', S, D) rad: mean absolute difference from the unchanged model's run.
    """
    from o2m.mj.simulate import rollout

    base = rollout(model, exp.init[sets], exp.controls[sets], joint_names=exp.dofs).coordinates
    names, spreads = [], []
    for v in variants:
        scale = [f for m, prop, f, added in v.muscle_edits if m == "*" and prop == "max_isometric_force" and not added]
        if v.settings != IntegratorSettings() or len(scale) != len(v.muscle_edits) or not (scale or v.initial_offsets):
            continue
        changed = copy.deepcopy(model)
        if scale:
            muscles = changed.actuator_gaintype == mujoco.mjtGain.mjGAIN_MUSCLE
            changed.actuator_gainprm[muscles, 2] *= scale[0]
            changed.actuator_biasprm[muscles, 2] *= scale[0]
        init = _perturbed_initial_states(exp, changed, sets, dict(v.initial_offsets)) if v.initial_offsets else \
            exp.init[sets]
        run = rollout(changed, init, exp.controls[sets], joint_names=exp.dofs).coordinates
        names.append(v.name)
        spreads.append(compare_runs(base, run)[0])
    return {"mujoco_variants": np.array(names), "mujoco_spread": np.array(spreads)}


def write_spread(path: Path, table: dict[str, np.ndarray], meta: dict) -> None:
    """Write :func:`spread_table`'s arrays and ``meta`` (JSON) to ``path`` (``.npz``)."""
    np.savez_compressed(path, **table, meta=json.dumps(meta))


def load_spread(path: Path) -> dict[str, np.ndarray]:
    """The arrays of a ``self_spread.npz`` (``meta`` parsed)."""
    with np.load(path) as z:
        out = {k: z[k] for k in z.files}
    out["meta"] = json.loads(str(out["meta"]))
    return out


def _row(label: str, n: int, values: np.ndarray) -> str:
    """A table row in mrad: the values per joint and their mean."""
    return f"| {label} | {n} | " + " | ".join(f"{1e3 * x:.2f}" for x in values) + f" | {1e3 * values.mean():.2f} |"


def print_table(table: dict[str, np.ndarray], large: float = 0.002) -> None:
    """Per joint (mrad): MuJoCo's fitted error, each OpenSim variant's spread and largest
    difference (mean and max over the sets it ran on), the fitted MuJoCo model's own spread;
    then per set the elbow, ``*`` where an OpenSim variant's largest elbow difference exceeds
    ``large`` rad."""
    dofs, mj = list(table["dofs"]), table["mujoco_fitted"]
    print("| mean over test sets, mrad | sets | " + " | ".join(dofs) + " | mean |")
    print("|---|---|" + "---|" * (len(dofs) + 1))
    print(_row("MuJoCo fitted vs OpenSim", len(mj), mj.mean(axis=0)))
    for v in range(len(table["variants"])):
        ran = np.isfinite(table["spread"][v]).all(axis=1)
        if ran.any():
            print(_row(f"OpenSim, {table['descriptions'][v]}", ran.sum(), table["spread"][v][ran].mean(axis=0)))
            print(_row("... its largest difference, any set", ran.sum(), table["spread_max"][v][ran].max(axis=0)))
        if 0 < ran.sum() < len(ran):
            print(_row(f"... MuJoCo fitted vs OpenSim on those {ran.sum()} sets", ran.sum(), mj[ran].mean(axis=0)))
    for name, spread in zip(table.get("mujoco_variants", []), table.get("mujoco_spread", []), strict=True):
        print(_row(f"MuJoCo fitted against itself, {name}", len(spread), spread.mean(axis=0)))
    elbow = dofs.index("elbow_flexion")
    print("\nelbow_flexion per set, mrad: MuJoCo fitted error | mean (max) difference of "
          + " | ".join(table["variants"]))
    for s, i in enumerate(table["sets"]):
        cells = " | ".join(f"{1e3 * table['spread'][v, s, elbow]:.2f} ({1e3 * table['spread_max'][v, s, elbow]:.2f})"
                           for v in range(len(table["variants"])))
        flag = " *" if np.nanmax(table["spread_max"][:, s, elbow], initial=0) > large else ""
        print(f"set {i:3d} | {1e3 * mj[s, elbow]:.1f} | {cells}{flag}")


def _rank_agreement(table: dict[str, np.ndarray]) -> None:
    """Spearman rank of each variant's per-set spread with MuJoCo's per-set fitted error."""
    from scipy.stats import spearmanr

    mj = table["mujoco_fitted"]
    elbow = list(table["dofs"]).index("elbow_flexion")
    for v, name in enumerate(table["variants"]):
        ran = np.isfinite(table["spread"][v]).all(axis=1)
        if ran.sum() < 5:
            continue
        rho_all = spearmanr(table["spread"][v][ran].mean(axis=1), mj[ran].mean(axis=1))[0]
        rho_elbow = spearmanr(table["spread"][v][ran, elbow], mj[ran, elbow])[0]
        print(f"{name}: Spearman with MuJoCo's per-set error over {ran.sum()} sets: "
              f"mean over joints {rho_all:.2f}, elbow {rho_elbow:.2f}")


def _collect_runs(args: argparse.Namespace, dataset: Dataset, chosen: tuple[Variant, ...]
                  ) -> dict[str, dict[int, OpenSimRun]]:
    """Run the chosen variants, or with ``--no-run`` read the runs kept under ``--runs``."""
    runs = {}
    for variant in chosen:
        if args.no_run:
            folder = args.runs / variant.name
            runs[variant.name] = {int(p.stem[4:]): OpenSimRun.from_npz(p) for p in sorted(folder.glob("set_*.npz"))}
        else:
            runs[variant.name] = run_variant(variant, dataset, args.runs, max_workers=args.max_workers,
                                             timeout=args.timeout)
    return runs


def _mujoco_side(args: argparse.Namespace, sets: list[int], chosen: tuple[Variant, ...]) -> dict[str, np.ndarray]:
    """:func:`mujoco_self_spread` of ``--mujoco-model`` (nothing when the file is missing)."""
    from o2m.paper.pipeline import load_experiment

    if not args.mujoco_model.exists():
        print(f"{args.mujoco_model} not found: no MuJoCo self-spread (run `python -m o2m paper` first)")
        return {}
    exp = load_experiment(args.data, args.mujoco_model.parent)
    return mujoco_self_spread(exp, mujoco.MjModel.from_xml_path(str(args.mujoco_model)), sets, chosen)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m o2m.paper.self_spread", description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA_DIR)
    parser.add_argument("--runs", type=Path, default=Path("out/self_spread"), help="finished runs, kept")
    parser.add_argument("--variants", nargs="*", default=[v.name for v in VARIANTS])
    parser.add_argument("--max-workers", type=int, default=1)
    parser.add_argument("--timeout", type=float, default=1200.0, help="wall-clock seconds per run")
    parser.add_argument("--no-run", action="store_true", help="only tabulate the runs already kept")
    parser.add_argument("--mujoco-model", type=Path, default=Path(FITTED_XML), help="the fitted MJCF")
    args = parser.parse_args(argv)
    dataset = load_dataset(args.data)
    chosen = tuple(v for v in VARIANTS if v.name in args.variants)
    table = spread_table(dataset, chosen, _collect_runs(args, dataset, chosen))
    table["mujoco_fitted"] = mujoco_errors(args.data, table["sets"])
    table.update(_mujoco_side(args, list(dataset.test), chosen))
    osim = models.fetch_model(MOBL_MODEL, progress=False)
    meta = {"model": models.bundled_model(MOBL_MODEL).osim, "model_sha256": models.sha256_of(osim),
            "reference": dataset.meta.get("integrator"), "initial_state": MOBL_INITIAL_STATE,
            "variants": [{**replace(v, settings=None).__dict__, "settings": v.settings.__dict__} for v in chosen],
            "mujoco_model": str(args.mujoco_model),
            "command": "python -m o2m.paper.self_spread " + " ".join(sys.argv[1:] if argv is None else argv)}
    write_spread(args.data / "self_spread.npz", table, meta)
    print_table(table)
    _rank_agreement(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
