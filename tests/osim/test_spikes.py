"""OpenSim's own path failures that comparisons leave out: detours (o2m.osim.spikes.path_detour),
loops round a wrap (o2m.osim.spikes.path_loop) and windings round one (path_winding).

Spikes and failure bands are tested with the wrap tests (tests/convert/test_wrapping.py).
"""

from __future__ import annotations

import mujoco
import numpy as np

from o2m.osim import runtime
from o2m.osim.spikes import (
    BAND_FRACTION,
    DETOUR_FRACTION,
    FULL_TURN,
    arc_turn,
    current_path_points,
    drawn_length,
    path_detour,
    path_loop,
    path_winding,
    runs_cross,
    wrap_arcs,
    wrap_runs,
)
from tests.helpers import model_file


def _path(*points: tuple[str, str | None, tuple[float, float, float]]) -> list:
    return [(name, wrap, np.array(p, dtype=float)) for name, wrap, p in points]


def test_a_wrap_past_an_inner_point_is_a_detour():
    """P1 -> P2 (0.16 m down) -> P3, with wrap contacts on P1-P2 0.25 m down: the path runs
    past P2 and back (ECRL's shape on MoBL_ARMS_model_for_mujoco.osim)."""
    path = _path(("P1", None, (0, 0, 0)), ("w", "torus", (0.01, -0.25, 0)), ("w", "torus", (0.012, -0.255, 0)),
                 ("P2", None, (0, -0.16, 0)), ("P3", None, (0, -0.26, 0)))
    found = path_detour(path)
    assert found is not None and found["wrap"] == "torus" and found["segment"] == "P1-P2", found
    assert abs(found["beyond"] - (0.255 / 0.16 - 1)) < 1e-9


def test_no_detour_for_a_wrap_between_its_points_or_past_an_end_of_the_path():
    """A wrap bending its segment between its ends, one whose contact lies before the path's
    origin (the origin on the wrap surface: MoBL-ARMS's LAT), and a small overshoot past an
    inner point (under DETOUR_FRACTION) are no detours."""
    between = _path(("P1", None, (0, 0, 0)), ("w", "cyl", (0.02, -0.05, 0)), ("w", "cyl", (0.02, -0.1, 0)),
                    ("P2", None, (0, -0.16, 0)), ("P3", None, (0, -0.26, 0)))
    before_origin = _path(("P1", None, (0, 0, 0)), ("w", "cyl", (0.01, 0.05, 0)), ("P2", None, (0, -0.16, 0)))
    small = 0.5 * DETOUR_FRACTION * 0.16
    just_past = _path(("P1", None, (0, 0, 0)), ("w", "cyl", (0.01, -0.16 - small, 0)),
                      ("P2", None, (0, -0.16, 0)), ("P3", None, (0, -0.26, 0)))
    assert path_detour(between) is None
    assert path_detour(before_origin) is None
    assert path_detour(just_past) is None


def test_mobl_for_mujoco_ecrl_detours_round_the_wrist_torus_in_opensim():
    """The floor behind ECRL's length error on MoBL_ARMS_model_for_mujoco.osim: with the wrist
    flexed, OpenSim wraps ECRL's wrist torus (on proximal_row) on its elbow segment ECRL-P1-P2, the
    path running from the elbow past P2 to the wrist and back; its length is then far above that of
    its path points joined straight, which no tendon through those points can follow."""
    model, state = runtime.load_model(model_file("mobl-arms/MoBL_ARMS_model_for_mujoco.osim"))
    pose = {"elv_angle": 1.231, "shoulder_elv": 0.552, "shoulder_rot": 0.086, "elbow_flexion": 1.229,
            "pro_sup": -0.629, "deviation": 0.084, "flexion": -1.153}
    coordinates = model.getCoordinateSet()
    for name, value in pose.items():
        coordinates.get(name).setValue(state, value, False)
    model.assemble(state)
    model.realizePosition(state)
    points = current_path_points(model, state, "ECRL")
    found = path_detour(points)
    assert found is not None and found["wrap"] == "ECRL" and found["segment"] == "ECRL-P1-ECRL-P2", found
    fixed = np.array([p for _, wrap, p in points if wrap is None])
    straight = float(np.linalg.norm(np.diff(fixed, axis=0), axis=1).sum())
    length = runtime.geometry_path(model, "ECRL").getLength(state)
    assert length > 1.5 * straight, (length, straight)


