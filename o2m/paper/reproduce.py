"""The paper's whole step order, in one place: references, conversion and fits, speed, figures.

``python -m o2m paper`` only calls :func:`reproduce` and prints :func:`format_summary`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from o2m.osim import runtime
from o2m.paper.dataset import load_dataset, make_dataset
from o2m.paper.figures import make_figures
from o2m.paper.pipeline import FULL, QUICK, run_paper
from o2m.paper.speed import measure_speed

__all__ = ["PaperRun", "STAGES", "format_summary", "reproduce"]

#: The stages of both pipelines, as the summary names them, with their column headings.
STAGES = {"converted": "converted", "paper_fitted": "paper CMA", "paper_corrected": "paper corr",
          "force_fitted": "o2m forces", "fibres": "o2m fibres", "fitted": "o2m CMA", "corrected": "o2m corr",
          "schutte": "o2m Schutte", "schutte_corrected": "Schutte corr"}


@dataclass
class PaperRun:
    """What :func:`reproduce` measured: the pipeline's summary, the speed record, the figure files."""

    summary: dict
    speed: dict
    figures: list[Path]
    figure_dir: Path
    opensim_log: Path | None = None


def reproduce(
    data: str | os.PathLike = "data/mobl_arms",
    out: str | os.PathLike = "out",
    figures: str | os.PathLike = "figures",
    *,
    quick: bool = False,
    regenerate_opensim: bool = False,
    refit: bool = False,
    executor=None,
    n_sets: int = 100,
    seed: int = 2020,
    timeout: float = 600.0,
    log: Callable[[str], None] = print,
    opensim_log: str | os.PathLike | None = None,
) -> PaperRun:
    """Reproduce the paper: (1) the OpenSim references (stored in ``data``, or regenerated),
    (2) conversion, muscle force fit, CMA-ES and corrective controls (:func:`run_paper`),
    (3) the speed of both simulators, (4) the figures.

    ``quick`` uses small budgets and writes under ``out/quick/``; otherwise results go to
    ``data/results`` and figures to ``figures``. The speed measured here replaces the stored
    ``speed.json`` only in quick mode or with ``refit``; otherwise it goes to ``out/speed.json``.
    ``executor`` (a concurrent.futures executor, e.g. Dask's) runs the OpenSim simulations and
    CMA-ES candidates. ``log`` gets one line per step. OpenSim's log goes to ``opensim_log``
    (default ``out/opensim.log``, rewritten on every run), not to the terminal.
    """
    data, out = Path(data), Path(out)
    log_file = Path(opensim_log) if opensim_log is not None else out / "opensim.log"
    log_file.unlink(missing_ok=True)
    with runtime.opensim_log(log_file):
        run = _reproduce(data, out, Path(figures), quick=quick, regenerate_opensim=regenerate_opensim, refit=refit,
                         executor=executor, n_sets=n_sets, seed=seed, timeout=timeout, log=log, log_file=log_file)
    run.opensim_log = log_file
    return run


def _reproduce(data: Path, out: Path, figures: Path, *, quick: bool, regenerate_opensim: bool, refit: bool,
               executor, n_sets: int, seed: int, timeout: float, log: Callable[[str], None],
               log_file: Path) -> PaperRun:
    """The steps of :func:`reproduce`, with OpenSim's log already redirected."""
    if regenerate_opensim:
        if quick:
            data = out / "quick-data"
        log(f"[1/4] regenerating OpenSim references into {data} ({4 if quick else n_sets} sets)")
        make_dataset(data, n_sets=4 if quick else n_sets, seed=seed, timeout=timeout, executor=executor,
                     opensim_log=log_file)
    else:
        log(f"[1/4] using the stored OpenSim references in {data}")
    ds = load_dataset(data)
    log(
        f"      {len(ds.ok)} sets, {int(ds.ok.sum())} succeeded in OpenSim, failures: "
        + ("; ".join(f"set {i} {st}: {why[:80]}" for i, st, why in ds.failures()) or "none")
    )
    results = out / "quick" / "results" if quick else data / "results"
    figure_dir = out / "quick" / "figures" if quick else Path(figures)
    log(f"[2/4] converting, fitting parameters ({'quick' if quick else 'full'} mode) and corrective controls")
    summary = run_paper(
        data,
        settings=QUICK if quick else FULL,
        model_dir=out / "paper",
        results_dir=results,
        refit=refit or quick,
        executor=executor,
    )
    log("[3/4] timing one 1-s simulation in OpenSim and in MuJoCo")
    speed = measure_speed(str(data), n_sets=1 if quick else 5, model_dir=str(out / "paper"))
    # A timing differs on every run: it replaces the stored one (and its figure) only with the
    # fits, so rerunning the main job leaves the tracked files alone unless a result changed.
    stored = results.parent / "speed.json"
    speed_file = stored if quick or refit or not stored.exists() else out / "speed.json"
    speed_file.parent.mkdir(parents=True, exist_ok=True)
    speed_file.write_text(json.dumps(speed, indent=1) + "\n")
    log(f"[4/4] figures -> {figure_dir}")
    written = make_figures(results, figure_dir, speed_file=stored)
    return PaperRun(summary, speed, written, figure_dir)


