"""Massless moving bodies: refused where OpenSim refuses them, reported where it accepts them.

MuJoCo needs mass on every body that moves, so :class:`~o2m.convert.builder.MjcfBuilder` gives a
massless moving body :data:`~o2m.convert.inertials.MIN_MASS` kg. That is harmless where the body
carries massive bodies, but a moving body that carries no mass at all (none of its own, none below
it) then has an inertia of about 1e-8: any force on it (a muscle's, a spring's) accelerates it by
1e8 times that force and the simulation diverges. OpenSim 4.6 refuses some such models ("massless
but not internal and not welded to a massful body") and accepts others (WristModel, massless
throughout, is a kinematic model). o2m asks OpenSim: what it refuses, o2m refuses with an error
naming the body and its line; what it accepts converts, with a warning per body in the report.
"""

from __future__ import annotations

from pathlib import Path

from o2m.convert.builder import MjcfBuilder
from o2m.convert.inertials import MIN_MASS
from o2m.errors import ModelFileError
from o2m.osim import runtime
from o2m.osim.document import opensim_reason
from o2m.osim.skeleton import Body, Skeleton


def massless_moving(skel: Skeleton, builder: MjcfBuilder) -> list[Body]:
    """The bodies whose joint moves (has an axis that is not fixed) and that carry less than
    :data:`~o2m.convert.inertials.MIN_MASS` kg in all (their own mass and every body below them)."""
    children: dict[str, list[str]] = {}
    joint_of = {}
    for j in skel.joints:
        children.setdefault(j.parent, []).append(j.child)
        joint_of[j.child] = j
    out = []
    for name, body in skel.bodies.items():
        j = joint_of.get(name)
        if j is None or all(builder.is_fixed(ax) for ax in j.rotations + j.translations):
            continue
        if _subtree_mass(skel, children, name) < MIN_MASS:
            out.append(body)
    return out


def _subtree_mass(skel: Skeleton, children: dict[str, list[str]], root: str) -> float:
    """The mass (kg) of body ``root`` and every body below it (walked without recursion)."""
    total, todo, seen = 0.0, [root], set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        total += skel.bodies[name].mass if name in skel.bodies else 0.0
        todo.extend(children.get(name, []))
    return total


def check_massless(skel: Skeleton, builder: MjcfBuilder, osim: Path) -> list[str]:
    """Raise an error naming the first massless moving body (:func:`massless_moving`) when OpenSim
    refuses the model for its massless bodies; else one warning per such body (none usually)."""
    bodies = massless_moving(skel, builder)
    if not bodies:
        return []
    try:
        runtime.load_model(osim)
    except ModelFileError as exc:
        component, reason = opensim_reason(exc)
        named = component.rsplit("/", 1)[-1] if component and component.startswith("/bodyset/") else None
        body = next((b for b in bodies if b.name == named), bodies[0])
        raise skel.document.error(body.element, f"moves and carries no mass (none of its own, none below it), "
                                                f"which MuJoCo cannot simulate; OpenSim 4.6 refuses the model "
                                                f"too: {reason}") from None
    return [f"Body {b.name}: moves and carries no mass (OpenSim accepts it): MuJoCo gives it {MIN_MASS:g} kg, "
            f"and any force on it makes the simulation diverge (a model for kinematics only)" for b in bodies]