def _posed(path: str, pose: dict[str, float]):
    model, state = runtime.load_model(model_file(path))
    coordinates = model.getCoordinateSet()
    for name, value in pose.items():
        coordinates.get(name).setValue(state, value, False)
    model.assemble(state)
    model.realizePosition(state)
    return model, state


def _loop_runs(long_way: bool) -> np.ndarray:
    """Runs round a unit circle (axis z) from a point just off it at (0.2, -1.4) to a far point at
    (-10, -9): the short way (tangent points on the near side) or the long way, round the far side
    (the tangents OpenSim's TMAJ takes round TMAJ_LAThum, in units of its radius)."""
    before, after = np.array([0.2, -1.4, 1.3]), np.array([-10.0, -9.0, -7.0])

    def tangent(p: np.ndarray, sign: float) -> np.ndarray:
        d = float(np.hypot(p[0], p[1]))
        ang = np.arctan2(p[1], p[0]) + sign * np.arccos(1.0 / d)
        return np.array([np.cos(ang), np.sin(ang), 0.0])

    s = -1.0 if long_way else 1.0
    return np.array([before, tangent(before, s), tangent(after, -s), after])


def test_runs_that_cross_round_a_cylinder_are_a_loop():
    """The long way round (over half a turn) crosses the runs in the cylinder's cross-section;
    the short way does not. The same points as a sphere's runs are judged on their own plane."""
    assert runs_cross("WrapCylinder", _loop_runs(long_way=True))
    assert not runs_cross("WrapCylinder", _loop_runs(long_way=False))
    flat = _loop_runs(long_way=True) * np.array([1.0, 1.0, 0.0]) + np.array([0.0, 0.0, 1e-3])
    assert runs_cross("WrapSphere", flat)
    found = path_loop([("ring", "WrapTorus", _loop_runs(True)), ("post", "WrapCylinder", _loop_runs(True))])
    assert found == {"wrap": "post", "kind": "WrapCylinder"}, found
    assert path_loop([("post", "WrapCylinder", _loop_runs(False))]) is None


def test_mujoco_refuses_a_wrap_whose_runs_cross():
    """MuJoCo 4.0 never wraps a tendon the long way round a cylinder where the runs would cross,
    whichever side its side site is on (its wrap_circle rejects crossing runs): it leaves it
    straight or takes the short way, so no wrap geom follows such an OpenSim loop."""
    flat = np.array([1.0, 1.0, 0.0])

    def way(long_way: bool) -> float:
        r = _loop_runs(long_way) * flat
        cos = float(np.clip(r[1] @ r[2], -1.0, 1.0))
        arc = 2 * np.pi - np.arccos(cos) if long_way else np.arccos(cos)
        return float(np.linalg.norm(r[1] - r[0]) + arc + np.linalg.norm(r[3] - r[2]))

    runs = _loop_runs(long_way=True) * flat
    straight, short, long = float(np.linalg.norm(runs[3] - runs[0])), way(False), way(True)
    lengths = []
    for side in ((-1.5, 0.0, 0.0), (1.5, 0.0, 0.0), (0.0, 1.5, 0.0), (0.0, -1.5, 0.0), (-1.0, -1.0, 0.0)):
        xml = f"""<mujoco><worldbody>
          <geom name="post" type="cylinder" size="1 5" contype="0" conaffinity="0"/>
          <site name="a" pos="{' '.join(map(str, runs[0]))}"/><site name="b" pos="{' '.join(map(str, runs[3]))}"/>
          <site name="side" pos="{' '.join(map(str, side))}"/></worldbody>
          <tendon><spatial name="t"><site site="a"/><geom geom="post" sidesite="side"/><site site="b"/></spatial>
          </tendon></mujoco>"""
        m = mujoco.MjModel.from_xml_string(xml)
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        lengths.append(float(d.ten_length[0]))
    assert long > short + 1.0 > straight + 1.0
    assert all(min(abs(v - straight), abs(v - short)) < 1e-9 for v in lengths), (lengths, straight, short, long)


