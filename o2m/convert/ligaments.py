"""Ligaments as springs on the spatial tendons of their paths.

A Ligament's GeometryPath is the spatial tendon :mod:`o2m.convert.tendons` builds; the tension
``pcsa_force · curve(L / resting_length)`` (0 when slack) becomes the tendon's spring: a dead
band ``[0, edge]`` and a polynomial stiffness fitted minimax over the tendon's length range.
A Blankevoort1991Ligament is the same with its own curve (:class:`BlankevoortCurve`, times
``linear_stiffness``, over ``slack_length``); its damping is not converted (the report says so).
The fit is measured by MuJoCo's tendon force at random poses. Lengths in metres, forces in newtons.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import mujoco
import numpy as np
from lxml import etree
from numpy.typing import ArrayLike

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
from o2m.osim.function_reader import parse_function
from o2m.osim.functions import Function

__all__ = ["BlankevoortCurve", "convert_blankevoort", "convert_ligament", "fit_ligaments", "measure_ligaments"]

#: Extra strain beyond rest over which a ligament is fitted when its length range stays short of it.
LIGAMENT_MIN_STRAIN = 0.05
#: OpenSim's default Ligament force-length curve (used when the document leaves it out).
DEFAULT_LIGAMENT_CURVE = (
    '<SimmSpline name="force_length_curve"><x>-5 0.998 0.999 1 1.1 1.2 1.3 1.4 1.5 1.6 1.601 1.602 5</x>'
    '<y>0 0 0 0 0.035 0.12 0.26 0.55 1.17 2 2 2 2</y></SimmSpline>')


def _path_tendon(ctx: _Context, el: etree._Element) -> str:
    """The name of ``el``'s spatial tendon (its own name); an error where its path was not converted."""
    name = ctx.path_tendon(el)
    if name is None:
        raise ctx.builder.doc.error(el, "has no MuJoCo tendon (its GeometryPath was not converted)")
    return name


def convert_ligament(ctx: _Context, el: etree._Element) -> None:
    """Ligament -> a spring on the spatial tendon of its path (fitted after the model compiles)."""
    b, name = ctx.builder, _path_tendon(ctx, el)
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


@dataclass(frozen=True, eq=False)
class BlankevoortCurve(Function):
    """Blankevoort1991Ligament's spring force over its linear stiffness, at x = length / slack length:
    with strain e = x - 1, 0 when slack, e² / (2 e_t) in the toe region (e ≤ e_t), e - e_t / 2 beyond."""

    kind: ClassVar[str] = "Blankevoort1991Ligament"
    transition_strain: float = 0.06

    def __call__(self, x: ArrayLike) -> np.ndarray:
        e, t = np.asarray(x, dtype=float) - 1.0, self.transition_strain
        return np.where(e <= 0.0, 0.0, np.where(e <= t, e * e / (2.0 * t), e - 0.5 * t))

    def derivative(self, x: ArrayLike) -> np.ndarray:
        e, t = np.asarray(x, dtype=float) - 1.0, self.transition_strain
        return np.where(e <= 0.0, 0.0, np.where(e <= t, e / t, 1.0))

    @property
    def knots(self) -> np.ndarray:
        return np.array([1.0, 1.0 + self.transition_strain])


def convert_blankevoort(ctx: _Context, el: etree._Element) -> None:
    """Blankevoort1991Ligament -> a spring on the spatial tendon of its path, as a Ligament."""
    b, name = ctx.builder, _path_tendon(ctx, el)
    slack = _number(el, "slack_length", 0.0, ctx)
    if not slack > 0.0:  # OpenSim divides by it: the strain is infinite
        raise b.doc.error(el, f"has slack_length {slack:g}; its strain needs it positive")
    transition = _number(el, "transition_strain", 0.06, ctx)
    if not transition > 0.0:
        raise b.doc.error(el, f"has transition_strain {transition:g}; it must be positive")
    stiffness = _number(el, "linear_stiffness", 1.0, ctx)
    if not (np.isfinite(stiffness) and stiffness >= 0.0):
        raise b.doc.error(el, f"has linear_stiffness {stiffness:g}; it must be a number of at least 0")
    ctx.out.ligaments.append(Ligament(name, name, slack, stiffness, BlankevoortCurve(transition_strain=transition),
                                      element=el.tag))
    damping = _number(el, "damping_coefficient", 0.003, ctx)
    if damping:
        b.result.notes.append(f"Blankevoort1991Ligament '{name}': damping_coefficient {damping:g} not converted "
                              "(the tendon has the elastic force only)")


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
        step = lig.pcsa_force * float(np.asarray(lig.curve(np.array([1.0])), dtype=float)[0])
        floor = (f"; OpenSim's tension steps from 0 to {step:.4g} N at the resting length (its curve is "
                 f"not 0 at length / resting_length = 1), so no spring is within {abs(step) / 2:.3g} N of it"
                 if abs(step) > 1e-9 * max(lig.pcsa_force, 1.0) else "")
        result.approximations.append(Approximation(
            lig.element, lig.name,
            f"tension as a tendon spring: dead band to {lig.fit.edge:.6g} m, stiffness "
            + " ".join(f"{c:.4g}" for c in lig.fit.coef),
            float(max(lig.fit.max_error, err_pose)), "N",
            f"force-length fit over [{lig.length_range[0]:.4g}, {lig.length_range[1]:.4g}] m: worst "
            f"{lig.fit.max_error:.3g} N; MuJoCo's tendon force at {N_POSES} poses: worst {err_pose:.3g} N; "
            f"{'pcsa_force' if lig.element == 'Ligament' else 'linear_stiffness'} {lig.pcsa_force:g} N{floor}"))


def _measure_ligament(lig: Ligament, model: mujoco.MjModel, builder: MjcfBuilder) -> float:
    """Worst |MuJoCo tendon force - OpenSim tension at MuJoCo's tendon length| (N) over random poses."""
    return worst_tendon_spring_error(model, builder, lig.tendon,
                                     lambda length: float(lig.tension(np.array([length]))[0]))

