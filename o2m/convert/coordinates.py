"""Coordinates and CoordinateCouplerConstraints: each coordinate as a function of an independent one.

A coupler makes a coordinate a function of another; resolved, every coordinate is a
:class:`Driver`: an independent coordinate and a function of its value. Values are radians or
metres. A coordinate's MuJoCo joint (named as the coordinate, ``qpos`` = its value) stands on
one of the transform axes it drives (:func:`choose_coordinate_axes`, :class:`CoordinateAxis`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from o2m.osim.skeleton import Coordinate, Joint, Skeleton, TransformAxis

#: Range over which a coupling with an unbounded driving coordinate is fitted (rad or m).
UNBOUNDED_FIT_RANGE = {"rotation": (-np.pi, np.pi), "translation": (-1.0, 1.0)}
#: Samples used to decide whether a function is linear over a range.
_LINEAR_SAMPLES = 401


class Driver:
    """An independent coordinate and a function of it: the value of a coordinate or an axis."""

    def __init__(self, base: str, fn: Callable[[np.ndarray], np.ndarray]):
        self.base, self.fn = base, fn

    def then(self, f: Callable[[np.ndarray], np.ndarray]) -> Driver:
        inner = self.fn
        return Driver(self.base, lambda x: f(inner(x)))


def relative(driver: Driver, ref: float) -> Callable[[np.ndarray], np.ndarray]:
    """x -> driver.fn(x) - ref: a joint's value relative to its reference value."""
    return lambda x: np.asarray(driver.fn(np.asarray(x, dtype=float)), dtype=float) - ref


def as_linear(fn: Callable[[np.ndarray], np.ndarray], lo: float, hi: float) -> tuple[float, float] | None:
    """(slope, intercept) when ``fn`` is linear on [lo, hi] to 1e-12 (relative), else None."""
    x = np.linspace(lo, hi, _LINEAR_SAMPLES)
    y = np.asarray(fn(x), dtype=float)
    if hi - lo < 1e-15:
        return 0.0, float(y[0])
    slope = (y[-1] - y[0]) / (hi - lo)
    icpt = y[0] - slope * lo
    scale = max(1.0, float(np.max(np.abs(y))))
    if np.max(np.abs(y - (slope * x + icpt))) <= 1e-12 * scale:
        return float(slope), float(icpt)
    return None


def coordinate_drivers(skel: Skeleton) -> dict[str, Driver]:
    """Each coordinate of ``skel`` as a function of an independent coordinate (couplers resolved)."""
    couplers = {c.dependent: c for c in skel.couplers}
    drivers: dict[str, Driver] = {}

    def resolve(name: str, seen: tuple[str, ...]) -> Driver:
        if name in drivers:
            return drivers[name]
        if name in seen:
            raise skel.document.error(couplers[name].element, "is part of a circular chain of couplers")
        cp = couplers.get(name)
        if cp is None:
            d = Driver(name, lambda x: np.asarray(x, dtype=float))
        else:
            d = resolve(cp.independent, seen + (name,)).then(cp.function)
        drivers[name] = d
        return d

    for name in skel.coordinates:
        resolve(name, ())
    return drivers


def fit_range(skel: Skeleton, name: str, kind: str) -> tuple[float, float]:
    """The range of coordinate ``name`` (``kind``: "rotation" or "translation") that its couplings
    are fitted over: its own, or :data:`UNBOUNDED_FIT_RANGE` when it has none."""
    lo, hi = skel.coordinates[name].range
    ulo, uhi = UNBOUNDED_FIT_RANGE[kind]
    if hi - lo > 1e3:  # OpenSim writes ±99999.9 for "no range"
        lo, hi = ulo, uhi
    return float(lo), float(hi)


def is_fixed(skel: Skeleton, drivers: dict[str, Driver], ax: TransformAxis) -> bool:
    """True when the axis does not move: no coordinate, or it depends on a locked coordinate only."""
    return ax.coordinate is None or skel.coordinates[drivers[ax.coordinate].base].locked


@dataclass(frozen=True)
class CoordinateAxis:
    """The transform axis a coordinate's MuJoCo joint stands on, and how its value maps to the axis.

    ``form`` is ``"identity"`` (axis value = q), ``"mirrored"`` (axis value = ``slope`` q +
    ``intercept`` with slope -1: the MuJoCo axis is reversed, exact) or ``"complement"`` (any
    other function f: the coordinate's joint turns by q about the axis and a second joint on the
    same axis, ``<joint>_<axis>``, by f(q) - q, driven by a joint equality; exact where f is linear).
    """

    joint: Joint
    axis: TransformAxis
    form: str
    slope: float = 1.0
    intercept: float = 0.0

    def __iter__(self):  # (joint, axis), as callers unpack it
        return iter((self.joint, self.axis))

    def __getitem__(self, i: int):
        return (self.joint, self.axis)[i]