def test_mobl_tmaj_loops_round_its_humeral_cylinder_in_opensim():
    """The floor behind TMAJ's length error on the wrapped MoBL-ARMS: TMAJ-P1 sits 1 mm on the
    non-active side of TMAJ_LAThum's quadrant (-x), 9.9 mm from its axis (radius 7 mm); where the
    straight path passes the cylinder on that side OpenSim takes it round the -x side, the long
    way (about 300 degrees, 40 mm of arc for 14 mm between its contacts), its runs crossing. The
    path is then far longer than its points joined straight, which MuJoCo keeps (above)."""
    pose = {"elv_angle": -0.38, "shoulder_elv": 1.53, "shoulder_rot": 0.14, "elbow_flexion": 2.12,
            "pro_sup": -0.45}
    model, state = _posed("mobl-arms/MoBL_ARMS_model_for_testing_opensim.osim", pose)
    found = path_loop(wrap_runs(model, state, "TMAJ"))
    assert found == {"wrap": "TMAJ_LAThum", "kind": "WrapCylinder"}, found
    fixed = np.array([p for _, wrap, p in current_path_points(model, state, "TMAJ") if wrap is None])
    straight = float(np.linalg.norm(np.diff(fixed, axis=0), axis=1).sum())
    length = runtime.geometry_path(model, "TMAJ").getLength(state)
    assert length > 1.2 * straight, (length, straight)


def test_opensim_draws_the_path_it_measures_over_one_wrap():
    """Over one wrap per segment OpenSim's length is that of the path it draws (the arcs' chords
    cost under 1 mm): Arm26's BIClong round BIClonghh at the default pose and with the elbow flexed."""
    for elbow in (0.0, 1.5):
        model, state = _posed("opensim-models/Models/Arm26/arm26.osim", {"r_elbow_flex": elbow})
        length = runtime.geometry_path(model, "BIClong").getLength(state)
        assert abs(drawn_length(model, state, "BIClong") - length) < 1e-3, elbow


def test_mobl_corb_length_is_not_that_of_the_path_opensim_draws():
    """The floor behind CORB's length error on the wrapped MoBL-ARMS: over its two wraps on one
    segment (TMAJ_LAT_PEC_CORBhh, CORBhum) OpenSim's getLength is 184 mm where the path it draws is
    254 mm long (MuJoCo's tendon, following a path, 228 mm); no tendon has a length other than its path's."""
    pose = {"elv_angle": -1.08, "shoulder_elv": 2.28, "shoulder_rot": -1.03, "elbow_flexion": 0.43, "pro_sup": 1.14}
    model, state = _posed("mobl-arms/MoBL_ARMS_model_for_testing_opensim.osim", pose)
    length = runtime.geometry_path(model, "CORB").getLength(state)
    drawn = drawn_length(model, state, "CORB")
    assert drawn - length > 5 * BAND_FRACTION * length, (length, drawn)


