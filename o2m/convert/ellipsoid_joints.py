"""EllipsoidJoint and ScapulothoracicJoint as exact chains of MuJoCo hinges.

Simbody's Ellipsoid mobilizer (:class:`o2m.osim.skeleton.EllipsoidSurface`) turns its M frame
by R = Rx(q1) Ry(q2) Rz(q3) and puts its origin at ``p = diag(a, b, c) R e_z``: a translation
that depends on two angles at once, which no single MuJoCo joint equality can drive. But with
u(s, t) = Rx(s q1) Ry(t q2) e_z (signs s, t = ±1), whose components are (t sin q2,
-s sin q1 cos q2, cos q1 cos q2),

    p = k1 u(+, +) + k2 u(-, +) + k3 u(+, -) + k4 u(-, -)

for any k with k1 + k2 - k3 - k4 = a, k1 - k2 + k3 - k4 = b and k1 + k2 + k3 + k4 = c: a
one-parameter family, in which one of the four arms can be dropped. Each arm is a fixed offset
k e_z after hinges turning by ±q1 about x and ±q2 about y, so the chain

    Rx(±q1) Ry(±q2) · k e_z · (hinges to the next arm's signs) · k' e_z ... Ry(..) Rz(q3)

is exact, every hinge a linear function (±1 or ±2 times) of one coordinate. The arms' order
and the dropped arm are chosen for the fewest hinges: 3 for a sphere, 4 when b = c, 6 when
a = c or a = b, 7 otherwise. The first ±1 hinge of each coordinate is the coordinate's MuJoCo
joint (its axis reversed for -1, so it carries the coordinate's value); the others follow it by
linear joint equalities. A three-hinge turn (y, x, y through one point: every chain but a
sphere's and b = c's) lines its two y hinges up when q1 = 0, where the mass matrix would be
singular, so the driven hinges of such a chain get a small armature, recorded in the report. A
ScapulothoracicJoint's winging is one more hinge, about its axis through its origin. Past
MuJoCo's 6 degrees of freedom per body, the first hinges go on an intermediate body
``<child>_ellipsoid`` (1e-12 kg) between the parent and the child.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from o2m.convert.coupling_plan import MAX_BODY_DOFS
from o2m.convert.inertials import (
    COUPLINGS_BODY_INERTIA,
    COUPLINGS_BODY_MASS,
    MIN_INERTIA,
    set_inertial,
)
from o2m.convert.records import Approximation
from o2m.osim.functions import LinearFunction
from o2m.osim.skeleton import Joint, TransformAxis
from o2m.transforms import OSIM_TO_MJ, Transform, axis_angle_matrix, matrix_to_quat

#: Body-fixed x, y, z unit axes.
_AXES = np.eye(3)
#: A driven hinge's armature where two hinges of its chain can line up, as a fraction of the
#: child body's own inertia about it: small, as the test models' dynamics are sensitive to it
#: (docs/conversion.md); a tenth of it let a chain's equalities diverge.
CHAIN_ARMATURE = 1e-3
#: Coordinate-range samples per coordinate on which the chain is checked against OpenSim's formula.
CHECK_SAMPLES = 7


@dataclass
class Link:
    """One element of a joint's chain: a fixed transform, or a hinge about ``axis`` (its own
    frame, through its origin) turning by ``scale`` times coordinate ``coordinate`` (an index
    into the joint's rotations)."""

    fixed: Transform | None = None
    axis: np.ndarray | None = None
    coordinate: int = -1
    scale: float = 1.0

    def at(self, q: list[float]) -> Transform:
        """This link's transform with the joint's coordinates at ``q`` (rad)."""
        if self.fixed is not None:
            return self.fixed
        return Transform(axis_angle_matrix(self.axis, self.scale * q[self.coordinate]))


def arm_weights(radii: np.ndarray) -> list[tuple[np.ndarray, ...]]:
    """The four arm weight vectors (k1..k4, module docstring) that drop one arm each."""
    a, b, c = (float(r) for r in radii)
    base = np.array([(a + b) / 2, (c - b) / 2, (c - a) / 2, 0.0])
    null = np.array([1.0, -1.0, -1.0, 1.0])
    return [base + t * null for t in (0.0, (c - b) / 2, (c - a) / 2, -(a + b) / 2)]


#: Signs (s, t) of the four arms u(s, t), in the order of their weights.
_SIGNS = [(1, 1), (-1, 1), (1, -1), (-1, -1)]


def _turn(frm: tuple[int, int] | None, to: tuple[int, int]) -> list[tuple[int, int, float]]:
    """Hinges (axis index, coordinate index, scale) taking frame Rx(s q1) Ry(t q2) to ``to``."""
    if frm is None:
        return [(0, 0, float(to[0])), (1, 1, float(to[1]))]
    (s, t), (s2, t2) = frm, to
    if s == s2:
        return [(1, 1, float(t2 - t))] if t != t2 else []
    return [(1, 1, float(-t)), (0, 0, float(s2 - s)), (1, 1, float(t2))]


def surface_steps(radii: np.ndarray) -> list[tuple[int, int, float] | float]:
    """The shortest exact chain of the Ellipsoid mobilizer: hinges (axis index, coordinate index,
    scale) and offsets along the current z (a float, m), ending with Rz(q3)."""
    scale = max(float(np.max(np.abs(radii))), 1e-300)
    best: list | None = None
    for weights in arm_weights(radii):
        arms = [(_SIGNS[i], float(k)) for i, k in enumerate(weights) if abs(k) > 1e-12 * scale]
        for order in itertools.permutations(arms):
            steps: list = []
            frame = None
            for signs, k in order:
                steps += _turn(frame, signs)
                steps.append(k)
                frame = signs
            steps += _turn(frame, (1, 1))
            steps.append((2, 2, 1.0))
            hinges = sum(not isinstance(x, float) for x in steps)
            if best is None or hinges < best[0]:
                best = (hinges, steps)
    return best[1]


def joint_chain(joint: Joint) -> list[Link]:
    """``joint``'s parent body to its child body as links (module docstring): exact."""
    surf = joint.surface
    links = [Link(joint.parent_frame @ surf.frame)]
    for step in surface_steps(surf.radii):
        if isinstance(step, float):
            links.append(Link(Transform(pos=np.array([0.0, 0.0, step]))))
        else:
            links.append(Link(axis=_AXES[step[0]], coordinate=step[1], scale=step[2]))
    links.append(Link(surf.after))
    if surf.winging_axis is not None:
        links += [Link(Transform(pos=surf.winging_point)), Link(axis=surf.winging_axis, coordinate=3),
                  Link(Transform(pos=-surf.winging_point))]
    links.append(Link(joint.child_frame.inverse()))
    return links


def chain_transform(links: list[Link], q: list[float]) -> Transform:
    out = Transform()
    for link in links:
        out = out @ link.at(q)
    return out


def chain_error(joint: Joint, links: list[Link], ranges: list[tuple[float, float]]) -> tuple[float, float]:
    """Worst distance (m) and angle (rad) between the chain's child frame and OpenSim's
    (:meth:`Joint.transform`) on a grid over the coordinates' ranges."""
    grids = [np.linspace(lo, hi, CHECK_SAMPLES) for lo, hi in ranges]
    pos = ang = 0.0
    for q in itertools.product(*grids):
        want = joint.transform({ax.coordinate: v for ax, v in zip(joint.rotations, q, strict=True)})
        got = chain_transform(links, list(q))
        pos = max(pos, float(np.linalg.norm(got.pos - want.pos)))
        r = got.rot.T @ want.rot
        sin = np.linalg.norm([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / 2.0
        ang = max(ang, float(np.arctan2(sin, (np.trace(r) - 1.0) / 2.0)))
    return pos, ang


def _fold_fixed(builder, joint: Joint, links: list[Link], q0: list[float]) -> list[Link]:
    """``links`` with the hinges of locked coordinates folded into fixed links at their default."""
    return [Link(link.at(q0)) if link.fixed is None and builder.is_fixed(joint.rotations[link.coordinate])
            else link for link in links]


def _segments(links: list[Link]) -> list[list[Link]]:
    """``links`` cut after a hinge so that no part holds more than :data:`MAX_BODY_DOFS` hinges;
    the last part (the child body) holds the last hinges."""
    hinges = [i for i, link in enumerate(links) if link.fixed is None]
    if len(hinges) <= MAX_BODY_DOFS:
        return [links]
    cut = hinges[len(hinges) - MAX_BODY_DOFS - 1] + 1
    return [*_segments(links[:cut]), links[cut:]]


def _hinge_inertia(builder, joint: Joint, suffix: Transform, axis: np.ndarray) -> float:
    """The child body's own inertia (kg m²) about a hinge about ``axis`` (its own frame), whose
    frame is ``suffix`` (the links after it, at the reference pose) away from the child body's."""
    body = builder.skel.bodies[joint.child]
    u = suffix.rot.T @ axis
    d = body.com - (-suffix.rot.T @ suffix.pos)
    inertia = body.inertia + body.mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return max(float(u @ inertia @ u), MIN_INERTIA)


def _add_body(builder, joint: Joint, parent, x: Transform, n: int, last: bool):
    """The MuJoCo body of part ``n`` of ``joint``'s chain at ``x`` in ``parent``: the child body,
    or an intermediate body (:data:`~o2m.convert.inertials.COUPLINGS_BODY_MASS`)."""
    x_mj = Transform(OSIM_TO_MJ) @ x if joint.parent == "ground" and n == 0 else x
    name = joint.child if last else _intermediate_name(builder, joint, n)
    body = parent.add_body(name=name, pos=x_mj.pos, quat=matrix_to_quat(x_mj.rot))
    builder.exact[("body", name)] = {"pos": x_mj.pos, "quat": matrix_to_quat(x_mj.rot)}
    if last:
        set_inertial(builder, body, joint)
        return body
    body.explicitinertial = True
    body.mass, body.ipos = COUPLINGS_BODY_MASS, np.zeros(3)
    body.fullinertia = [COUPLINGS_BODY_INERTIA] * 3 + [0.0] * 3
    builder.exact[("inertial", name)] = {"pos": np.zeros(3), "mass": COUPLINGS_BODY_MASS,
                                         "fullinertia": np.array(body.fullinertia)}
    return body


def add_surface_joint(builder, joint: Joint) -> None:
    """Add ``joint`` (an EllipsoidJoint or ScapulothoracicJoint) to ``builder``'s spec as its exact
    hinge chain (module docstring): the child body, an intermediate body where needed, the
    hinges and their equalities; record the check against OpenSim and any driven hinges' armature."""
    q_ref = {name: builder.ref[name] for name in builder.skel.coordinates}
    q0 = [ax.value(q_ref) for ax in joint.rotations]
    links = _fold_fixed(builder, joint, joint_chain(joint), q0)
    parts = _segments(links)
    parent, frame = builder.bodies[joint.parent], builder.ground_frames[joint.parent]
    placed: set[int] = set()  # coordinates whose MuJoCo joint is made
    armature: list[tuple[str, float, float, str]] = []
    lines_up = any(link.fixed is None and link.coordinate == 0 and abs(link.scale) == 2.0 for link in links)
    driven = 0
    for n, part in enumerate(parts):
        x = chain_transform([Link(link.at(q0)) for link in part], q0)
        body = _add_body(builder, joint, parent, x, n, n == len(parts) - 1)
        rest = [Link(link.at(q0)) for later in parts[n + 1:] for link in later]
        for i, link in enumerate(part):
            if link.fixed is not None:
                continue
            suffix = chain_transform([Link(lk.at(q0)) for lk in part[i + 1:]], q0)
            axis, anchor = suffix.rot.T @ link.axis, -suffix.rot.T @ suffix.pos
            ax = joint.rotations[link.coordinate]
            if abs(link.scale) == 1.0 and link.coordinate not in placed:
                placed.add(link.coordinate)
                builder._add_mj_joint(body, joint, ax, "hinge", link.scale * axis, anchor, q0[link.coordinate])
                continue
            driven += 1
            hinge = TransformAxis(f"ellipsoid{driven}", "rotation", axis, ax.coordinate, LinearFunction(link.scale),
                                  joint.element)
            builder._add_mj_joint(body, joint, hinge, "hinge", axis, anchor, link.scale * q0[link.coordinate])
            if lines_up:
                value = CHAIN_ARMATURE * _hinge_inertia(builder, joint, suffix @ chain_transform(rest, q0),
                                                             link.axis)
                builder.spec.joint(f"{joint.name}_{hinge.name}").armature = value
                armature.append((f"{joint.name}_{hinge.name}", value, link.scale, ax.coordinate))
        parent, frame = body, frame @ x
    builder.bodies[joint.child] = parent
    builder.ground_frames[joint.child] = frame
    _record(builder, joint, links, q0, len(parts) - 1, driven, armature)


def _intermediate_name(builder, joint: Joint, n: int) -> str:
    taken = set(builder.skel.bodies) | {b.name for b in builder.spec.bodies}
    name, i = f"{joint.child}_ellipsoid" + (str(n) if n else ""), 1
    while name in taken:
        name, i = f"{joint.child}_ellipsoid{n}_{i}", i + 1
    return name


def _record(builder, joint: Joint, links: list[Link], q0: list[float], extra_bodies: int, driven: int,
            armature: list[tuple[str, float, float, str]]) -> None:
    """Note the chain and its error against OpenSim's formula over the coordinates' ranges
    (locked ones at their default); record the driven hinges' armature, if any."""
    ranges = [(v, v) if builder.is_fixed(ax) else builder.fit_range(ax.coordinate, "rotation")
              for ax, v in zip(joint.rotations, q0, strict=True)]
    pos, ang = chain_error(joint, links, ranges)
    hinges = sum(link.fixed is None for link in links)
    radii = " ".join(f"{r:g}" for r in joint.surface.radii)
    where = (f", the first on {extra_bodies} intermediate body ({COUPLINGS_BODY_MASS:g} kg, no geometry)"
             if extra_bodies else "")
    builder.result.notes.append(
        f"joint '{joint.name}' ({joint.type}, ellipsoid radii {radii} m in its mobilizer frame) is a chain of "
        f"{hinges} hinges, {driven} of them driven by linear joint equalities{where}: exact; checked against "
        f"OpenSim's formula on {CHECK_SAMPLES}^{len(joint.rotations)} poses over the coordinates' ranges: worst "
        f"{pos * 1e3:.2g} mm, {np.degrees(ang):.2g} deg")
    if not armature:
        return
    added: dict[str, float] = {}
    for _, value, scale, coord in armature:
        added[coord] = added.get(coord, 0.0) + value * scale ** 2
    builder.result.approximations.append(Approximation(
        joint.type, joint.name, f"armature of the {len(armature)} driven hinges of its chain (keeps the mass matrix "
        f"regular where two hinges line up, at q1 = 0)", max(added.values()), "kg m^2",
        "armature " + ", ".join(f"{name} {value:.3g}" for name, value, _, _ in armature) + f" kg m^2 "
        f"({CHAIN_ARMATURE:g} of the child's own inertia about each), adding at most "
        + ", ".join(f"{v:.3g} kg m^2 to '{c}'" for c, v in added.items())))
