"""Which wraps of a split segment MuJoCo keeps: chosen by measured error.

:mod:`o2m.convert.wrap_split` splits a segment that several wraps share by via points, one wrap
per sub-segment. A via point forces the path through it also where OpenSim's path touches only
one of the wraps (then runs straight past the other); where OpenSim touches the two together at
few poses the split costs more than it gains (MoBL-ARMS's TMAJ: 27 % with TMAJ_LAThum alone, 63 %
split), where it touches them together often it gains (INFSP: 2.5 % split, 22 % alone). So the
tendon is built with every wrap OpenSim touches there, and each *variant* (a contiguous run of
those wraps, with the via points between them; the others left out; or none of them, the segment
straight) is fitted to OpenSim's
lengths and moment arms (:func:`o2m.convert.wrapfit.fit_paths`); of the variants whose worst
length error and moment-arm RMS are near the smallest, the one with the smallest objective over
all its poses is kept (:func:`best_variant`; :func:`drop_from_spec` removes the rest from the
model). Lengths are measured over every pose set of the fit, the validation poses it was not
fitted on among them (moment arms over the poses that have them): a
variant chosen on its few fitting poses alone is often one that fits them by chance (the wrapped
MoBL-ARMS's PECM1 kept both its wraps, 9.1 mm RMS on the validation poses, where PEC12hum alone
is 5.6 mm).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
from lxml import etree

#: Most variants fitted per tendon (the product of its split segments' runs; beyond it one
#: segment varies at a time, the others keeping every wrap).
MAX_VARIANTS = 8

#: A variant whose worst length error exceeds the smallest among its tendon's variants by more
#: than this factor plus :data:`VARIANT_PCT_MARGIN` (percentage points) is not kept, whatever its
#: objective (MoBL-ARMS's PECM1: PEC1hh alone had the smallest objective and a 40 % worst length;
#: with a margin of 1 point Rajagopal2016's gaslat_l kept a wrap that left it 1.62 % off, not 0.52).
VARIANT_PCT_FACTOR = 1.2
VARIANT_PCT_MARGIN = 0.1
#: ... nor one whose RMS moment-arm error at the fitting and check poses exceeds the smallest by
#: more than :data:`VARIANT_PCT_FACTOR` plus this (mm): the validation poses have lengths only,
#: and on them alone MoBL-ARMS's DELT1 went straight (6.3 % at worst there against its sphere's
#: 11.3 %), its moment arm about elv_angle 14 mm RMS off.
VARIANT_ARM_MARGIN_MM = 0.5
#: Of those, one whose tendon flips round a wrap between its fitting poses where OpenSim's path
#: does not (:mod:`o2m.convert.wrap_jumps`) gives way to one that does not flip, if that one's
#: objective is at most this factor larger: a length that jumps in a simulation costs more than
#: a slightly larger error at the poses.
FLIP_TRADE = 1.5
#: The label of a split segment's run that keeps none of its wraps.
NO_WRAP = "straight"


@dataclass(frozen=True)
class PathVariant:
    """One choice of wraps for a tendon: ``label`` names the kept wraps per split segment
    (OpenSim names), ``dropped`` the MuJoCo sites and geoms (side sites included) left out,
    ``swapped`` the ellipsoid geoms made their other stand-in (:mod:`o2m.convert.ellipsoid_standins`)."""

    label: str
    dropped: frozenset[str]
    swapped: frozenset[str] = frozenset()


def _segment_runs(rec: Any, geoms: dict[str, tuple[str, str]]) -> list[tuple[str, frozenset[str]]]:
    """The contiguous runs of the wraps of split ``rec`` (a :class:`~o2m.convert.wrap_split.WrapSplit`),
    longest first, then none (the segment straight): (label, MuJoCo names left out), given wrap
    name -> (geom, side site)."""
    n = len(rec.wraps)
    out = []
    for size in range(n, 0, -1):
        for i in range(n - size + 1):
            j = i + size - 1
            kept = rec.wraps[i:j + 1]
            drop = {name for w in rec.wraps if w not in kept for name in geoms.get(w, ("", "")) if name}
            drop |= {s for k, s in enumerate(rec.sites) if not i <= k < j}  # via k joins wraps k and k+1
            out.append(("+".join(kept), frozenset(drop)))
    # no wrap at all: where OpenSim's quadrant and finite-cylinder rules, which MuJoCo's side sites
    # cannot follow, switch its path between ways round, the straight segment can be nearer than
    # any wrap kept
    every = {name for w in rec.wraps for name in geoms.get(w, ("", "")) if name}
    out.append((NO_WRAP, frozenset(every | set(rec.sites))))
    return out


def split_variants(splits: Iterable[Any], path_geoms: Sequence[Any],
                   max_variants: int = MAX_VARIANTS) -> dict[str, list[PathVariant]]:
    """Tendon -> its variants (the first keeps every wrap) for the tendons with a split segment
    of two or more wraps; ``splits`` are :class:`~o2m.convert.wrap_split.WrapSplit` records,
    ``path_geoms`` :class:`~o2m.convert.wraps.PathGeom` s."""
    by_tendon: dict[str, list[Any]] = {}
    for rec in splits:
        if len(rec.wraps) > 1:
            by_tendon.setdefault(rec.path, []).append(rec)
    out: dict[str, list[PathVariant]] = {}
    for tendon, recs in by_tendon.items():
        geoms = {g.source: (g.geom, g.sidesite) for g in path_geoms if g.tendon == tendon}
        runs = [_segment_runs(r, geoms) for r in recs]
        if _count(runs) <= max_variants:
            combos = list(itertools.product(*runs))
        else:  # one segment at a time, the others whole
            combos = [tuple(runs[k][0] for k in range(len(runs)))]
            for k, options in enumerate(runs):
                combos += [tuple(opt if m == k else runs[m][0] for m in range(len(runs))) for opt in options[1:]]
        out[tendon] = [PathVariant(" | ".join(c[0] for c in combo), frozenset().union(*[c[1] for c in combo]))
                       for combo in combos]
    return out


def whole_and_straight(geoms: Sequence[Any]) -> list[PathVariant]:
    """The variants of a tendon without a split segment, given its :class:`~o2m.convert.wraps.PathGeom` s:
    every wrap kept, and none (its geoms and side sites left out)."""
    every = {name for g in geoms for name in (g.geom, g.sidesite) if name}
    return [PathVariant("+".join(g.source for g in geoms), frozenset()), PathVariant(NO_WRAP, frozenset(every))]


def _count(runs: list[list[Any]]) -> int:
    n = 1
    for r in runs:
        n *= len(r)
    return n


def xml_without(xml: str, tendon: str, dropped: Iterable[str]) -> str:
    """MJCF text ``xml`` with the sites and geoms ``dropped`` left out of the path of ``tendon``."""
    dropped = set(dropped)
    if not dropped:
        return xml
    root = etree.fromstring(xml.encode())
    for ten in root.iter("spatial"):
        if ten.get("name") != tendon:
            continue
        for el in list(ten):
            if el.get("site") in dropped or el.get("geom") in dropped:
                ten.remove(el)
    return etree.tostring(root, encoding="unicode")


def _pose_sets(fit: Any) -> list[dict[str, float]]:
    """A fit's errors on each of its pose sets: fitting, check and, where it has them, the
    validation poses it was not fitted on (lengths only)."""
    valid = getattr(fit, "valid_after", None)
    return [fit.after, fit.check_after] + ([valid] if valid else [])


def _overall(fit: Any) -> float:
    """A fit's objective over all its pose sets (mm²; inf where not finite): its mean squared
    length error over every pose, the validation poses among them, plus its mean squared
    moment-arm error over the fitting and check poses (the validation poses have lengths only)."""
    value = _mean([(s["len_rms_mm"] ** 2, s["poses"]) for s in _pose_sets(fit)]) + _arm_rms(fit) ** 2
    return value if math.isfinite(value) else math.inf


def _mean(values: list[tuple[float, int]]) -> float:
    """Mean of (value, count) pairs weighted by count."""
    return sum(v * n for v, n in values) / max(sum(n for _, n in values), 1)


def _worst_pct(fit: Any) -> float:
    """A fit's worst length error over all its pose sets (% of OpenSim's length; inf where not
    finite, so that a fit without finite errors is never preferred)."""
    value = max(s["len_max_pct"] for s in _pose_sets(fit))
    return value if math.isfinite(value) else math.inf


def _arm_rms(fit: Any) -> float:
    """A fit's RMS moment-arm error over its fitting and check poses (mm; inf where not finite)."""
    value = math.sqrt(_mean([(s["ma_rms_mm"] ** 2, s["poses"]) for s in (fit.after, fit.check_after)]))
    return value if math.isfinite(value) else math.inf


