"""Chain shortcuts: a body whose pose relative to an ancestor only translates, re-attached to it.

A chain of OpenSim bodies A -> ... -> B whose joints are all moved by one independent coordinate
e (through couplers) puts B at X_AB(e) relative to A. Where the intermediate joints' rotations
cancel (MoBL-ARMS's shoulder rhythm: ``clavphant`` and ``scapphant`` undo the clavicle's and the
scapula's rotations, so ``scapphant`` only translates in the thorax along a curve of
``shoulder_elv``), B's pose is a constant rotation and a translation p(e). B can then hang from A
directly, its joint replaced by slides along p's principal directions driven by e (joint
equalities, fitted as every skeleton coupling is), while the intermediate bodies keep their own
joints. Every body's pose as a function of the independent coordinates is unchanged; B and its
subtree just sit on a shorter chain, so every Jacobian below B runs over fewer degrees of freedom.

The rule applies (:func:`shorten_chains`) where all of these hold:

* every moving axis of B's joint and of the joints above it up to A is driven by the same
  independent coordinate e, and none of B's joint's coordinates is independent or named by a
  force (its MuJoCo joint goes away); A is the first ancestor whose own joint is not moved by
  e alone;
* the chain above B has at least one moving joint (else nothing gets shorter);
* B's orientation in A is constant to :data:`ROTATION_TOLERANCE` over e's range, widened by
  :data:`CHECK_WIDENING` of its width on each side;
* p(e) needs no more slides (directions along which it moves by more than
  :data:`LOCUS_TOLERANCE`) than B's joint has moving axes, and each slide follows e by a plain
  quartic within :data:`~o2m.convert.coupling_plan.COUPLING_TARGET` (a joint equality, no extra
  joints), so the model gets no degree of freedom more.

The new joint keeps the old joint's name and element (errors and the report name it); its slides
are MuJoCo joints ``<joint>_shortcut1..3`` (not ``<joint>_translation1``: that would name an
OpenSim transform axis, whose value they are not), and the old joint's coordinates, all
dependent, get no MuJoCo joint. Units: metres, radians; OpenSim's
frames (Y-up).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from o2m.convert.coordinates import Driver, fit_range, is_fixed
from o2m.convert.coupling_plan import COUPLING_TARGET
from o2m.convert.polyfit import fit_polynomial
from o2m.osim.skeleton import Joint, Skeleton, TransformAxis
from o2m.transforms import Transform

#: Largest change (rad, as the largest element of R(e) - R(e_ref)) of B's orientation in A over
#: the checked range for which the orientation counts as constant: rounding only.
ROTATION_TOLERANCE = 1e-9
#: Largest motion (m) of p(e) across a direction for which that direction needs no slide.
LOCUS_TOLERANCE = 1e-9
#: The checked range is e's fitting range widened by this fraction of its width on each side.
CHECK_WIDENING = 0.5
#: Samples of e for the checks.
CHECK_SAMPLES = 201
_KEPT_SAMPLE_SETS = 16


class ChainOrigins:
    """B's origin in A (n, 3), m, at values ``x`` (n,) of the chain's independent coordinate; the
    last few sample sets are kept, as the coupling fits evaluate the slides on the same grids."""

    def __init__(self, chain: list[Joint], drivers: dict[str, Driver], defaults: dict[str, float]):
        self.chain, self.drivers, self.defaults = chain, drivers, defaults
        self._recent: dict[bytes, np.ndarray] = {}

    def __call__(self, x: np.ndarray) -> np.ndarray:
        key = x.tobytes()
        if key not in self._recent:
            if len(self._recent) >= _KEPT_SAMPLE_SETS:
                self._recent.pop(next(iter(self._recent)))
            self._recent[key] = chain_poses(self.chain, self.drivers, self.defaults, x)[1]
        return self._recent[key]


class ChainTranslation:
    """x -> u · (p(x) - offset): B's origin in A along ``direction`` (3,), m, at values ``x``
    (array) of the chain's independent coordinate."""

    def __init__(self, origins: ChainOrigins, direction: np.ndarray, offset: np.ndarray):
        self.origins, self.direction, self.offset = origins, direction, offset

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        return ((self.origins(x.ravel()) - self.offset) @ self.direction).reshape(x.shape)


def _rotations(axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) for ``angles`` (n,) rad about the unit vector ``axis`` (3,) (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angles)[:, None, None] * k + (1.0 - np.cos(angles))[:, None, None] * (k @ k)


