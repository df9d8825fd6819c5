"""An ellipsoid's MuJoCo stand-in, sphere or cylinder, chosen per path by measured error.

MuJoCo wraps tendons round spheres and cylinders only. A WrapEllipsoid becomes, per path, one of
two stand-ins (:func:`standins`): the sphere of its mean semi-axis, or the infinite cylinder along
its long axis whose radius is the mean of the other two. The converter starts from the sphere
unless the long axis exceeds :data:`ELONGATED` times the next one; the wrap fit
(:mod:`o2m.convert.wrapfit`) then fits each path both ways (:func:`with_kinds`) and keeps the other
kind only where it is clearly nearer OpenSim over the fit's poses and no further on any of its
pose sets, a set of validation poses (lengths only) among them (:func:`best_with_kinds`). No shape wins
everywhere: a cylinder has no ends, so near an elongated ellipsoid's ends, where its cross-section
shrinks, it is too thick and contains path points that lie outside the ellipsoid (a neck and
shoulder model's serratus anterior over its thorax ellipsoid: MuJoCo does not wrap a segment with
an end inside the geom), while a sphere misses the ellipsoid's length where a path runs along
it. The report's error of each ellipsoid is then the worst length error of its paths against
OpenSim at the fit's poses (:func:`record_errors`).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import mujoco
import numpy as np
from lxml import etree

from o2m.convert.wrap_choice import NO_WRAP, PathVariant, best_variant, variant_errors

#: The converter's start: a cylinder where the long semi-axis exceeds this times the next one.
ELONGATED = 1.5
#: A swapped stand-in may be this much (fraction) further from OpenSim than the best variant
#: without on one pose set, where neither acts at most poses (a neck and shoulder model's
#: pectoralis major over its thorax ellipsoid as a sphere: 94 against 334 mm² on the fitting
#: poses, 117.85 against 117.70 mm² on the check poses).
SET_TOLERANCE = 0.01
#: ... and must be nearer OpenSim by this fraction of the objective over all poses: a swap that
#: changes a few poses a little is a guess about the poses between (the neck and shoulder
#: model's Rhomboideus_S as a sphere: 3.7 % lower over the fit's poses, 20.3 % off at one of
#: 200 others where the cylinder is within 16 %).
SWAP_GAIN = 0.1
#: At most this many ellipsoid geoms of one variant get every combination of kinds (2^n
#: variants); beyond, all of them one way or all the other.
MAX_SWAPPED = 2


def standins(dimensions: Sequence[float]) -> dict[str, tuple[list[float], np.ndarray, float, str]]:
    """Both stand-ins of an ellipsoid of semi-axes ``dimensions`` (m, its own frame): kind ->
    (MuJoCo size, rotation (3, 3) from the ellipsoid's frame to the geom's, the largest gap (m)
    between the two surfaces along any of the ellipsoid's axes, a description)."""
    d = np.asarray(dimensions, dtype=float)
    order = np.argsort(d)
    r_sph = float(d.mean())
    r_cyl = float((d[order[0]] + d[order[1]]) / 2)
    # a cylinder keeps its radius beyond the ellipsoid's ends, where the ellipsoid's section
    # shrinks to a point: the gap there is its radius
    cyl_gap = max(r_cyl, float(np.max(np.abs(d[order[:2]] - r_cyl))))
    return {
        "sphere": ([r_sph, 0.0, 0.0], np.eye(3), float(np.max(np.abs(d - r_sph))),
                   f"a sphere of radius {r_sph:.4g} m"),
        "cylinder": ([r_cyl, float(d[order[2]]), 0.0], _rotation_taking_z_to(np.eye(3)[order[2]]), cyl_gap,
                     f"a cylinder of radius {r_cyl:.4g} m along its {d[order[2]]:.4g} m semi-axis"),
    }


def first_kind(dimensions: Sequence[float]) -> str:
    """The stand-in the converter starts from (the wrap fit may swap it): "cylinder" for an
    elongated ellipsoid (:data:`ELONGATED`), else "sphere"."""
    d = np.sort(np.asarray(dimensions, dtype=float))
    return "cylinder" if d[2] > ELONGATED * d[1] else "sphere"


def _rotation_taking_z_to(axis: np.ndarray) -> np.ndarray:
    """A rotation matrix (3, 3) whose third column is the unit vector ``axis``."""
    z = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def with_kinds(variants: Sequence[PathVariant], geoms: Sequence[Any]) -> list[PathVariant]:
    """``variants`` of a tendon, each followed by its copies with the stand-in kind of some of its
    kept ellipsoid geoms swapped (every subset, up to :data:`MAX_SWAPPED` geoms; else all
    swapped), given the tendon's :class:`~o2m.convert.wraps.PathGeom` s (those with an
    ``alternative``)."""
    by_geom = {g.geom: g for g in geoms if g.alternative}
    out = []
    for v in variants:
        out.append(v)
        kept = [g for g in by_geom if g not in v.dropped]
        if not kept or v.label == NO_WRAP:
            continue
        subsets = ([c for n in range(1, len(kept) + 1) for c in itertools.combinations(kept, n)]
                   if len(kept) <= MAX_SWAPPED else [tuple(kept)])
        for sub in subsets:
            names = ", ".join(f"{by_geom[g].source} {by_geom[g].alternative['kind']}" for g in sub)
            out.append(replace(v, label=f"{v.label} ({names})", swapped=frozenset(sub)))
    return out


def best_with_kinds(fits: list[Any]) -> Any:
    """Of one tendon's fitted variants (:class:`o2m.convert.wrapfit.PathFit` s), the one
    :func:`~o2m.convert.wrap_choice.best_variant` keeps; one with a swapped stand-in only where,
    against the best of those without, it is clearly nearer OpenSim over all its poses and no
    further on any of its pose sets, the validation poses among them (:func:`_clearly_better`):
    a choice among more variants over few poses otherwise keeps one that fits them by chance
    (MoBL-ARMS's PECM1, quick: its PEC1hh ellipsoid as a cylinder, 23.2 % over the fit's 70 poses
    against 26.7 % straight, was 26.9 % over 100 other poses against 15.6 %)."""
    best = best_variant(fits)
    plain = [f for f in fits if not f.swapped]
    if best.swapped and plain:
        base = best_variant(plain)
        # exact: within OpenSim's noise already; a swap may not bring flips the plain one has not
        if base.exact or best.flips > base.flips or not _clearly_better(best, base):
            best = base
    if len(fits) > 1:
        best.variants = variant_errors(fits)
    return best


def _clearly_better(a: Any, b: Any) -> bool:
    """Fit ``a`` has an objective (mm²) at least :data:`SWAP_GAIN` lower than ``b``'s over all
    poses (fitting, check and validation), on each set at most :data:`SET_TOLERANCE` above it,
    and no larger worst length error on any."""
    sets = [(a.after, b.after), (a.check_after, b.check_after)]
    if getattr(a, "valid_after", None) and getattr(b, "valid_after", None):
        sets.append((a.valid_after, b.valid_after))
    total = [sum(x["objective"] * x["poses"] for x, _ in sets), sum(y["objective"] * y["poses"] for _, y in sets)]
    return total[0] < (1 - SWAP_GAIN) * total[1] and all(x["objective"] <= (1 + SET_TOLERANCE) * y["objective"]
                                                         and x["len_max_pct"] <= y["len_max_pct"] for x, y in sets)


def swapped_geometry(geoms: Sequence[Any], swapped: Sequence[str]) -> dict[str, dict[str, Any]]:
    """Geom name -> its alternative stand-in (``kind``, ``size``, ``quat``, body frame) for the
    geoms ``swapped``."""
    alt = {g.geom: g.alternative for g in geoms if g.alternative}
    return {g: alt[g] for g in swapped}


def swap_kinds_xml(xml: str, swapped: dict[str, dict[str, Any]]) -> str:
    """MJCF text ``xml`` with each geom of ``swapped`` made its alternative stand-in."""
    if not swapped:
        return xml
    root = etree.fromstring(xml.encode())
    for el in root.iter("geom"):
        alt = swapped.get(el.get("name"))
        if alt is not None:
            el.set("type", alt["kind"])
            el.set("size", " ".join(repr(float(v)) for v in alt["size"][:2 if alt["kind"] == "cylinder" else 1]))
            el.set("quat", " ".join(repr(float(v)) for v in alt["quat"]))
    return etree.tostring(root, encoding="unicode")


def apply_kinds(spec: mujoco.MjSpec, fits: Sequence[Any], geom_exact: dict) -> None:
    """Make each geom a kept variant swapped its alternative stand-in in ``spec`` and in the
    exact-value table (before the fitted positions and radii are written)."""
    for f in fits:
        for name, alt in (f.swapped or {}).items():
            g = spec.geom(name)
            cyl = alt["kind"] == "cylinder"
            g.type = mujoco.mjtGeom.mjGEOM_CYLINDER if cyl else mujoco.mjtGeom.mjGEOM_SPHERE
            g.size = np.array(alt["size"], dtype=float)
            g.quat = np.array(alt["quat"], dtype=float)
            ex = geom_exact.setdefault(("geom", name), {})
            ex["quat"] = np.array(alt["quat"], dtype=float)
            ex["size"] = np.array(alt["size"][:2 if cyl else 1], dtype=float)


def record_errors(approximations: list, fits: Sequence[Any], geoms: Sequence[Any]) -> None:
    """Give each WrapEllipsoid approximation the worst length error (%) against OpenSim, at the
    wrap fit's fitting and check poses (OpenSim's own failures left out), of the paths over it
    (also where the fit left it out), and the stand-in each path kept; its geometric gap (m)
    stays in the description."""
    kept = {f.tendon: f for f in fits}
    for a in approximations:
        users = [g for g in geoms if g.source == a.name and g.tendon in kept]
        if a.element != "WrapEllipsoid" or not users:
            continue
        worst, kinds = 0.0, {}
        for g in users:
            f = kept[g.tendon]
            kind = "left out" if g.geom in f.dropped else (f.swapped or {}).get(g.geom, {}).get("kind", g.kind_mj)
            kinds.setdefault(kind, []).append(g.tendon)
            worst = max(worst, f.after["len_max_pct"], f.check_after["len_max_pct"])
        per = "; ".join(f"{k}: {', '.join(ts)}" for k, ts in sorted(kinds.items()))
        a.what = f"{a.what} (surfaces up to {a.max_error:.3g} m apart); per path after the wrap fit ({per})"
        a.max_error, a.units = worst, "%"
        a.detail = "worst length error of its paths against OpenSim at the wrap fit's and check poses"


__all__ = ["ELONGATED", "SET_TOLERANCE", "SWAP_GAIN", "apply_kinds", "best_with_kinds", "first_kind", "record_errors",
           "standins", "swap_kinds_xml", "swapped_geometry", "with_kinds"]
