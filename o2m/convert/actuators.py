"""Coordinate, torque, point and point-to-point actuators as MuJoCo motors and transmissions.

* **CoordinateActuator**: a motor on the coordinate's joint, ``gear = optimal_force``. On a
  rotational coordinate of a Ball, Free or Ellipsoid joint, whose Simbody mobility is an angular
  velocity component in the joint's parent frame F (not an angle's rate), a site transmission
  with a refsite at F instead: the torque ``optimal_force`` about F's axis on the child, its
  opposite on the parent (a motor on the hinge would turn with the hinges before it).
* **ActivationCoordinateActuator**: the same motor with OpenSim's first-order activation, MuJoCo's
  ``filter`` dynamics: ``act' = (ctrl - act) / activation_time_constant``, force ``gear · act``.
* **PointToPointActuator**: a motor on a spatial tendon between its two points, ``gear =
  optimal_force``: OpenSim pushes the points apart along their line by a positive force, as a
  positive tendon force lengthens a MuJoCo tendon.
* **PathActuator**: a motor on its path's tendon (built by :mod:`o2m.convert.tendons`), ``gear =
  -optimal_force``: OpenSim's tension ``control · optimal_force`` pulls the path's points
  together, as a negative MuJoCo tendon force does.
* **TorqueActuator**: a site transmission with ``refsite``: the torque ``optimal_force ·
  axis`` on bodyA, its opposite on bodyB. Exact when the axis is fixed in bodyA
  (``torque_is_global`` false) or when one body is ground; a global axis between two moving
  bodies is fixed in bodyA as at the default pose (the report gives how far it turns away).
* **PointActuator**: a site at the point with a force gear, in the body frame, or in the world
  frame through a ``refsite`` on the world when ``force_is_global``. A global point (fixed in
  ground, sliding over the body) is fixed in the body where it is at the default pose (the
  report gives how far it moves).

Actuators are named as in OpenSim; ``min_control`` and ``max_control`` become ``ctrlrange`` when
both are finite. Forces in newtons, torques in newton metres.
"""

from __future__ import annotations

import mujoco
import numpy as np
from lxml import etree

from o2m.convert.builder import MjcfBuilder
from o2m.convert.force_context import (
    N_POSES,
    ForceConversion,
    PoseDrift,
    _Context,
    _coordinate,
    _flag,
    _number,
    _random_values,
    _text,
    _vector,
    angular_velocity_coordinate,
    note_force_on_hinge,
)
from o2m.convert.records import Approximation
from o2m.osim.skeleton import Skipped
from o2m.transforms import OSIM_TO_MJ, Transform

__all__ = ["convert_activation_coordinate_actuator", "convert_coordinate_actuator", "convert_path_actuator",
           "convert_point_actuator", "convert_point_to_point_actuator", "convert_torque_actuator", "measure_drifts"]


def _frame_by_name(ctx: _Context, el: etree._Element, prop: str) -> tuple[str, Transform]:
    """(body, frame in body) of the PhysicalFrame a TorqueActuator/PointActuator property names."""
    target = _text(el, prop)
    if not target:
        raise ctx.builder.doc.error(el, f"has no <{prop}>")
    last = target.rstrip("/").split("/")[-1]
    if last == "ground":
        return "ground", Transform()
    found = [f for f in ctx.reader.model.iter("Body", "PhysicalOffsetFrame", "Ground") if f.get("name") == last]
    bodies = [f for f in found if f.tag == "Body"]
    pick = bodies if len(bodies) == 1 else found
    if len(pick) != 1:
        why = "no frame has that name" if not pick else f"{len(pick)} frames share that name"
        raise ctx.builder.doc.error(el, f"<{prop}> names '{target}', which cannot be resolved: {why}")
    body, x, _ = ctx.reader.frame(pick[0])
    return body, x


