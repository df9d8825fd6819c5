"""The paper's figures, drawn from stored results (no simulation here).

:func:`make_figures` reads ``<results>/results.npz`` and ``summary.json`` (from
:func:`o2m.paper.run_paper`) and ``speed.json`` (from :mod:`o2m.speed`) and writes PNG and PDF
files to ``figures/``:

1. ``joint_errors``: mean absolute error per joint over the test sets (rad): converted; the paper's
   pipeline (CMA-ES fit of the converted model, then corrective controls); o2m's (muscle force fit,
   CMA-ES fit, corrective controls).
2. ``corrections_boxplot``: per muscle, the mean absolute activation correction over the test sets.
3. ``speed``: time of one 1-s simulation in OpenSim and in MuJoCo, and their ratio.
4. ``overlay``: joint trajectories of a few test sets, OpenSim against MuJoCo.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

__all__ = ["correction_boxplot", "joint_error_bars", "make_figures", "overlay", "passive_forces", "speed_bars"]


def _plt():
    # No matplotlib.use("Agg") here: matplotlib falls back to Agg by itself without a display,
    # and switching backends would turn a notebook's inline figures off.
    import matplotlib.pyplot as plt

    return plt


def joint_error_bars(dofs: list[str], errors: dict[str, np.ndarray]):
    """Grouped bars of the mean absolute error per joint (rad); ``errors`` maps a label to (n_sets, n_dofs)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(10, 3.8))
    width = 0.8 / max(1, len(errors))
    x = np.arange(len(dofs))
    for k, (label, e) in enumerate(errors.items()):
        mean = np.nanmean(e, axis=0)
        ax.bar(x + (k - (len(errors) - 1) / 2) * width, mean, width, label=f"{label} (mean {np.nanmean(e):.3f})")
    ax.set_xticks(x, dofs, rotation=20)
    ax.set_ylabel("mean absolute error (rad)")
    ax.set_title("Joint error against OpenSim, test sets")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the bars, not over them
    fig.tight_layout()
    return fig


def correction_boxplot(muscles: list[str], correction_mae: np.ndarray):
    """Boxplot per muscle of the mean absolute correction over test sets; ``correction_mae`` (n_sets, n_muscles)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(11, 3.5))
    ax.boxplot(correction_mae, tick_labels=muscles, showfliers=True)
    ax.tick_params(axis="x", rotation=90, labelsize=7)
    ax.set_ylabel("mean |corrected - reference|")
    ax.set_title(f"Activation corrections per muscle (mean over all {np.mean(correction_mae):.3f})")
    fig.tight_layout()
    return fig


def speed_bars(speed: dict):
    """Bars of the median time of one 1-s simulation in each simulator (log scale), with the ratio;
    MuJoCo's bar (one thread) has its 10th-90th percentile over sets and repeats when measured."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(4.5, 3.5))
    labels = ["OpenSim", "MuJoCo\n(1 thread)"]
    values = [speed["opensim_median_s"], speed["mujoco_median_s"]]
    ax.bar(labels, values, color=["tab:gray", "tab:blue"])
    main = speed.get("models", {}).get("converted")
    if main:  # the spread of MuJoCo's time (OpenSim's sets are too few for one)
        spread = [[main["median_s"] - main["p10_s"]], [main["p90_s"] - main["median_s"]]]
        ax.errorbar([1], [main["median_s"]], yerr=spread, color="k", capsize=4)
    ax.set_yscale("log")
    for i, v in enumerate(values):
        ax.text(i, v, f"{v:.3g} s", ha="center", va="bottom")
    ax.set_ylabel("time of one 1-s simulation (s)")
    ax.set_title(f"MuJoCo is {speed['ratio']:.0f}x faster ({values[0]:.3g} s vs {values[1] * 1e3:.3g} ms)")
    fig.tight_layout()
    return fig


