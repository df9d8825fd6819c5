"""Helpers the tests share: the model mirror, conversion options, approximation budgets.

The tests are an edge of o2m, so they read the environment here: ``O2M_MODEL_MIRROR`` (a local
copy of the models) and ``O2M_QUICK`` (CI's quick wrap fits).
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import mujoco
import numpy as np
import pytest

from o2m import models
from o2m.convert import ConvertOptions
from o2m.errors import FetchError

#: CI's quick mode: the converter's quick wrap-fit sizes, the notebooks' small budgets.
QUICK = os.environ.get("O2M_QUICK", "") not in ("", "0")


def convert_options(**kw) -> ConvertOptions:
    """:class:`ConvertOptions` with ``quick`` as this test run's mode, and ``kw`` on top."""
    return ConvertOptions(**{"quick": QUICK, **kw})


#: A local copy of the third-party models CI lays beside the clone (``shared/models``).
MIRROR_CANDIDATES = [Path(__file__).resolve().parents[2] / "shared" / "models"]
#: A small registry file that tells whether the models can be had at all.
PROBE = "opensim-models/Models/Arm26/arm26.osim"


def local_mirror() -> Path | None:
    """A local folder copy of the models: ``$O2M_MODEL_MIRROR`` when it is a folder, else
    ``shared/models`` beside the clone; None when there is none (the models are then downloaded)."""
    env = os.environ.get("O2M_MODEL_MIRROR")
    if env:
        return None if env.startswith(("http://", "https://")) else Path(env)
    return next((p for p in MIRROR_CANDIDATES if (p / "registry.tsv").exists()), None)


@functools.cache
def _unavailable() -> str | None:
    try:
        models.fetch(PROBE)
    except FetchError as exc:
        return (f"the models can be neither copied from a mirror nor downloaded ({exc}); connect to the "
                "internet or set O2M_MODEL_MIRROR to a local copy laid out like o2m/registry.tsv")
    return None


def require_models() -> None:
    """Skip only when the models cannot be had: no mirror and no download. A fresh machine with
    internet fetches them from the registry's public URLs (hash-checked, cached)."""
    reason = _unavailable()
    if reason:
        pytest.skip(reason)


def model_file(registry_path: str) -> Path:
    """The cached copy of one registry file (fetched from the mirror or its URL)."""
    require_models()
    return models.fetch(registry_path)


def approximation_budget(xml, approximations) -> dict[str, tuple[float, float]]:
    """Per body: (position, angle) error allowed by the recorded fits of the joints above it.

    A slide fit adds its error (m) to the position; a hinge fit adds its error (rad) to the
    angle and, times 1 m (longer than any limb segment chain here), to the position.
    """
    m = mujoco.MjModel.from_xml_path(str(xml))
    per_joint = {a.joint: a for a in approximations if a.joint}
    own = np.zeros((m.nbody, 2))
    for j in range(m.njnt):
        a = per_joint.get(m.joint(j).name)
        if a is None:
            continue
        b = m.jnt_bodyid[j]
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
            own[b, 0] += a.max_error
        else:
            own[b] += (a.max_error * 1.0, a.max_error)
    total = own.copy()
    for b in range(1, m.nbody):  # parents come before children in MuJoCo's body order
        total[b] += total[m.body_parentid[b]]
    return {m.body(b).name: (float(total[b, 0]), float(total[b, 1])) for b in range(1, m.nbody)}


#: A one-muscle pendulum: a hinge lifted by a straight tendon whose moment arm changes with the angle.
MUSCLE_PENDULUM = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="link" pos="0 0 1">
      <joint name="swing" type="hinge" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.03" mass="1"/>
      <site name="tip" pos="0.5 0 0"/>
    </body>
    <site name="anchor" pos="0.3 0 1.4"/>
  </worldbody>
  <tendon><spatial name="lifter"><site site="anchor"/><site site="tip"/></spatial></tendon>
  <actuator><muscle name="lifter" tendon="lifter" force="40" lengthrange="0.3 0.9"/></actuator>
