"""OpenSim's own path failures that comparisons leave out: detours (o2m.osim.spikes.path_detour).

Spikes and failure bands are tested with the wrap tests (tests/convert/test_wrapping.py).
"""

from __future__ import annotations

import numpy as np

from o2m.osim import runtime
from o2m.osim.spikes import DETOUR_FRACTION, current_path_points, path_detour
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