def best_variant(fits: list[Any]) -> Any:
    """Of one tendon's fitted variants (:class:`o2m.convert.wrapfit.PathFit` s), the one with the
    smallest objective over all poses among those whose worst length error and moment-arm RMS are
    near the smallest (:data:`VARIANT_PCT_FACTOR`; where none is near both, among all), on a tie
    the first, unless it flips where OpenSim does not and
    another of them does not, within :data:`FLIP_TRADE`; it records every variant's errors."""
    floor = min(_worst_pct(f) for f in fits)
    arms = min(_arm_rms(f) for f in fits)
    eligible = [f for f in fits if _worst_pct(f) <= VARIANT_PCT_FACTOR * floor + VARIANT_PCT_MARGIN
                and _arm_rms(f) <= VARIANT_PCT_FACTOR * arms + VARIANT_ARM_MARGIN_MM] or fits
    # on equal errors the first (the most wraps kept): a wrap that acts at none of the sampled
    # poses may act at others
    best = min(eligible, key=_overall)
    steady = [f for f in eligible if not f.flips and _overall(f) <= FLIP_TRADE * _overall(best)]
    if best.flips and steady:
        best = min(steady, key=_overall)
    if len(fits) > 1:
        best.variants = variant_errors(fits)
    return best


def variant_errors(fits: list[Any]) -> dict[str, dict[str, float]]:
    """Each fitted variant's objective (mm²) and worst length error (%) over all its poses, its
    moment-arm RMS (mm) over the fitting and check poses, and its flips between the fitting poses
    that OpenSim does not share."""
    return {f.variant: {"objective": _overall(f), "len_max_pct": _worst_pct(f), "ma_rms_mm": _arm_rms(f),
                        "flips": f.flips} for f in fits}