def _body_site(ctx: _Context, body: str, name: str, pos: np.ndarray, quat: np.ndarray | None = None) -> str:
    """Add a site to ``body`` (OpenSim body frame; ground: the world); returns its name."""
    name = ctx.unique("site", name)
    quat = np.array([1.0, 0, 0, 0]) if quat is None else np.asarray(quat, dtype=float)
    pos = OSIM_TO_MJ @ pos if body == "ground" else np.asarray(pos, dtype=float)
    ctx.builder.bodies[body].add_site(name=name, pos=pos, quat=quat, size=[0.004, 0, 0], group=5,
                                      rgba=[0.9, 0.6, 0.1, 1])
    ctx.builder.exact[("site", name)] = {"pos": pos, "quat": quat}
    return name


def _add_actuator(ctx: _Context, el: etree._Element, gear: np.ndarray, **target) -> mujoco.MjsActuator:
    name = el.get("name")
    act = ctx.spec.add_actuator(name=name, **target)
    act.gear = [float(g) for g in gear]
    lo, hi = _number(el, "min_control", -np.inf, ctx), _number(el, "max_control", np.inf, ctx)
    if np.isfinite(lo) and np.isfinite(hi):
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrlrange = [lo, hi]
    else:
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        if np.isfinite(lo) or np.isfinite(hi):
            ctx.builder.result.notes.append(f"{el.tag} '{name}': one-sided control range [{lo:g}, {hi:g}] left "
                                            "unlimited (MuJoCo's ctrlrange has two ends)")
    ctx.out.exact[("actuator", name)] = {"gear": np.asarray(gear, dtype=float)}
    ctx.out.actuators.append(name)
    return act


def convert_coordinate_actuator(ctx: _Context, el: etree._Element) -> None:
    """CoordinateActuator -> a motor on the coordinate's joint, gear = optimal_force (a torque about the
    parent frame's axis on a Ball, Free or Ellipsoid joint's rotation: :func:`_mobility_torque`)."""
    b = ctx.builder
    cname = _coordinate(ctx, el)
    if cname not in b.skel.coordinates:
        raise b.doc.error(el, f"actuates coordinate '{cname}', which no joint defines")
    if cname not in b.coord_joint or b.skel.coordinates[cname].locked:
        ctx.out.skipped.append(Skipped(el.tag, el.get("name"), f"coordinate '{cname}' is locked, so the actuator "
                                       "cannot move it (no MuJoCo joint)"))
        return
    force = _number(el, "optimal_force", 1.0, ctx)
    mobility = angular_velocity_coordinate(ctx, cname)
    if mobility is not None and not mobility[0].reversed:
        _mobility_torque(ctx, el, *mobility, force)
        return
    note_force_on_hinge(ctx, el, cname, "a motor")  # a reversed joint's: its mobility is the child's
    _add_actuator(ctx, el, np.array([force, 0, 0, 0, 0, 0]), trntype=mujoco.mjtTrn.mjTRN_JOINT, target=cname)


def _mobility_torque(ctx: _Context, el: etree._Element, joint, i: int, force: float) -> None:
    """The actuator of rotational coordinate ``i`` of a Ball, Free or Ellipsoid ``joint``: a torque ``force``
    (N m per unit control) about axis i of the joint's parent frame F on the child, its opposite on
    the parent, as Simbody applies a force to that mobility (a site transmission with a refsite at F)."""
    name = el.get("name")
    axis = joint.parent_frame.rot[:, i]  # F's axis i in the parent body's frame
    ref = _body_site(ctx, joint.parent, f"{name}_refsite", joint.parent_frame.pos)
    site = _body_site(ctx, joint.child, f"{name}_site", joint.child_frame.pos)
    # MuJoCo puts +R_ref·gear on the site's body (the child); the refsite's frame is the parent body's
    gear = force * (OSIM_TO_MJ @ axis if joint.parent == "ground" else axis)
    _add_actuator(ctx, el, np.r_[np.zeros(3), gear], trntype=mujoco.mjtTrn.mjTRN_SITE, target=site, refsite=ref)