def _stage_table(per_joint: dict[str, dict[str, float]], stages: dict[str, str]) -> list[str]:
    """Rows of DoF x stage errors (rad), with the mean over DoFs last."""
    rows = [f"  {'DoF':15s}" + "".join(f"{h:>13s}" for h in stages.values())]
    for d, v in per_joint.items():
        rows.append(f"  {d:15s}" + "".join(f"{v[k]:13.4f}" for k in stages))
    mean = {k: sum(v[k] for v in per_joint.values()) / len(per_joint) for k in stages}
    rows.append(f"  {'mean':15s}" + "".join(f"{mean[k]:13.4f}" for k in stages))
    return rows


def format_summary(run: PaperRun) -> str:
    """The measured numbers of a :func:`reproduce` run, as the command line prints them."""
    s, sp = run.summary, run.speed
    lines: list[str] = []
    e = s["mean_error_rad"]
    lines.append(
        f"Mean absolute joint error on {s['n_test']} test sets (rad): converted {e['converted']:.4f}; "
        f"the paper's pipeline: CMA-ES fitted {e['paper_fitted']:.4f}, with corrections {e['paper_corrected']:.4f}; "
        f"o2m's: muscle forces fitted {e['force_fitted']:.4f}, passive fibres {e['fibres']:.4f}, "
        f"CMA-ES fitted {e['fitted']:.4f}, "
        f"with corrections {e['corrected']:.4f}"
        + (f"; OpenSim's own muscles in MuJoCo (o2m.schutte, no fit) {e['schutte']:.4f}, with corrections "
           f"{e['schutte_corrected']:.4f}" if "schutte_corrected" in e else "")
    )
    lines += _stage_table(s["per_joint_error_rad"], {k: v for k, v in STAGES.items() if k in e})
    if s.get("paper_corrected_sets", s["n_test"]) < s["n_test"]:
        lines.append(f"  (paper corr: on the first {s['paper_corrected_sets']} test sets only, where o2m's "
                     f"corrections reach {s['corrected_on_paper_sets']:.4f} rad with mean size "
                     f"{s['mean_abs_correction_on_paper_sets']:.4f})")
    fresh = s.get("fresh_sets", {})
    if fresh.get("n"):
        lines.append(f"On {fresh['n']} fresh sets (another seed, never fitted on), rad:")
        lines += _stage_table(fresh["per_joint_error_rad"], {k: v for k, v in STAGES.items()
                                                             if k in fresh["mean_error_rad"]})
    uncorrected = [k for k in STAGES if "corrected" not in k]
    lines.append("Mean over DoFs and sets, per split (rad):")
    lines.append(f"  {'split':15s}" + "".join(f"{STAGES[k]:>13s}" for k in uncorrected))
    for split, v in s.get("split_error_rad", {}).items():
        lines.append(f"  {split:15s}" + "".join(f"{v[k]:13.4f}" if k in v else f"{'':13s}" for k in uncorrected))
    mf = s["muscle_forces"]
    lines.append(
        f"Muscle force fit: RMS error {mf['rms_held_out_start']:.2f} -> {mf['rms_held_out']:.2f} % of max isometric "
        f"force on held-out states ({mf['kept']} of {mf['muscles']} muscles changed)"
    )
    schutte = (f", o2m's with OpenSim's muscles {s['mean_abs_correction_schutte']:.4f}"
               if "mean_abs_correction_schutte" in s else "")
    lines.append(f"Mean absolute correction: paper's pipeline {s['mean_abs_correction_paper']:.4f}, "
                 f"o2m's {s['mean_abs_correction']:.4f}{schutte}")
    fresh_sizes = fresh.get("mean_abs_correction", {})
    if fresh_sizes:
        schutte = (f", o2m's with OpenSim's muscles {fresh_sizes['schutte_corrected']:.4f}"
                   if "schutte_corrected" in fresh_sizes else "")
        lines.append(f"  on the fresh sets: paper's pipeline {fresh_sizes['paper_corrected']:.4f}, "
                     f"o2m's {fresh_sizes['corrected']:.4f}{schutte}")
    for label, key in (("CMA-ES, paper's pipeline (best training candidate)", "paper_fit"),
                       ("CMA-ES, o2m's pipeline (early-stopped on validation)", "fit")):
        f = s[key]
        lines.append(
            f"{label}: training cost {f['cost0']:.4g} -> {f['cost']:.4g} (best seen {f['best_training_cost']:.4g}), "
            f"validation cost {f['validation_cost0']:.4g} -> {f['validation_cost']:.4g}; {f['generations']} "
            f"generations, {f['evaluations']} candidates, {f['wall_time_s']:.0f} s"
        )
    lines.append(f"Fitted model: {s['fitted_xml']}")
    if s.get("passive_fibres"):
        pf = s["passive_fibres"]
        lines.append(f"  with its passive fibres ({len(pf['muscles'])} muscles, the o2m.fibre plugin): {pf['xml']}")
    if s.get("schutte"):
        lines.append(f"With OpenSim's own muscles (the o2m.schutte plugin, no fit): {s['schutte']['xml']}")
    lines.append(
        f"Speed: OpenSim {sp['opensim_median_s']:.2f} s, MuJoCo {sp['mujoco_median_s']:.4f} s per 1-s "
        f"simulation: {sp['ratio']:.0f}x; batched rollouts {sp['rollout_per_s']:.0f} simulations/s"
    )
    lines.append(f"{len(run.figures)} figure files in {run.figure_dir}")
    if run.opensim_log is not None:
        lines.append(f"OpenSim's log: {run.opensim_log}")
    return "\n".join(lines)
