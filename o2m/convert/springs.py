"""PointToPointSpring as a spring on a two-site spatial tendon; PathSpring as its path's tendon's spring.

OpenSim's PointToPointSpring pulls its two points together with ``stiffness · (L - rest_length)``
along the straight line between them (pushing them apart when shorter than ``rest_length``), L
the points' distance. A MuJoCo spatial tendon through two sites has length L and applies its
spring ``-stiffness · (L - springlength)`` along that same line (J^T times the tension), so the
spring converts exactly: ``stiffness`` (N/m) and ``springlength = [rest_length, rest_length]`` (m,
no dead band). :func:`measure_springs` checks it at random poses (MuJoCo's tendon force against
the formula at MuJoCo's length).

OpenSim's PathSpring pulls along its GeometryPath (the tendon :mod:`o2m.convert.tendons` builds)
with ``stiffness · max(L - resting_length, 0) · (1 + dissipation · dL/dt)``. Its elastic part is
MuJoCo's tendon spring with the dead band ``springlength = [0, resting_length]``, exactly; the
damping, proportional to the stretch, has no MuJoCo counterpart and is left out (the report says
by how much it changes the tension: ``dissipation · |dL/dt|`` of it).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from lxml import etree

from o2m.convert.actuators import _body_site, _frame_by_name
from o2m.convert.builder import MjcfBuilder
from o2m.convert.force_context import (
    N_POSES,
    ForceConversion,
    Spring,
    _Context,
    _number,
    _vector,
    worst_tendon_spring_error,
)
from o2m.convert.records import Approximation
from o2m.osim.skeleton import Skipped
from o2m.transforms import Transform

__all__ = ["convert_path_spring", "convert_point_to_point_spring", "measure_springs"]


def _end_frame(ctx: _Context, el: etree._Element, i: int) -> tuple[str, Transform]:
    """(body, frame in body) of end ``i``: the path in ``socket_body<i>`` (OpenSim 4) or the body
    named in ``body<i>`` (3.x)."""
    if el.find(f"socket_body{i}") is not None:
        body, frame, _ = ctx.reader.socket_frame(el, f"socket_body{i}")
        return body, frame
    return _frame_by_name(ctx, el, f"body{i}")


def convert_point_to_point_spring(ctx: _Context, el: etree._Element) -> None:
    """PointToPointSpring -> a spatial tendon between sites at its two points, with the spring."""
    b = ctx.builder
    name = el.get("name")
    ends = []
    for i in (1, 2):
        body, frame = _end_frame(ctx, el, i)
        ends.append((body, frame.apply(_vector(el, f"point{i}", (0.0, 0.0, 0.0), ctx))))
    stiffness = _number(el, "stiffness", 1.0, ctx)
    rest = _number(el, "rest_length", 0.0, ctx)
    if not (math.isfinite(stiffness) and stiffness >= 0.0):
        raise b.doc.error(el, f"has <stiffness> {stiffness:g}; a spring needs a finite stiffness >= 0 N/m")
    if not (math.isfinite(rest) and rest >= 0.0):
        raise b.doc.error(el, f"has <rest_length> {rest:g}; it must be finite and >= 0 m")
    if ends[0][0] == ends[1][0]:
        ctx.out.skipped.append(Skipped(el.tag, name, f"both points are on '{ends[0][0]}' (no force between bodies)"))
        return
    sites = [_body_site(ctx, body, f"{name}_point{i}", pos) for i, (body, pos) in enumerate(ends, start=1)]
    tendon = ctx.spec.add_tendon(name=ctx.unique("tendon", name))
    for s in sites:
        tendon.wrap_site(s)
    tendon.stiffness = [stiffness, 0.0, 0.0]
    tendon.springlength = [rest, rest]
    tendon.rgba = [0.9, 0.6, 0.1, 1.0]
    ctx.out.exact[("tendon", tendon.name)] = {"stiffness": np.array([stiffness, 0.0, 0.0]),
                                              "springlength": np.array([rest, rest])}
    ctx.out.springs.append(Spring(name, tendon.name, stiffness, rest))


def convert_path_spring(ctx: _Context, el: etree._Element) -> None:
    """PathSpring -> the elastic spring (dead band below ``resting_length``) of its path's tendon."""
    b, name = ctx.builder, ctx.path_tendon(el)
    if name is None:
        ctx.out.skipped.append(Skipped(el.tag, el.get("name"), "its path became no MuJoCo tendon"))
        return
    stiffness = _number(el, "stiffness", math.nan, ctx)
    rest = _number(el, "resting_length", math.nan, ctx)
    dissipation = _number(el, "dissipation", math.nan, ctx)
    for prop, value in (("stiffness", stiffness), ("resting_length", rest), ("dissipation", dissipation)):
        if not (math.isfinite(value) and value >= 0.0):
            raise b.doc.error(el, f"has <{prop}> {value:g}; a PathSpring needs a finite {prop} >= 0")
    tendon = ctx.spec.tendon(name)
    tendon.stiffness = [stiffness, 0.0, 0.0]
    tendon.springlength = [0.0, rest]
    ctx.out.exact[("tendon", name)] = {"stiffness": np.array([stiffness, 0.0, 0.0]),
                                       "springlength": np.array([0.0, rest])}
    ctx.out.springs.append(Spring(name, name, stiffness, rest, el.tag, slack=True, dissipation=dissipation))


def measure_springs(out: ForceConversion, model: mujoco.MjModel, builder: MjcfBuilder) -> None:
    """Record each spring's worst |MuJoCo tendon tension - stiffness (L - rest_length)| (N) over
    random poses in ``builder.result.approximations`` (round-off for the exact mapping)."""
    for spring in out.springs:
        worst = worst_tendon_spring_error(model, builder, spring.tendon, spring.tension)
        if spring.slack:
            what = (f"the spring of its path's tendon: stiffness {spring.stiffness:g} N/m, slack below "
                    f"{spring.rest_length:g} m; its dissipation {spring.dissipation:g} s/m is left out (OpenSim's "
                    f"tension times 1 + dissipation dL/dt: {100 * spring.dissipation:.3g} % at 1 m/s)")
            how = f"MuJoCo's tendon tension against stiffness max(L - resting_length, 0) at {N_POSES} poses, at rest"
        else:
            what = (f"a spring on spatial tendon '{spring.tendon}' between its two points: stiffness "
                    f"{spring.stiffness:g} N/m, springlength {spring.rest_length:g} m")
            how = f"MuJoCo's tendon tension against stiffness (L - rest_length) at {N_POSES} poses"
        builder.result.approximations.append(Approximation(spring.element, spring.name, what, worst, "N", how))