def convert_activation_coordinate_actuator(ctx: _Context, el: etree._Element) -> None:
    """ActivationCoordinateActuator -> the CoordinateActuator's motor with a ``filter`` activation
    of time constant ``activation_time_constant`` (s, OpenSim's default 0.01)."""
    tau = _number(el, "activation_time_constant", 0.01, ctx)
    if not (np.isfinite(tau) and tau > 0):
        raise ctx.builder.doc.error(el, f"has <activation_time_constant> {tau:g}; it must be a positive time (s)")
    count = len(ctx.out.actuators)
    convert_coordinate_actuator(ctx, el)
    if len(ctx.out.actuators) == count:
        return  # skipped: a locked coordinate
    act = ctx.spec.actuator(el.get("name"))
    act.dyntype = mujoco.mjtDyn.mjDYN_FILTER
    act.dynprm = [tau] + [0.0] * (len(act.dynprm) - 1)
    start = _number(el, "default_activation", 0.5, ctx)
    if start != 0.0:
        ctx.builder.result.activations[el.get("name")] = start
        ctx.builder.result.notes.append(f"{el.tag} '{el.get('name')}': OpenSim starts its activation at {start:g}; "
                                        "so does the 'default-pose' keyframe's act (mj_resetData starts it at 0)")


def convert_path_actuator(ctx: _Context, el: etree._Element) -> None:
    """PathActuator -> a motor on its path's tendon, gear = -optimal_force (a pull for control > 0)."""
    name = ctx.path_tendon(el)
    if name is None:
        ctx.out.skipped.append(Skipped(el.tag, el.get("name"), "its path became no MuJoCo tendon"))
        return
    gear = np.array([-_number(el, "optimal_force", 1.0, ctx), 0, 0, 0, 0, 0])
    _add_actuator(ctx, el, gear, trntype=mujoco.mjtTrn.mjTRN_TENDON, target=name)


def convert_point_to_point_actuator(ctx: _Context, el: etree._Element) -> None:
    """PointToPointActuator -> a motor (gear = optimal_force) on a spatial tendon between its points."""
    name = el.get("name")
    ends = [_frame_by_name(ctx, el, prop) for prop in ("bodyA", "bodyB")]
    if ends[0][0] == ends[1][0]:
        ctx.out.skipped.append(Skipped(el.tag, name, f"both points are on '{ends[0][0]}' (no force between bodies)"))
        return
    if _flag(el, "points_are_global", False):
        ctx.out.skipped.append(Skipped(el.tag, name, "its points are fixed in ground and slide over the bodies "
                                       "(points_are_global), which no MuJoCo site does"))
        return
    sites = [_body_site(ctx, body, f"{name}_point{tag}", x.apply(_vector(el, f"point{tag}", (0.0, 0.0, 0.0), ctx)))
             for (body, x), tag in zip(ends, "AB", strict=True)]
    tendon = ctx.spec.add_tendon(name=ctx.unique("tendon", name))
    for site in sites:
        tendon.wrap_site(site)
    tendon.rgba = [0.9, 0.6, 0.1, 1.0]
    gear = np.array([_number(el, "optimal_force", 1.0, ctx), 0, 0, 0, 0, 0])
    _add_actuator(ctx, el, gear, trntype=mujoco.mjtTrn.mjTRN_TENDON, target=tendon.name)