def _test_range(skel: Skeleton, name: str, kind: str) -> tuple[float, float]:
    """Where an axis function is tested for linearity: the coordinate's fitting range, widened to
    :data:`UNBOUNDED_FIT_RANGE` when it has no width (a coordinate with a zero-width range)."""
    lo, hi = fit_range(skel, name, kind)
    return (lo, hi) if hi - lo > 1e-9 else UNBOUNDED_FIT_RANGE[kind]


def _form(ax: TransformAxis, lo: float, hi: float) -> tuple[str, float, float] | None:
    lin = as_linear(ax.function, lo, hi)
    if lin is None or abs(abs(lin[0]) - 1.0) > 1e-12:
        return None
    if lin[0] > 0:
        return ("identity", 1.0, 0.0) if abs(lin[1]) < 1e-12 else None
    return "mirrored", -1.0, lin[1]


def choose_coordinate_axes(skel: Skeleton, drivers: dict[str, Driver]) -> dict[str, CoordinateAxis]:
    """Each free coordinate's MuJoCo joint: on the first moving axis that is the identity of it;
    else on the first that is its mirror image (-q + c); else on the first moving axis it drives
    (a rotation axis when it drives one), complemented by a second joint there. A dependent
    coordinate without an identity or mirrored axis gets none: its axes follow its driver."""
    moving: dict[str, list[tuple[Joint, TransformAxis]]] = {}
    for joint in skel.joints:
        for ax in joint.translations + joint.rotations:
            if ax.coordinate is not None and not is_fixed(skel, drivers, ax):
                moving.setdefault(ax.coordinate, []).append((joint, ax))
    chosen: dict[str, CoordinateAxis] = {}
    for name, axes in moving.items():
        forms = [(j, ax, _form(ax, *_test_range(skel, name, ax.kind))) for j, ax in axes]
        for wanted in ("identity", "mirrored"):
            hit = next(((j, ax, f) for j, ax, f in forms if f is not None and f[0] == wanted), None)
            if hit is not None:
                chosen[name] = CoordinateAxis(hit[0], hit[1], *hit[2])
                break
        else:
            if drivers[name].base == name:  # a free coordinate reaching its axes through functions only
                j, ax = next(((j, ax) for j, ax in axes if ax.kind == "rotation"), axes[0])
                chosen[name] = CoordinateAxis(j, ax, "complement")
    return chosen


#: A range this wide or wider is OpenSim's way of writing "no range" (rad or m).
NO_RANGE_WIDTH = 1e3


def _clamped_range(coordinate: Coordinate) -> bool:
    """Whether the coordinate is clamped to a range OpenSim means as one (:data:`NO_RANGE_WIDTH`)."""
    return coordinate.clamped and coordinate.range[1] - coordinate.range[0] < NO_RANGE_WIDTH


def joint_limited(coordinate: Coordinate, hard_limits: bool) -> tuple[bool, str | None]:
    """Whether a coordinate's MuJoCo joint gets limits, and a note for the report where it cannot.

    OpenSim enforces a clamped coordinate's range only when it sets or assembles values, never in
    forward dynamics (a clamped slider under gravity falls through the end of its range), so the
    faithful joint is unlimited; ``hard_limits`` gives clamped coordinates MuJoCo's hard limits.
    A range of :data:`NO_RANGE_WIDTH` or wider stays unlimited.
    """
    lo, hi = coordinate.range
    if not (hard_limits and _clamped_range(coordinate)):
        return False, None
    if not lo < hi:  # MuJoCo's limits need two ends
        return False, (f"coordinate '{coordinate.name}' is clamped to a range of no width {[lo, hi]}: its "
                       f"MuJoCo joint is left unlimited (MuJoCo's limits need two ends)")
    return True, None


def unenforced_clamps(skel: Skeleton, hard_limits: bool) -> list[str]:
    """The report's note naming the clamped coordinates whose MuJoCo joints stay unlimited (none
    with ``hard_limits``): users who expect joint limits learn why there are none."""
    names = [c.name for c in skel.coordinates.values() if _clamped_range(c) and not c.locked]
    if hard_limits or not names:
        return []
    return [f"{len(names)} clamped coordinates ({', '.join(names)}) have unlimited MuJoCo joints: OpenSim "
            f"enforces a clamped range only when it sets or assembles values, not in forward dynamics "
            f"(ConvertOptions.clamped_limits / --clamped-limits gives them MuJoCo's hard limits)"]


#: Joint types whose rotational coordinates Simbody moves through the angular velocity's components
#: in the joint's parent frame (its Ball, Free and Ellipsoid mobilizers) rather than through the
#: angles' rates: a coordinate's speed is such a component, and a generalized force on it a torque
#: about the parent frame's axis, where MuJoCo's hinge standing for it turns with the hinges before it.
ANGULAR_VELOCITY_JOINTS = frozenset({"BallJoint", "FreeJoint", "EllipsoidJoint"})


def is_mobility_rotation(joint: Joint, coord: str) -> bool:
    """Whether ``coord`` is a rotation of ``joint``, a joint of :data:`ANGULAR_VELOCITY_JOINTS`."""
    return joint.type in ANGULAR_VELOCITY_JOINTS and coord in [ax.coordinate for ax in joint.rotations]