def overlay(times: np.ndarray, dofs: list[str], opensim: np.ndarray, mujoco: dict[str, np.ndarray], title: str = ""):
    """Joint trajectories (T, n_dofs) of one set: OpenSim against each labelled MuJoCo variant (rad)."""
    plt = _plt()
    fig, axes = plt.subplots(1, len(dofs), figsize=(3 * len(dofs), 3.4), sharex=True)
    for j, ax in enumerate(np.atleast_1d(axes)):
        ax.plot(times, opensim[:, j], "k", lw=2, label="OpenSim")
        for label, q in mujoco.items():
            ax.plot(times, q[:, j], lw=1, label=label)
        ax.set_title(dofs[j], fontsize=9)
        ax.set_xlabel("time (s)")
    np.atleast_1d(axes)[0].set_ylabel("angle (rad)")
    handles, labels = np.atleast_1d(axes)[0].get_legend_handles_labels()
    # below the panels, where it hides no curve
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 5), fontsize=7, frameon=False)
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0.04 * (1 + (len(labels) - 1) // 5), 1, 1))
    return fig


def passive_forces(times: np.ndarray, angle: np.ndarray, recorded: np.ndarray, forces: dict[str, np.ndarray],
                   title: str = "", angle_label: str = "elbow_flexion (rad)"):
    """One never-excited muscle's tendon force (N) over a set: OpenSim's recorded one against each
    labelled model of it, with a joint ``angle`` (rad) below; arrays of shape (T,)."""
    plt = _plt()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(6.4, 4.2), sharex=True, height_ratios=[2, 1])
    top.plot(times, recorded, "k", lw=2, label="OpenSim (recorded)")
    for label, f in forces.items():
        top.plot(times, f, lw=1.2, label=label)
    top.set_ylabel("tendon force (N)")
    top.legend(fontsize=7)
    top.set_title(title, fontsize=9)
    bottom.plot(times, angle, "k", lw=1)
    bottom.set_ylabel(angle_label, fontsize=8)
    bottom.set_xlabel("time (s)")
    fig.tight_layout()
    return fig


#: No creation date or software version in the files, so a rerun that changes no number changes no byte.
_REPRODUCIBLE = {"png": {"Software": None}, "pdf": {"CreationDate": None, "Producer": None, "Creator": None}}


def _save(fig, out: Path, name: str) -> list[Path]:
    paths = [out / f"{name}.png", out / f"{name}.pdf"]
    fig.savefig(paths[0], dpi=150, metadata=_REPRODUCIBLE["png"])
    fig.savefig(paths[1], metadata=_REPRODUCIBLE["pdf"])
    _plt().close(fig)
    return paths


def _order(label: str, stages: dict[str, str]) -> int:
    """Position of a (possibly annotated) stage label among ``stages``."""
    return next(k for k, name in enumerate(stages.values()) if label.startswith(name))


def make_figures(results_dir: str | os.PathLike[str], out_dir: str | os.PathLike[str] = "figures",
                 speed_file: str | os.PathLike[str] | None = None) -> list[Path]:
    """Write every figure that the stored results allow; returns the files written."""
    res_dir, out = Path(results_dir), Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    npz = res_dir / "results.npz"
    if npz.exists():
        with np.load(npz) as z:
            r = {k: z[k] for k in z.files}
        dofs, muscles = [str(d) for d in r["dofs"]], [str(m) for m in r["muscles"]]
        stages = {"converted": "converted", "paper_fitted": "paper: + CMA-ES fit",
                  "paper_corrected": "paper: + corrections", "forces": "o2m: muscle forces fitted",
                  "fibres": "o2m: + passive fibres", "fitted": "o2m: + CMA-ES fit", "corrected": "o2m: + corrections",
                  "schutte": "o2m: OpenSim's muscles, no fit",
                  "schutte_corrected": "o2m: OpenSim's muscles + corrections"}
        errors = {label: r[f"err_{key}"] for key, label in stages.items() if f"err_{key}" in r}
        if "paper_corrected_sets" in r and len(r["paper_corrected_sets"]) < len(r["test"]):
            n = len(r["paper_corrected_sets"])
            errors[f"{stages['paper_corrected']} (first {n} sets)"] = errors.pop(stages["paper_corrected"])
            errors = {label: errors[label] for label in sorted(errors, key=lambda x: _order(x, stages))}
        written += _save(joint_error_bars(dofs, errors), out, "joint_errors")
        written += _save(correction_boxplot(muscles, r["correction_mae"]), out, "corrections_boxplot")
        for k, s in enumerate(r["overlay_sets"]):
            curves = {label: r[f"overlay_{key}"][k] for key, label in stages.items()
                      if f"overlay_{key}" in r and k < len(r[f"overlay_{key}"])}
            written += _save(overlay(r["times"], dofs, r["overlay_opensim"][k], curves, f"test set {int(s)}"),
                             out, f"overlay_set{int(s):03d}")
    sp = Path(speed_file) if speed_file else res_dir.parent / "speed.json"
    if sp.exists():
        written += _save(speed_bars(json.loads(sp.read_text())), out, "speed")
    return written