#: MjsTendon attributes that are no setting of its own.
_NOT_COPIED = {"path", "id", "signature", "name", "compiler"}


def drop_from_spec(spec: mujoco.MjSpec, dropped: dict[str, Iterable[str]]) -> None:
    """Leave the sites and geoms ``dropped[tendon]`` out of each tendon's path, and out of the
    model (they serve that tendon only). MjSpec cannot remove one element of a tendon's path, so
    the tendons from the first changed one on are re-added, in their order, with their settings."""
    dropped = {t: set(d) for t, d in dropped.items() if d}
    tendons = list(spec.tendons)
    first = next((k for k, t in enumerate(tendons) if t.name in dropped), None)
    if first is None:
        return
    saved = [_save(t, dropped.get(t.name, set())) for t in tendons[first:]]
    for t in tendons[first:]:
        spec.delete(t)
    for name, settings, path in saved:
        new = spec.add_tendon(name=name)
        for attr, value in settings.items():
            setattr(new, attr, value)
        for kind, args in path:
            getattr(new, kind)(*args)
    names = set().union(*dropped.values())
    for site in list(spec.sites):
        if site.name in names:
            spec.delete(site)
    for geom in list(spec.geoms):
        if geom.name in names:
            spec.delete(geom)


def _save(tendon: Any, dropped: set[str]) -> tuple[str, dict[str, Any], list[tuple[str, tuple]]]:
    """A tendon's name, settings and path (adder method, arguments), without ``dropped``."""
    settings = {}
    for attr in dir(tendon):
        if attr.startswith("_") or attr in _NOT_COPIED or attr.startswith("wrap_"):
            continue
        value = getattr(tendon, attr)
        if not callable(value):
            settings[attr] = value.copy() if hasattr(value, "copy") else value
    path = []
    for w in tendon.path:
        kind = w.type
        if kind == mujoco.mjtWrap.mjWRAP_SITE:
            if w.target.name not in dropped:
                path.append(("wrap_site", (w.target.name,)))
        elif kind in (mujoco.mjtWrap.mjWRAP_SPHERE, mujoco.mjtWrap.mjWRAP_CYLINDER):
            if w.target.name not in dropped:
                side = w.sidesite.name if w.sidesite and w.sidesite.name not in dropped else ""
                path.append(("wrap_geom", (w.target.name, side)))
        elif kind == mujoco.mjtWrap.mjWRAP_JOINT:
            path.append(("wrap_joint", (w.target.name, w.coef)))
        elif kind == mujoco.mjtWrap.mjWRAP_PULLEY:
            path.append(("wrap_pulley", (w.divisor,)))
        else:
            raise ValueError(f"tendon {tendon.name}: path element of type {kind} not handled")
    return tendon.name, settings, path


__all__ = ["MAX_VARIANTS", "NO_WRAP", "VARIANT_PCT_FACTOR", "VARIANT_PCT_MARGIN", "PathVariant", "best_variant",
           "drop_from_spec", "variant_errors", "split_variants", "whole_and_straight", "xml_without"]
