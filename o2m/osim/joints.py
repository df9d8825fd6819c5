"""OpenSim joints in one canonical form, and joints turned round to hang from ground.

Canonical joint form. Every OpenSim joint type is written as OpenSim's CustomJoint writes it:

    X_PB(q) = X_PF · Tr(Σ_k t_k(q) e_k) · R(a1, r1(q)) · R(a2, r2(q)) · R(a3, r3(q)) · X_BM⁻¹

with X_PF the parent frame in the parent body, X_BM the child frame in the child body,
translations t_k along axes e_k of F, and rotations r_i applied about body-fixed axes a_i.
A PinJoint is one rotation about Z, a SliderJoint one translation along X, and so on.

EllipsoidJoint and ScapulothoracicJoint do not fit that form: Simbody's Ellipsoid mobilizer
moves the joint frame's origin over an ellipsoid as it turns (:class:`EllipsoidSurface`). Their
joints keep the coordinates' rotation axes in ``rotations`` (X, Y, Z and the winging axis) and
carry the surface in ``Joint.surface``, which :meth:`Joint.transform` follows exactly.

A model's joints may name any body as parent; OpenSim 4 builds its tree from ground and reverses
a joint that points the other way (a 3.x ``<reverse>`` joint is upgraded to one).
:func:`orient_joints` finds those joints and :func:`reverse_joint` writes each one seen from its
child in the same form.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from lxml import etree

from o2m.osim.document import OsimDocument
from o2m.osim.functions import Function
from o2m.transforms import Transform, axis_angle_matrix

__all__ = ["EllipsoidSurface", "Joint", "TransformAxis", "orient_joints", "reverse_joint"]

_X, _Y, _Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


@dataclass
class TransformAxis:
    """One axis of a joint's canonical form; value = ``function(coordinate)``."""

    name: str
    kind: str  # "rotation" or "translation"
    axis: np.ndarray  # (3,) unit vector
    coordinate: str | None
    function: Function
    element: etree._Element

    def value(self, coords: dict[str, float]) -> float:
        x = coords[self.coordinate] if self.coordinate is not None else 0.0
        return float(self.function(np.array([x]))[0])


@dataclass
class EllipsoidSurface:
    """Simbody's Ellipsoid mobilizer inside an EllipsoidJoint or ScapulothoracicJoint.

    With R = Rx(q1) Ry(q2) Rz(q3) (body-fixed X-Y-Z angles, the joint's first three
    coordinates), the mobilizer's M frame sits in its F frame at
    ``X_FM = (R, diag(radii) R e_z)``: on the ellipsoid of semi-axes ``radii`` (m, along F's x,
    y, z) centred on F's origin. A ScapulothoracicJoint turns F by +90 deg about z in its parent
    frame (the thorax's x and y radii swap) and M back by -90 deg, then turns by its fourth
    coordinate (winging) about ``winging_axis`` through ``winging_point``, in that last frame.
    """

    radii: np.ndarray  # (3,) m
    frame: Transform  # F in the joint's parent frame
    after: Transform  # the frame after M, in M
    winging_axis: np.ndarray | None = None  # (3,) unit
    winging_point: np.ndarray | None = None  # (3,) m

    def transform(self, q: list[float]) -> Transform:
        """The frame after the surface (and the winging) in the joint's parent frame, at angles ``q`` (rad)."""
        rot = axis_angle_matrix(np.array(_X), q[0]) @ axis_angle_matrix(np.array(_Y), q[1]) \
            @ axis_angle_matrix(np.array(_Z), q[2])
        out = self.frame @ Transform(rot, self.radii * rot[:, 2]) @ self.after
        if self.winging_axis is not None:
            p = self.winging_point
            out = out @ Transform(pos=p) @ Transform(axis_angle_matrix(self.winging_axis, q[3])) @ Transform(pos=-p)
        return out


@dataclass
class Joint:
    """A joint in canonical form: ``parent_frame`` in ``parent`` and ``child_frame`` in ``child``;
    ``surface`` for the two joint types on Simbody's Ellipsoid mobilizer (module docstring)."""

    name: str
    type: str
    parent: str
    child: str
    parent_frame: Transform
    child_frame: Transform
    rotations: list[TransformAxis]
    translations: list[TransformAxis]
    coordinates: list[str]
    element: etree._Element
    surface: EllipsoidSurface | None = None
    #: True when parent and child are swapped from the document's (:func:`reverse_joint`).
    reversed: bool = False

    def transform(self, coords: dict[str, float]) -> Transform:
        """X_PB: the child body frame in the parent body frame at coordinate values ``coords``."""
        if self.surface is not None:
            inner = self.surface.transform([ax.value(coords) for ax in self.rotations])
            return self.parent_frame @ inner @ self.child_frame.inverse()
        t = sum((ax.value(coords) * ax.axis for ax in self.translations), np.zeros(3))
        rot = np.eye(3)
        for ax in self.rotations:
            rot = rot @ axis_angle_matrix(ax.axis, ax.value(coords))
        return self.parent_frame @ Transform(pos=t) @ Transform(rot=rot) @ self.child_frame.inverse()