def test_mobl_for_mujoco_fcu_overshoot_is_an_inconsistent_length_not_a_detour():
    """fidelity.py's worst FCU sample on MoBL_ARMS_model_for_mujoco.osim is of this kind: OpenSim's
    path runs from the elbow past FCU-P2 to the wrist torus and back, its contacts just inside the
    detour rule (1.21-1.23 of FCU-P1-P2 along it), and its length is neither that of its points
    joined straight (285 mm, which the tendon follows) nor that of the path it draws (549 mm)."""
    pose = {"elv_angle": 1.193, "shoulder_elv": 2.625, "shoulder_rot": -1.03, "elbow_flexion": 0.488,
            "pro_sup": 0.438, "deviation": 0.317, "flexion": 1.133}
    model, state = _posed("mobl-arms/MoBL_ARMS_model_for_mujoco.osim", pose)
    points = current_path_points(model, state, "FCU")
    assert path_detour(points) is None
    fixed = np.array([p for _, wrap, p in points if wrap is None])
    straight = float(np.linalg.norm(np.diff(fixed, axis=0), axis=1).sum())
    length = runtime.geometry_path(model, "FCU").getLength(state)
    drawn = drawn_length(model, state, "FCU")
    assert length > 1.5 * straight and drawn - length > 2 * BAND_FRACTION * length, (straight, length, drawn)


def _helix(start_deg: float, turn_deg: float, radius: float = 0.008, rise: float = 0.03, n: int = 40) -> np.ndarray:
    """A spiral arc on a cylinder about z: from ``start_deg`` through ``turn_deg`` (either sense)."""
    ang = np.radians(start_deg + np.linspace(0.0, turn_deg, n))
    return np.c_[radius * np.cos(ang), radius * np.sin(ang), np.linspace(0.0, -rise, n)]


def test_an_arc_over_a_full_turn_round_its_wrap_winds():
    """The long way round a cylinder (210 degrees) is a path; 522 degrees (the shape of OpenSim's
    SUP arc on MoBL-ARMS) winds round it and is flagged, with the turn measured in either sense.
    A sphere's arc is measured from its centre: a great circle over 300 degrees is not flagged,
    one over 400 is."""
    assert abs(arc_turn("WrapCylinder", _helix(114, 210)) - np.radians(210)) < 1e-9
    assert abs(arc_turn("WrapCylinder", _helix(114, -522)) - np.radians(522)) < 1e-9
    assert path_winding([("SUP", "WrapCylinder", _helix(114, 210))]) is None
    found = path_winding([("ring", "WrapTorus", _helix(0, 600)), ("SUP", "WrapCylinder", _helix(114, -522))])
    assert found is not None and found["wrap"] == "SUP" and found["turn"] > FULL_TURN, found

    def circle(turn_deg: float) -> np.ndarray:
        ang = np.radians(np.linspace(0.0, turn_deg, 50))
        return 0.02 * np.c_[np.cos(ang), np.zeros_like(ang), np.sin(ang)]
    assert abs(arc_turn("WrapSphere", circle(300)) - np.radians(300)) < 1e-9
    assert path_winding([("head", "WrapSphere", circle(300))]) is None
    assert path_winding([("head", "WrapEllipsoid", circle(400))])["turn"] > FULL_TURN


def test_mobl_sup_winds_round_its_cylinder_in_opensim_once_supinated():
    """The floor behind SUP's length on MoBL-ARMS: its cylinder (quadrant -x) is wrapped less than
    half a turn up to pro_sup 0 (the length growing smoothly), then, past about 0.07 rad, by a
    spiral of over a full turn in the wrong sense (the length jumps by about 41 mm), which one
    whole turn would shorten: no shortest path, and not one a tendon can follow."""
    turns = {}
    for q in (-1.0, 0.0, 0.3, 1.2):
        model, state = _posed("mobl-arms/MoBL_ARMS_model_for_testing_opensim.osim", {"pro_sup": q})
        arcs = {w: (k, a) for w, k, a in wrap_arcs(model, state, "SUP")}
        turns[q] = arc_turn(*arcs["SUP"])
    assert turns[-1.0] < turns[0.0] < np.pi, turns
    assert turns[0.3] > FULL_TURN and turns[1.2] > FULL_TURN, turns
