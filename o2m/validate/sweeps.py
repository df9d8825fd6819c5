"""Moment arms over one-coordinate sweeps: both models' curves, their plots, each path's worst pair.

A sweep moves one independent coordinate over its range, the others at their defaults, and
compares MuJoCo's ``-dL/dq`` with OpenSim's ``computeMomentArm`` (metres, or dimensionless about
a translational coordinate).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from o2m.mj.tendons import FD_STEP, mujoco_moment_arms
from o2m.osim.pair import ModelPair
from o2m.osim.runtime import TRANSLATIONAL, sample_bounds
from o2m.osim.spikes import DLDQ_CONSISTENCY

__all__ = ["format_moment_arm_report", "moment_arm_curve", "moment_arm_report", "moment_arm_sweeps",
           "plot_moment_arm_sweeps", "plot_moment_arms"]


def _moment_arm_curve(pair: ModelPair, muscle: str, coordinate: str, n: int, method: str
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    c = pair.coord(coordinate)
    obj = pair.force(muscle)
    tid = int(pair.tendon_ids[[nm for nm, _, _ in pair.matched].index(muscle)])
    lo, hi = sample_bounds(c)
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
    pair = ModelPair(osim_path, mjcf_path, assembly_accuracy)
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

    pair = ModelPair(osim_path, mjcf_path)
    linear = int(pair.coord(coordinate).getMotionType()) == TRANSLATIONAL
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
    pair = ModelPair(osim_path, mjcf_path, assembly_accuracy)
    spans = pair.spanned()
    names = [nm for nm, _, _ in pair.matched]
    out = []
    h = FD_STEP * 10
    for c in pair.indep:
        cname = pair.name(c)
        users = [i for i, nm in enumerate(names) if cname in spans.get(nm, set())]
        if not users:
            continue
        lo, hi = sample_bounds(c)
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
        linear = int(c.getMotionType()) == TRANSLATIONAL
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
    # No matplotlib.use("Agg"): matplotlib falls back to it without a display, and switching
    # backends would turn a notebook's inline figures off.
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


def moment_arm_report(osim_path: str | os.PathLike, mjcf_path: str | os.PathLike, pdf_path: str | os.PathLike, *,
                      n: int = 41, title: str = "moment arms (mm)") -> list[dict[str, Any]]:
    """Sweep every (path, spanned coordinate) pair, draw each path's worst pair into ``pdf_path``
    and return, per path, that pair's largest error in mm (dimensionless about a translation)
    against OpenSim's ``computeMomentArm`` and against OpenSim's ``-dL/dq``."""
    sweeps = moment_arm_sweeps(osim_path, mjcf_path, n=n)
    if not sweeps:  # no path spans a coordinate
        return []
    drawn = plot_moment_arm_sweeps(sweeps, pdf_path, title=title)
    scale = {True: 1.0, False: 1e3}
    return [{"muscle": r["muscle"], "coordinate": r["coordinate"],
             "max_error_mm": r["max_error"] * scale[r["linear"]],
             "max_error_vs_dldq_mm": r["max_error_vs_dldq"] * scale[r["linear"]]} for r in drawn]


def format_moment_arm_report(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """Lines of a :func:`moment_arm_report`: each path's worst pair, max |MuJoCo - OpenSim|."""
    return [f"  {r['muscle']:16s} {r['coordinate']:22s} vs computeMomentArm {r['max_error_mm']:8.3g}   "
            f"vs -dL/dq {r['max_error_vs_dldq_mm']:8.3g}" for r in rows]
