"""Chain shortcuts (:mod:`o2m.convert.shortcuts`) on small models shaped like MoBL-ARMS's shoulder.

A "clavicle" turns about two axes and a "scapula" about three, each followed by a phantom
body whose joint undoes its rotation (the same axes in reverse order, negated angles), every
angle a linear function of one coordinate ``elv``; an "arm" hangs from the last phantom by a
pin of its own coordinate. The last phantom then only translates in ground as ``elv`` moves:
the converter hangs it from ground by slides, and every body must still be where OpenSim puts
it. Where the phantom's joint does not undo the rotation, or its angles follow another
coordinate, nothing changes.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
from lxml import etree

from o2m.convert.converter import convert
from o2m.convert.coordinates import coordinate_drivers
from o2m.convert.shortcuts import shorten_chains
from o2m.osim.document import load_document
from o2m.osim.skeleton import read_skeleton
from o2m.validate.kinematics import compare_kinematics
from tests.convert.test_joint_types import (
    IDENTITY,
    ZERO,
    Axis,
    Coord,
    CouplerSpec,
    JointSpec,
    build_model,
    linear,
)
from tests.helpers import convert_options

ELV_RANGE = (0.0, 1.2)
#: Body-fixed rotation axes of the clavicle and the scapula (unit length).
CLAV_AXES = [(0.0, 1.0, 0.0), (-0.994, 0.0, -0.105)]
SCAP_AXES = [(0.157, 0.947, -0.279), (-0.754, 0.298, 0.585), (0.638, 0.119, 0.761)]
#: Each rotation angle per radian of elv.
CLAV_RATES = [-0.25, 0.12]
SCAP_RATES = [-0.05, 0.4, 0.18]
#: name -> (mass kg, COM m, inertia xx yy zz xy xz yz kg m^2).
BODIES = {
    "clavicle": (0.16, (0.0, 0.01, 0.06), (2e-4, 2e-4, 4e-5, 0.0, 0.0, 0.0)),
    "clavphant": (0.01, (0.0, 0.0, 0.0), (1e-6, 1e-6, 1e-6, 0.0, 0.0, 0.0)),
    "scapula": (0.7, (-0.05, -0.03, -0.02), (1e-3, 1e-3, 1e-3, 1e-5, 0.0, 0.0)),
    "scapphant": (0.01, (0.0, 0.0, 0.0), (1e-6, 1e-6, 1e-6, 0.0, 0.0, 0.0)),
    "arm": (2.0, (0.0, -0.16, 0.0), (0.012, 0.004, 0.013, 0.0, 0.0, 0.0)),
}
NO_OFFSETS = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


def _rotating(name: str, parent: str, child: str, axes, coords: list[str], offset) -> JointSpec:
    """A CustomJoint turning about ``axes`` (body-fixed, in order) by ``coords``, at ``offset`` in the parent."""
    rot = [Axis(f"rotation{i + 1}", ax, c, IDENTITY) for i, (ax, c) in enumerate(zip(axes, coords, strict=True))]
    rot += [Axis(f"rotation{i + 1}", (1.0, 0.0, 0.0) if i else (0.0, 0.0, 1.0), None, ZERO)
            for i in range(len(axes), 3)]
    trans = [Axis(f"translation{k + 1}", tuple(np.eye(3)[k]), None, ZERO) for k in range(3)]
    return JointSpec(name, "CustomJoint", parent, child, (offset, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
                     [Coord(c, range=(-3.0, 3.0)) for c in coords], rot + trans)


def shoulder(path: Path, *, undo_scale: float = 1.0, second_coordinate: bool = False) -> str:
    """The shoulder model: the phantoms' angles are ``-undo_scale`` times what they undo; with
    ``second_coordinate`` the scapula's angles follow another independent coordinate ``tilt``
    (its phantom's still follow ``elv``)."""
    clav = [f"sc{i}" for i in range(2)]
    scap = [f"ac{i}" for i in range(3)]
    joints = [
        _rotating("sternoclavicular", "ground", "clavicle", CLAV_AXES, clav, (0.006, 0.007, 0.025)),
        _rotating("unrotscap", "clavicle", "clavphant", CLAV_AXES[::-1], [f"u{c}" for c in clav[::-1]],
                  (-0.014, 0.020, 0.136)),
        _rotating("acromioclavicular", "clavphant", "scapula", SCAP_AXES, scap, (0.0, 0.0, 0.0)),
        _rotating("unrothum", "scapula", "scapphant", SCAP_AXES[::-1], [f"u{c}" for c in scap[::-1]],
                  (-0.0096, -0.034, 0.009)),
        JointSpec("shoulder", "PinJoint", "scapphant", "arm", NO_OFFSETS, [Coord("rot", range=(-1.0, 1.0))]),
    ]
    joints.append(JointSpec("elevation", "PinJoint", "ground", "elv_body", NO_OFFSETS,
                            [Coord("elv", range=ELV_RANGE, default=0.5)]))
    joints.append(JointSpec("tilting", "PinJoint", "ground", "tilt_body", NO_OFFSETS,
                            [Coord("tilt", range=ELV_RANGE, default=0.3)]))
    couplers = []
    for names, rates in ((clav, CLAV_RATES), (scap, SCAP_RATES)):
        for c, rate in zip(names, rates, strict=True):
            driver = "tilt" if second_coordinate and c in scap else "elv"
            couplers.append(CouplerSpec(f"{c}_con", c, driver, linear(rate, 0.0)))
            couplers.append(CouplerSpec(f"u{c}_con", f"u{c}", "elv", linear(-undo_scale * rate, 0.0)))
    bodies = dict(BODIES, elv_body=(0.1, (0.0, 0.0, 0.0), (1e-4,) * 3 + (0.0,) * 3),
                  tilt_body=(0.1, (0.0, 0.0, 0.0), (1e-4,) * 3 + (0.0,) * 3))
    return build_model(path / "shoulder.osim", joints, couplers=couplers, bodies=bodies)


def _chain_dofs(model: mujoco.MjModel, body: str) -> int:
    """Degrees of freedom of ``body`` and all its ancestors."""
    b, n = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body), 0
    while b > 0:
        n += int(model.body_dofnum[b])
        b = int(model.body_parentid[b])
    return n