def convert_torque_actuator(ctx: _Context, el: etree._Element) -> None:
    """TorqueActuator -> a site transmission with a refsite (torque on bodyA, reaction on bodyB)."""
    b = ctx.builder
    name = el.get("name")
    body_a, x_a = _frame_by_name(ctx, el, "bodyA")
    body_b, _ = _frame_by_name(ctx, el, "bodyB")
    axis = _vector(el, "axis", (0.0, 0.0, 1.0), ctx)
    if np.linalg.norm(axis) < 1e-12:
        raise b.doc.error(el, "has a zero <axis>")
    axis = axis / np.linalg.norm(axis)
    force = _number(el, "optimal_force", 1.0, ctx)
    is_global = _flag(el, "torque_is_global", True)
    if body_a == body_b:
        ctx.out.skipped.append(Skipped(el.tag, name, f"bodyA and bodyB are both '{body_a}' (no net torque)"))
        return
    local_axis = x_a.rot @ axis  # in bodyA's body frame, when not global
    if not is_global and body_a != "ground":
        # axis fixed in bodyA: refsite on A; MuJoCo puts +R_ref·gear on the site's body (B), so negate
        ref = _body_site(ctx, body_a, f"{name}_refsite", np.zeros(3))
        site = _body_site(ctx, body_b, f"{name}_site", np.zeros(3))
        gear_rot = -force * local_axis
    else:
        ground_axis = axis if is_global else local_axis  # bodyA is ground when not global here
        if body_b == "ground" or body_a == "ground":
            ref = _body_site(ctx, "ground", f"{name}_refsite", np.zeros(3))
            on, sign = (body_a, 1.0) if body_b == "ground" else (body_b, -1.0)
            site = _body_site(ctx, on, f"{name}_site", np.zeros(3))
            gear_rot = sign * force * (OSIM_TO_MJ @ ground_axis)
        else:  # a ground-fixed axis between two moving bodies: fixed in bodyA as at the default pose
            local = b.ground_frames[body_a].rot.T @ ground_axis
            ref = _body_site(ctx, body_a, f"{name}_refsite", np.zeros(3))
            site = _body_site(ctx, body_b, f"{name}_site", np.zeros(3))
            gear_rot = -force * local
            ctx.out.drifts.append(PoseDrift(el.tag, name, f"ground-fixed torque axis fixed in '{body_a}' as at the "
                                            "default pose", body_a, ground_axis, local, "axis"))
    _add_actuator(ctx, el, np.r_[np.zeros(3), gear_rot], trntype=mujoco.mjtTrn.mjTRN_SITE, target=site, refsite=ref)


def convert_point_actuator(ctx: _Context, el: etree._Element) -> None:
    """PointActuator -> a site transmission with a force gear (world frame via a world refsite)."""
    b = ctx.builder
    name = el.get("name")
    body, x = _frame_by_name(ctx, el, "body")
    if body == "ground":
        ctx.out.skipped.append(Skipped(el.tag, name, "acts on ground (no effect)"))
        return
    point = _vector(el, "point", (0.0, 0.0, 0.0), ctx)
    direction = _vector(el, "direction", (1.0, 0.0, 0.0), ctx)
    if np.linalg.norm(direction) < 1e-12:
        raise b.doc.error(el, "has a zero <direction>")
    direction = direction / np.linalg.norm(direction)
    force = _number(el, "optimal_force", 1.0, ctx)
    if _flag(el, "point_is_global", False):
        local = b.ground_frames[body].inverse().apply(point)
        ctx.out.drifts.append(PoseDrift(el.tag, name, "ground-fixed application point fixed in the body as at the "
                                        "default pose", body, point, local, "point"))
    else:
        local = x.apply(point)
    site = _body_site(ctx, body, f"{name}_site", local)
    if _flag(el, "force_is_global", False):
        ref = _body_site(ctx, "ground", f"{name}_refsite", np.zeros(3))
        gear = np.r_[force * (OSIM_TO_MJ @ direction), np.zeros(3)]
        _add_actuator(ctx, el, gear, trntype=mujoco.mjtTrn.mjTRN_SITE, target=site, refsite=ref)
    else:
        gear = np.r_[force * (x.rot @ direction), np.zeros(3)]
        _add_actuator(ctx, el, gear, trntype=mujoco.mjtTrn.mjTRN_SITE, target=site)

def measure_drifts(out: ForceConversion, builder: MjcfBuilder) -> None:
    """Measure how far each global axis or point fixed in a body moves from OpenSim's over random
    poses and record it in ``builder.result.approximations``."""
    result = builder.result
    for dr in out.drifts:
        result.approximations.append(Approximation(
            dr.element, dr.name, dr.what, _measure_drift(dr, builder), "rad" if dr.kind == "axis" else "m",
            f"worst over {N_POSES} poses"))


def _measure_drift(dr: PoseDrift, builder: MjcfBuilder) -> float:
    worst = 0.0
    for values in _random_values(builder, N_POSES):
        frame = builder.ground_frames_at(builder.coordinate_values(values))[dr.body]
        if dr.kind == "axis":
            c = float(np.clip((frame.rot @ dr.local) @ dr.value, -1.0, 1.0))
            worst = max(worst, float(np.arccos(c)))
        else:
            worst = max(worst, float(np.linalg.norm(frame.apply(dr.local) - dr.value)))
    return worst