def chain_poses(chain: list[Joint], drivers: dict[str, Driver], defaults: dict[str, float],
                x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations (n, 3, 3) and origins (n, 3) of the chain's last child in its first parent when
    the independent coordinate driving the chain is ``x`` (n,); other coordinates at ``defaults``.
    Each joint in canonical form (:class:`o2m.osim.skeleton.Joint`), for all samples at once."""
    x = np.asarray(x, dtype=float)

    def axis_values(ax: TransformAxis) -> np.ndarray:
        if ax.coordinate is None:
            q = np.zeros(x.shape)
        elif ax.coordinate in defaults:
            q = np.full(x.shape, defaults[ax.coordinate])
        else:
            q = np.asarray(drivers[ax.coordinate].fn(x), dtype=float)
        return np.asarray(ax.function(q), dtype=float).reshape(x.shape)

    rots, poss = np.broadcast_to(np.eye(3), (x.size, 3, 3)), np.zeros((x.size, 3))
    for joint in chain:
        shift = sum((axis_values(ax)[:, None] * ax.axis for ax in joint.translations), np.zeros((x.size, 3)))
        turn = np.broadcast_to(np.eye(3), (x.size, 3, 3))
        for ax in joint.rotations:
            turn = turn @ _rotations(ax.axis, axis_values(ax))
        inner = joint.child_frame.inverse()
        rot = joint.parent_frame.rot @ turn @ inner.rot
        pos = joint.parent_frame.pos + (shift + turn @ inner.pos) @ joint.parent_frame.rot.T
        poss = poss + np.einsum("nij,nj->ni", rots, pos)
        rots = rots @ rot
    return rots, poss


def _moving_bases(skel: Skeleton, drivers: dict[str, Driver], joint: Joint) -> set[str]:
    return {drivers[ax.coordinate].base for ax in joint.rotations + joint.translations
            if not is_fixed(skel, drivers, ax)}


def _moving_count(skel: Skeleton, drivers: dict[str, Driver], joint: Joint) -> int:
    return sum(not is_fixed(skel, drivers, ax) for ax in joint.rotations + joint.translations)


def _named_by_forces(skel: Skeleton, names: set[str]) -> bool:
    """Whether an element of the model's forces names one of the coordinates ``names`` (a
    CoordinateLimitForce, an actuator, a moving or conditional path point): it would need the
    coordinate's MuJoCo joint, which a shortcut removes."""
    if skel.document is None:
        return False
    return any((el.text or "").strip() in names for forces in skel.document.model.iter("ForceSet", "components")
               for el in forces.iter() if isinstance(el.tag, str))


def _chain_above(skel: Skeleton, drivers: dict[str, Driver], by_child: dict[str, Joint],
                 joint: Joint) -> tuple[str, list[Joint]] | None:
    """(e, the joints from A down to ``joint``) when the rule's first two conditions hold, else None."""
    bases = _moving_bases(skel, drivers, joint)
    if len(bases) != 1 or joint.surface is not None:  # chain_poses follows the canonical form only
        return None
    (base,) = bases
    own = [ax.coordinate for ax in joint.rotations + joint.translations if not is_fixed(skel, drivers, ax)]
    if any(drivers[c].base == c for c in own) or _named_by_forces(skel, set(own)):
        return None
    chain = [joint]
    while chain[-1].parent in by_child and _moving_bases(skel, drivers, by_child[chain[-1].parent]) == {base} \
            and by_child[chain[-1].parent].surface is None:
        chain.append(by_child[chain[-1].parent])
    if len(chain) < 2:
        return None
    return base, chain[::-1]


def shortcut_joint(skel: Skeleton, drivers: dict[str, Driver], base: str, chain: list[Joint]) -> Joint | None:
    """The joint that moves ``chain``'s last child directly from its first parent by slides
    driven by ``base``, or None when its orientation there is not constant or its locus needs
    more slides than the last joint has moving axes."""
    coord = skel.coordinates[base]
    lo, hi = fit_range(skel, base, "rotation" if _is_rotational(skel, base) else "translation")
    lo, hi = min(lo, coord.default), max(hi, coord.default)
    widen = CHECK_WIDENING * (hi - lo)
    x = np.linspace(lo - widen, hi + widen, CHECK_SAMPLES)
    defaults = {c.name: c.default for c in skel.coordinates.values() if drivers[c.name].base != base}
    rots, poss = chain_poses(chain, drivers, defaults, x)
    if np.max(np.abs(rots - rots[0])) > ROTATION_TOLERANCE:
        return None
    centre = poss.mean(axis=0)
    _, _, directions = np.linalg.svd(poss - centre)
    spans = np.ptp((poss - centre) @ directions.T, axis=0)
    kept = directions[spans > LOCUS_TOLERANCE]
    joint = chain[-1]
    if len(kept) > _moving_count(skel, drivers, joint):
        return None
    offset = centre - kept.T @ (kept @ centre)  # the locus's constant part, across the kept directions
    origins = ChainOrigins(chain, drivers, defaults)
    slides = [TransformAxis(f"shortcut{k + 1}", "translation", u, base, ChainTranslation(origins, u, offset),
                            joint.element)
              for k, u in enumerate(kept)]
    if any(fit_polynomial(ax.function, lo, hi, coord.default, degree=4, exact_at_x0=True).max_error
           > COUPLING_TARGET["m"] for ax in slides):
        return None
    return replace(joint, parent=chain[0].parent, parent_frame=Transform(pos=offset),
                   child_frame=Transform(rot=rots[0]).inverse(), rotations=[], translations=slides)


def _is_rotational(skel: Skeleton, name: str) -> bool:
    return any(ax.coordinate == name and ax.kind == "rotation" for j in skel.joints for ax in j.rotations)


def shorten_chains(skel: Skeleton, drivers: dict[str, Driver]) -> tuple[Skeleton, list[str]]:
    """``skel`` with every joint the rule (module docstring) applies to replaced by its shortcut,
    parents first; and a note per shortcut for the report."""
    joints = list(skel.joints)
    notes = []
    for i, joint in enumerate(skel.joints):
        by_child = {j.child: j for j in joints}
        found = _chain_above(skel, drivers, by_child, joints[i])
        if found is None:
            continue
        base, chain = found
        short = shortcut_joint(skel, drivers, base, chain)
        if short is None:
            continue
        joints[i] = short
        removed = sum(_moving_count(skel, drivers, j) for j in chain)
        notes.append(f"body '{joint.child}' only translates in '{short.parent}' as '{base}' moves (the rotations of "
                     f"joints {', '.join(j.name for j in chain)} cancel): it hangs from '{short.parent}' by "
                     f"{len(short.translations)} slides of '{base}' instead of a chain of {removed} joint axes")
    return replace(skel, joints=joints), notes