def _convert(osim_path: str, out: Path, **options):
    conv = convert(osim_path, out, convert_options(fit_mechanics=False, fit_wraps=False, **options))
    return conv, mujoco.MjModel.from_xml_path(str(conv.xml))


def test_phantom_chain_gets_shorter_and_keeps_every_pose(tmp_path):
    osim_path = shoulder(tmp_path)
    conv, model = _convert(osim_path, tmp_path / "on")
    _, plain = _convert(osim_path, tmp_path / "off", chain_shortcuts=False)
    scapphant = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "scapphant")
    assert model.body_parentid[scapphant] == 0  # hangs from the world (OpenSim's ground)
    assert _chain_dofs(plain, "arm") == 2 + 2 + 3 + 3 + 1
    assert _chain_dofs(model, "arm") == 3 + 1
    assert model.nv <= plain.nv
    assert any("scapphant" in note and "only translates" in note for note in conv.report.notes)
    slides = [a for a in conv.report.approximations if "unrothum_shortcut" in a.what]
    assert len(slides) == 3
    bound = float(np.sqrt(3.0)) * max(a.max_error for a in slides)
    rep = compare_kinematics(osim_path, conv.xml, n_poses=60, seed=3)
    assert rep.n_poses == 60 and rep.skipped_poses == 0 and rep.missing_bodies == []
    assert 0.0 < bound <= 2e-5
    assert rep.max_pos_error <= bound + 1e-9, rep.summary()
    assert rep.max_ang_error <= 1e-9, rep.summary()


def test_no_shortcut_where_rotations_do_not_cancel(tmp_path):
    conv, model = _convert(shoulder(tmp_path, undo_scale=0.9), tmp_path / "out")
    scapphant = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "scapphant")
    assert model.body(int(model.body_parentid[scapphant])).name == "scapula"
    assert not any("only translates" in note for note in conv.report.notes)


def test_no_shortcut_where_the_chain_follows_two_coordinates(tmp_path):
    conv, model = _convert(shoulder(tmp_path, second_coordinate=True), tmp_path / "out")
    scapphant = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "scapphant")
    assert model.body(int(model.body_parentid[scapphant])).name == "scapula"
    assert _chain_dofs(model, "arm") == 2 + 2 + 3 + 3 + 1


def test_no_shortcut_where_a_force_names_the_removed_coordinates(tmp_path):
    """A CoordinateActuator on one of scapphant's (dependent) coordinates needs its MuJoCo joint."""
    path = Path(shoulder(tmp_path))
    assert shorten_chains(*_skeleton(path))[1]
    tree = etree.parse(str(path))
    (objects,) = tree.getroot().xpath("Model/ForceSet/objects")
    objects.append(etree.fromstring('<CoordinateActuator name="turn"><coordinate>uac1</coordinate>'
                                    "<optimal_force>1</optimal_force></CoordinateActuator>"))
    tree.write(str(path), xml_declaration=True, encoding="UTF-8")
    assert shorten_chains(*_skeleton(path))[1] == []


def _skeleton(path: Path):
    skel = read_skeleton(load_document(path))
    return skel, coordinate_drivers(skel)