</mujoco>
"""


def pendulum_fibre(slack: float, force: float):
    """An :class:`o2m.osim.fibres.PassiveFibre` for MUSCLE_PENDULUM's "lifter": a stiff linear tendon
    ``slack`` m long, 0.2 m of optimal fibre, no pennation, Schutte's exponential passive curve,
    max isometric ``force`` N."""
    import numpy as np

    from o2m.osim.fibres import FIBRE_GRID, STRAIN_GRID, PassiveFibre

    passive = np.exp(8.0 * (FIBRE_GRID - 1.0)) / np.exp(4.0)
    return PassiveFibre("lifter", force, 0.2, slack, 0.0, 20.0 * STRAIN_GRID, passive)


def pin_pendulum(name: str, q_range: tuple[float, float] = (-1.0, 1.5),
                 arm_com: tuple[float, float, float] = (0.15, 0.0, 0.0)):
    """An OpenSim model ``name``: ground -> body "arm" (1 kg, centre of mass ``arm_com`` m,
    inertia 0.01 kg m²) on PinJoint "pin" at the origin, whose coordinate "q" has range
    ``q_range`` (rad). Returns ``(model, arm)``."""
    import opensim as osim

    m = osim.Model()
    m.setName(name)
    arm = osim.Body("arm", 1.0, osim.Vec3(*arm_com), osim.Inertia(0.01, 0.01, 0.01))
    m.addBody(arm)
    j = osim.PinJoint("pin", m.getGround(), osim.Vec3(0), osim.Vec3(0), arm, osim.Vec3(0), osim.Vec3(0))
    c = j.updCoordinate()
    c.setName("q")
    c.setRangeMin(q_range[0])
    c.setRangeMax(q_range[1])
    m.addJoint(j)
    return m, arm


def arm_path_actuator(model, arm, end: str):
    """A PathActuator "m" (optimal force 100 N) of ``model`` from P1 on the ground at (-0.2, 0, 0)
    to the point ``end`` at (0.3, 0, 0) on ``arm`` (m), not yet added to the model."""
    import opensim as osim

    pa = osim.PathActuator()
    pa.setName("m")
    pa.setOptimalForce(100)
    pa.addNewPathPoint("P1", model.getGround(), osim.Vec3(-0.2, 0.0, 0))
    pa.addNewPathPoint(end, arm, osim.Vec3(0.3, 0.0, 0))
    return pa


def pendulum_lengths(osim_path, xml, qs):
    """OpenSim's and MuJoCo's lengths (m) of the path actuator "m" of a :func:`pin_pendulum`
    model and its conversion ``xml`` at the angles ``qs`` (rad) of "q" (MuJoCo's joints driven
    by equalities follow, as :func:`o2m.mj.posing.pose_mujoco` poses them)."""
    import opensim as osim

    from o2m.mj.posing import pose_mujoco

    model = osim.Model(str(osim_path))
    state = model.initSystem()
    pa = osim.PathActuator.safeDownCast(model.getForceSet().get("m"))
    coord = model.getCoordinateSet().get("q")
    m = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(m)
    l_os, l_mj = [], []
    for q in qs:
        coord.setValue(state, float(q))
        model.realizePosition(state)
        l_os.append(pa.getLength(state))
        pose_mujoco(m, d, {"q": float(q)})
        mujoco.mj_tendon(m, d)
        l_mj.append(d.ten_length[m.tendon("m").id])
    return np.array(l_os), np.array(l_mj)


def with_moving_point(text: str, point: str, body: str, locations: tuple[str, str, str]) -> str:
    """The .osim ``text`` with PathPoint ``point`` made a MovingPathPoint on ``body`` whose x, y
    and z locations are the function elements ``locations`` (XML text, m), each driven by the
    coordinate /jointset/pin/q (as text: simpler than OpenSim's API)."""
    i = text.index(f'<PathPoint name="{point}">')
    k = text.index("</PathPoint>", i) + len("</PathPoint>")
    sockets = "".join(f"<socket_{a}_coordinate>/jointset/pin/q</socket_{a}_coordinate>" for a in "xyz")
    functions = "".join(f"<{a}_location>{f}</{a}_location>" for a, f in zip("xyz", locations, strict=True))
    return (text[:i] + f'<MovingPathPoint name="{point}"><socket_parent_frame>/bodyset/{body}'
            f"</socket_parent_frame>{sockets}{functions}</MovingPathPoint>" + text[k:])


def add_three_point_paths(model, arm, names) -> None:
    """A PathActuator (optimal force 100 N) per name in ``names``, through ``<name>-P1`` (-0.2,
    0.05, 0) on ground and ``<name>-P2`` (0.1, 0.03, 0) and ``<name>-P3`` (0.3, 0, 0) on ``arm`` (m)."""
    import opensim as osim

    for name in names:
        pa = osim.PathActuator()
        pa.setName(name)
        pa.setOptimalForce(100)
        pa.addNewPathPoint(f"{name}-P1", model.getGround(), osim.Vec3(-0.2, 0.05, 0))
        pa.addNewPathPoint(f"{name}-P2", arm, osim.Vec3(0.1, 0.03, 0))
        pa.addNewPathPoint(f"{name}-P3", arm, osim.Vec3(0.3, 0.0, 0))
        model.addForce(pa)


def add_coupler(model, name: str, independent: str, dependent: str, function) -> None:
    """Add to the OpenSim ``model`` a CoordinateCouplerConstraint ``name``: ``dependent`` =
    ``function``(``independent``)."""
    import opensim as osim

    cc = osim.CoordinateCouplerConstraint()
    cc.setName(name)
    names = osim.ArrayStr()
    names.append(independent)
    cc.setIndependentCoordinateNames(names)
    cc.setDependentCoordinateName(dependent)
    cc.setFunction(function)
    model.addConstraint(cc)


def slider_model(name: str, *, gravity: bool = True):
    """An OpenSim model ``name`` with one 1-kg body on a slider along ground X (range ±0.05 m);
    returns (model, body). Gravity off with ``gravity`` False."""
    import opensim as osim

    m = osim.Model()
    m.setName(name)
    if not gravity:
        m.setGravity(osim.Vec3(0))
    b = osim.Body("b", 1.0, osim.Vec3(0), osim.Inertia(0.01))
    m.addBody(b)
    joint = osim.SliderJoint("s", m.getGround(), osim.Vec3(0), osim.Vec3(0), b, osim.Vec3(0), osim.Vec3(0))
    joint.upd_coordinates(0).setRangeMin(-0.05)
    joint.upd_coordinates(0).setRangeMax(0.05)
    m.addJoint(joint)
    return m, b


def arm_and_block(name: str, arm_angle: float, block_pose) -> tuple:
    """An OpenSim model ``name``: a 1-kg arm pinned to ground at ``arm_angle`` (rad about Z) and a
    0.5-kg block on a free joint at ``block_pose`` (rotations X Y Z in rad, then position in m);
    returns (model, arm, block), for a test to add the constraint between them."""
    import opensim as osim

    m = osim.Model()
    m.setName(name)
    arm = osim.Body("arm", 1.0, osim.Vec3(0, -0.25, 0), osim.Inertia(0.02, 0.002, 0.02))
    block = osim.Body("block", 0.5, osim.Vec3(0), osim.Inertia(0.001, 0.002, 0.003))
    m.addBody(arm)
    m.addBody(block)
    pin = osim.PinJoint("pin", m.getGround(), osim.Vec3(0), osim.Vec3(0), arm, osim.Vec3(0), osim.Vec3(0))
    free = osim.FreeJoint("free", m.getGround(), osim.Vec3(0), osim.Vec3(0), block, osim.Vec3(0), osim.Vec3(0))
    m.addJoint(pin)
    m.addJoint(free)
    pin.upd_coordinates(0).setDefaultValue(arm_angle)
    for i, v in enumerate(block_pose):
        free.upd_coordinates(i).setDefaultValue(float(v))
    return m, arm, block


#: MJCF: one hinge; tendon ``m`` runs from site ``a`` round sphere ``g`` (side site ``s`` below it)
#: to site ``c`` on the turning body, wrapping the sphere over part of the range.
ONE_HINGE_SPHERE_TENDON = """<mujoco><worldbody><site name="a" pos="0 0 0.1"/><geom name="g" type="sphere" size="0.02"
  pos="0.05 0 0.02" contype="0" conaffinity="0"/><site name="s" pos="0.05 0 -0.04"/>
  <body name="b" pos="0.1 0 0"><joint name="q" axis="0 1 0"/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>
  <site name="c" pos="0 0 -0.1"/></body>
  </worldbody><tendon><spatial name="m"><site site="a"/><geom geom="g" sidesite="s"/><site site="c"/>
  </spatial></tendon></mujoco>"""
