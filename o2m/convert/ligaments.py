"""Ligaments as springs on the spatial tendons of their paths.

A Ligament's GeometryPath is the spatial tendon :mod:`o2m.convert.tendons` builds; the tension
``pcsa_force · curve(L / resting_length)`` (0 when slack) becomes the tendon's spring: a dead
band ``[0, edge]`` and a polynomial stiffness fitted minimax over the tendon's length range.
The fit is measured by MuJoCo's tendon force at random poses. Lengths in metres, forces in newtons.
"""

from __future__ import annotations

import mujoco
import numpy as np
from lxml import etree

from o2m.convert.builder import MjcfBuilder
from o2m.convert.force_context import (
    N_GRID,
    N_POSES,
    ForceConversion,
    Ligament,
    SideFit,
    _Context,
    _independent_ranges,
    _number,
    worst_tendon_spring_error,
)
from o2m.convert.limit_forces import fit_deadband
from o2m.convert.records import Approximation
from o2m.osim.functions import parse_function

__all__ = ["convert_ligament", "fit_ligaments", "measure_ligaments"]

#: Extra strain beyond rest over which a ligament is fitted when its length range stays short of it.
LIGAMENT_MIN_STRAIN = 0.05
#: OpenSim's default Ligament force-length curve (used when the document leaves it out).
DEFAULT_LIGAMENT_CURVE = (
    '<SimmSpline name="force_length_curve"><x>-5 0.998 0.999 1 1.1 1.2 1.3 1.4 1.5 1.6 1.601 1.602 5</x>'
    '<y>0 0 0 0 0.035 0.12 0.26 0.55 1.17 2 2 2 2</y></SimmSpline>')


def convert_ligament(ctx: _Context, el: etree._Element) -> None:
    """Ligament -> a spring on the spatial tendon of its path (fitted after the model compiles)."""
    b = ctx.builder
    name = el.get("name")
    if name not in [t.name for t in ctx.spec.tendons]:
        raise b.doc.error(el, "has no MuJoCo tendon (its GeometryPath was not converted)")
    rest = _number(el, "resting_length", 0.0, ctx)
    if not rest > 0.0:
        raise b.doc.error(el, f"has resting_length {rest:g}; OpenSim needs it positive")
    curve_el = next((c for c in el if isinstance(c.tag, str) and c.get("name") == "force_length_curve"), None)
    if curve_el is None:
        holder = el.find("force_length_curve")
        curve_el = next((c for c in holder if isinstance(c.tag, str)), None) if holder is not None else None
    if curve_el is None:
        curve_el = etree.fromstring(DEFAULT_LIGAMENT_CURVE)
    ctx.out.ligaments.append(Ligament(name, name, rest, _number(el, "pcsa_force", 0.0, ctx), parse_function(curve_el)))


def fit_ligaments(out: ForceConversion, spec: mujoco.MjSpec, model: mujoco.MjModel, builder: MjcfBuilder) -> None:
    """Fit each ligament's tendon spring to its force-length curve over the tendon's length range
    (``model`` is the compiled model; the spring is set in ``spec``)."""
    if not out.ligaments:
        return
    from o2m.convert.tendons import tendon_length_ranges

    ranges = tendon_length_ranges(model, _independent_ranges(builder))
    for lig in out.ligaments:
        lo, hi = (float(v) for v in ranges[model.tendon(lig.tendon).id])
        hi = max(hi, lig.resting_length * (1.0 + LIGAMENT_MIN_STRAIN))
        lig.length_range = (lo, hi)
        length = np.linspace(lo, hi, N_GRID)
        target = lig.tension(length)
        tendon = spec.tendon(lig.tendon)
        if not np.any(target != 0.0):
            builder.result.notes.append(f"Ligament '{lig.name}': no tension over lengths [{lo:.4g}, {hi:.4g}] m; "
                                        "its tendon has no spring")
            continue
        e, p, err = fit_deadband(length, target, min(lo, lig.resting_length), hi)
        lig.fit = SideFit("tendon", "tension", edge=e, coef=tuple(float(c) for c in p), max_error=err,
                          tendon=lig.tendon)
        tendon.springlength = [0.0, e]
        tendon.stiffness = list(lig.fit.coef)
        out.exact[("tendon", lig.tendon)] = {"springlength": np.array([0.0, e]), "stiffness": np.array(lig.fit.coef)}


def measure_ligaments(out: ForceConversion, model: mujoco.MjModel, builder: MjcfBuilder) -> None:
    """Measure every fitted ligament in ``model`` (the MJCF as written) and record the errors in
    ``builder.result.approximations``."""
    result = builder.result
    for lig in out.ligaments:
        if lig.fit is None:
            continue
        err_pose = _measure_ligament(lig, model, builder)
        result.approximations.append(Approximation(
            "Ligament", lig.name,
            f"tension as a tendon spring: dead band to {lig.fit.edge:.6g} m, stiffness "
            + " ".join(f"{c:.4g}" for c in lig.fit.coef),
            float(max(lig.fit.max_error, err_pose)), "N",
            f"force-length fit over [{lig.length_range[0]:.4g}, {lig.length_range[1]:.4g}] m: worst "
            f"{lig.fit.max_error:.3g} N; MuJoCo's tendon force at {N_POSES} poses: worst {err_pose:.3g} N; "
            f"pcsa_force {lig.pcsa_force:g} N"))


def _measure_ligament(lig: Ligament, model: mujoco.MjModel, builder: MjcfBuilder) -> float:
    """Worst |MuJoCo tendon force - OpenSim tension at MuJoCo's tendon length| (N) over random poses."""
    return worst_tendon_spring_error(model, builder, lig.tendon,
                                     lambda length: float(lig.tension(np.array([length]))[0]))