def reverse_joint(j: Joint) -> Joint | None:
    """Joint ``j`` seen from its child (X_PB(q)⁻¹, parent and child swapped), in canonical form;
    None when that form cannot hold it: the inverse turns translations-then-rotations into
    rotations-then-translations, canonical only when coordinates move one kind alone. The
    unmoving kind folds into a frame; the moving axes run in reverse order about negated axes."""
    moving = [a for a in j.rotations + j.translations if a.coordinate is not None]
    if j.surface is not None or {a.kind for a in moving} == {"rotation", "translation"}:
        return None  # an ellipsoid's rotations move its translation too

    def flipped(axes: list[TransformAxis], kind: str) -> list[TransformAxis]:
        return [TransformAxis(f"{kind}{i + 1}", kind, -a.axis, a.coordinate, a.function, a.element)
                for i, a in enumerate(reversed(axes))]

    if all(a.kind == "rotation" for a in moving):  # X_BM · R3⁻¹R2⁻¹R1⁻¹ · (X_PF · Tr(t0))⁻¹
        t0 = sum((a.value({}) * a.axis for a in j.translations), np.zeros(3))
        return Joint(j.name, j.type, j.child, j.parent, j.child_frame, j.parent_frame @ Transform(pos=t0),
                     flipped(j.rotations, "rotation"), [], j.coordinates, j.element, reversed=True)
    r0 = np.eye(3)  # X_BM · R0⁻¹ · Tr(-t(q)) · X_PF⁻¹
    for a in j.rotations:
        r0 = r0 @ axis_angle_matrix(a.axis, a.value({}))
    return Joint(j.name, j.type, j.child, j.parent, j.child_frame @ Transform(rot=r0.T), j.parent_frame,
                 [], flipped(j.translations, "translation"), j.coordinates, j.element, reversed=True)


def loop_welds(joints: list[Joint]) -> list[Joint]:
    """The WeldJoints of ``joints`` that close a loop of joints, to hold as weld constraints.

    OpenSim's multibody graph cuts each loop at one of its joints and closes it with a constraint;
    every choice gives the same motion. o2m keeps a spanning tree of the other joints first
    (document order) and cuts at a WeldJoint, which a MuJoCo weld equality holds exactly; a loop
    of other joints alone is left for the builder to refuse."""
    root: dict[str, str] = {}

    def find(body: str) -> str:
        while root.setdefault(body, body) != body:
            body = root[body]
        return body

    cut = []
    for j in sorted(joints, key=lambda j: j.type == "WeldJoint"):  # stable: document order within each kind
        a, b = find(j.parent), find(j.child)
        if a == b and j.type == "WeldJoint":
            cut.append(j)
        root[a] = b
    return [j for j in joints if any(j is c for c in cut)]


def orient_joints(joints: list[Joint], doc: OsimDocument) -> list[Joint]:
    """``joints`` (same order), each reversed whose child is reached from ground before its parent.

    OpenSim 4 builds its tree from ground and reverses such a joint itself (a 3.x ``<reverse>``
    joint is upgraded to one); in a tree every body is the child of its own joint, so nothing
    else changes. Joints that close a loop or hang from nothing are left for the builder to refuse."""
    out = {id(j): j for j in joints}
    placed, pending = {"ground"}, list(joints)
    while True:
        ready = [j for j in pending if (j.parent in placed) != (j.child in placed)]
        if not ready:
            return [out[id(j)] for j in joints]
        for j in ready:
            if j.parent in placed:
                placed.add(j.child)
            else:
                r = reverse_joint(j)
                if r is None:
                    raise doc.error(j.element, f"is reversed (its child '{j.child}' is nearer ground than its "
                                               f"parent '{j.parent}') and its coordinates move both rotations and "
                                               "translations, which o2m cannot reverse")
                out[id(j)] = r
                placed.add(j.parent)
            pending.remove(j)
