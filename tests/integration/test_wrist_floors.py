"""WristModel's length misses over 1 %: where they come from, measured on OpenSim's own paths.

The model's paths are straight lines through their active points (no wrap objects on any
muscle), and its flexors pass the wrist through runs of consecutive ConditionalPathPoints
switched by flexion at different values (FCU: P2 on above 0.56 rad, P3 below -0.63, P4 below
-0.03, P5 below 0.56). MuJoCo switches a tendon only where a wrap geom's side site leaves it
(o2m's sphere per conditional point), and a spatial tendon needs a site between two wrap geoms:
that site is on the path in every state, so of a run only some points can switch; the others
are kept always on or left out, or two points of one body on in disjoint ranges share one
sphere that a carrier moves between them (o2m.convert.conditional._run_roles). A site carried
by a polynomial of flexion cannot jump between the places the states need (FPL: the segments of
its three states meet only at P4 and at P6, 25 mm apart, at one flexion value).

Measured here, independently of the converter: on the comparison's own poses (100, seed 0, as
the muscle comparison draws them), OpenSim's length with each run's points given every allowed
role (a sphere switching as OpenSim, always on, left out, a sphere shared by two points at the
point that is on; a site between any two spheres).
For the muscles in ROLE_FLOORS no choice is within 1 % at every pose: that is the floor of
this construction, and the conversion's worst error sits on it (to the sphere's rounding, or
the choice o2m made on its own sampled poses).
"""

from __future__ import annotations

import itertools

import numpy as np
import opensim as osim
import pytest

from o2m import models
from o2m.convert.converter import convert
from o2m.osim.pair import ModelPair
from o2m.osim.runtime import sample_bounds
from o2m.validate.jumps import opensim_length_steps
from o2m.validate.muscles import LEN_PCT, MA_P95_MM
from tests.helpers import convert_options, require_models

osim.Logger.setLevelString("error")

WRIST = "opensim-models/Models/WristModel/wrist.osim"
#: Worst length error (%) of the conversion on the comparison's poses (quick, 100 poses, seed 0),
#: measured, for the muscles whose best role choice misses 1 % there (best choice in brackets):
#: FPL 4.317 (4.317: P5 a sphere, P4 left out), FCU 2.180 (1.967: o2m chooses by moment arms
#: too, on its own poses: P5 a sphere, P3 always on, P2 and P4 left out), FDPL 1.282 (1.282),
#: FDPR 1.026 (1.032). FDSR (1.018 before) now shares a sphere between P2 and P3: 0.904.
ROLE_FLOORS = {"FPL": 4.32, "FCU": 2.19, "FDPL": 1.29, "FDPR": 1.03}
#: The muscles the gallery lists as missing a target (quick, 30 poses, seed 0), with the
#: conversion's measured score there: the larger of its worst length error over 1 % and its worst
#: moment-arm RMS over 2 mm (FPL 3.680, FCU 2.180, FDSI 1.101, FDSM 1.089, FDSR 1.221, FDSL 1.238,
#: FDPI 1.086, FDPR 1.099, FDPL 1.358). The best role choice's score on the same poses, the shared
#: sphere exactly at its points: 3.660, 1.861, 1.177, 1.150, 1.275, 1.261, 1.032, 1.098, 1.358.
TARGET_FLOORS = {"FPL": 3.69, "FCU": 2.19, "FDSI": 1.11, "FDSM": 1.10, "FDSR": 1.23, "FDSL": 1.25, "FDPI": 1.09,
                 "FDPR": 1.10, "FDPL": 1.36}


@pytest.fixture(scope="module")
def wrist(tmp_path_factory):
    require_models()
    fetched = models.fetch_model_with_geometry(WRIST, progress=False)
    conv = convert(fetched.osim, tmp_path_factory.mktemp("wrist"), convert_options(),
                   geometry_dirs=[fetched.geometry_dir])
    return ModelPair(fetched.osim, conv.xml), conv


def _comparison_states(pair: ModelPair, n: int = 100, seed: int = 0) -> list:
    """OpenSim states at the muscle comparison's poses: the default, then uniform draws."""
    bounds = np.array([sample_bounds(c) for c in pair.indep], dtype=float)
    draws = np.random.default_rng(seed).uniform(bounds[:, 0], bounds[:, 1], size=(n - 1, len(bounds)))
    states = [pair.os_state(None)]
    for row in draws:
        try:
            states.append(pair.os_state(dict(zip(pair.indep_names, row, strict=True))))
        except Exception:  # a pose OpenSim cannot assemble is left out, as in the comparison
            pass
    return states


def _best_role_choice(pair: ModelPair, muscle: str, states: list) -> tuple[float, str]:
    """The smallest worst length error (%) over ``states`` of OpenSim's path with its
    conditional points given roles (C: switching as OpenSim, S: always on, D: left out, H and J:
    a sphere shared by two points, at the point that is on; a site between two spheres), and
    that choice."""
    points, cond, where, active = _points(pair, muscle, states)
    truth = np.array([pair.force(muscle).getGeometryPath().getLength(s) for s in states])
    return min((float(np.max(np.abs(_choice_lengths(choice, cond, where, active) - truth) / truth)) * 100,
                "".join(choice)) for choice in _role_choices(cond))


def _points(pair: ModelPair, muscle: str, states: list) -> tuple[list, list, np.ndarray, np.ndarray]:
    """``muscle``'s path points, each as a ConditionalPathPoint (or None), their ground places
    (n_states, n_points, 3) and whether OpenSim has each on (n_states, n_points)."""
    pps = pair.force(muscle).getGeometryPath().getPathPointSet()
    points = [pps.get(i) for i in range(pps.getSize())]
    cond = [osim.ConditionalPathPoint.safeDownCast(p) for p in points]
    where = np.array([[[p.getLocationInGround(s).get(i) for i in range(3)] for p in points] for s in states])
    active = np.array([[c is None or c.isActive(s) for c in cond] for s in states])
    return points, cond, where, active


def _role_choices(cond: list):
    """Every allowed role string for the run of conditional points ``cond`` (see
    :func:`_best_role_choice`)."""
    run = [i for i, c in enumerate(cond) if c is not None]
    for choice in itertools.product("CSDHJ", repeat=len(run)):
        if any(c == "H" and (j + 1 == len(run) or choice[j + 1] != "J" or not _disjoint(cond[run[j]], cond[run[j + 1]]))
               or c == "J" and (j == 0 or choice[j - 1] != "H") for j, c in enumerate(choice)):
            continue
        kept = [c for c in choice if c not in "DJ"]
        if not any(a in "CH" and b in "CH" for a, b in zip(kept[:-1], kept[1:], strict=True)):
            yield choice


def _choice_lengths(choice: tuple[str, ...], cond: list, where: np.ndarray, active: np.ndarray) -> np.ndarray:
    """Length (m) per state of the straight path through the points on with roles ``choice``,
    at places ``where``; ``active``: which points OpenSim has on."""
    run = [i for i, c in enumerate(cond) if c is not None]
    on, at = active.copy(), where.copy()
    for j, (i, c) in enumerate(zip(run, choice, strict=True)):
        on[:, i] = {"C": active[:, i], "S": True, "D": False, "J": False,
                    "H": active[:, i] | active[:, min(i + 1, where.shape[1] - 1)]}[c]
        if c == "H":  # the shared sphere where the point that is on is (the best it can be)
            at[:, i] = np.where(active[:, i, None], where[:, i], where[:, run[j + 1]])
    length, prev = np.zeros(len(where)), at[:, 0]
    for j in range(1, where.shape[1]):
        length += np.where(on[:, j], np.linalg.norm(at[:, j] - prev, axis=1), 0.0)
        prev = np.where(on[:, j, None], at[:, j], prev)
    return length


def _disjoint(a, b) -> bool:
    """Whether ConditionalPathPoints ``a`` and ``b`` are on one body, switched by one coordinate
    in ranges that do not meet (o2m.convert.conditional.can_share)."""
    ra, rb = sorted([(a.get_range(0), a.get_range(1)), (b.get_range(0), b.get_range(1))])
    return (a.getParentFrame().getName() == b.getParentFrame().getName()
            and a.getCoordinate().getName() == b.getCoordinate().getName() and rb[0] > ra[1])


def test_the_wrist_flexors_length_misses_are_the_role_floor(wrist):
    """No role choice for the runs of ROLE_FLOORS' muscles is within 1 % at the comparison's
    poses, and the conversion is no worse than measured there; every other path with
    conditional points is within 1 %."""
    pair, _ = wrist
    states = _comparison_states(pair)
    l_mj = np.array([pair.mj_lengths(pair.os_indep_values(s))[pair.tendon_ids] for s in states])
    l_os = np.array([pair.os_lengths(s) for s in states])
    worst = dict(zip([n for n, _, _ in pair.matched], (100 * np.abs(l_mj - l_os) / l_os)[1:].max(axis=0),
                     strict=True))  # pose 0 left out: EDCL/EDCI's OpenSim spikes (zero-width ranges)
    for muscle, measured in ROLE_FLOORS.items():
        floor, choice = _best_role_choice(pair, muscle, states)
        assert floor > LEN_PCT, (muscle, floor, choice)
        assert floor - 0.01 <= worst[muscle] <= measured, (muscle, floor, worst[muscle])
    others = {m: e for m, e in worst.items() if m not in ROLE_FLOORS}
    assert max(others.values()) < LEN_PCT, sorted(others.items(), key=lambda kv: -kv[1])[:3]


def test_fpl_steps_at_both_range_ends(wrist):
    """FPL's two consecutive conditional points step OpenSim's length along flexion where each
    switches off (P5 at 0.0175 rad, P4 at 0.1745), by different points with no site between:
    MuJoCo follows one step (a sphere); the 10 mm one alone is a 1.96 % floor for a tendon
    that does not follow it."""
    pair, conv = wrist
    steps = [s for s in opensim_length_steps(pair.osim_path, conv.xml) if s["path"] == "FPL"]
    at = sorted((round(s["at"], 3), s) for s in steps if s["coordinate"] == "flexion")
    assert [a for a, _ in at] == [0.017, 0.175], steps
    assert all(s["height"] < -1e-3 for _, s in at), steps  # each point off shortens the path
    assert max(s["floor_pct"] for _, s in at) > LEN_PCT


def test_run_roles_weigh_moment_arms(wrist):
    """FDPM's run (P2 to P5) has a choice within both targets. By length alone o2m kept P2 always
    on and left P3 to P5 out: lengths within 0.71 %, but moment arms 2.2-2.3 mm RMS off about
    flexion and deviation. Weighing moment arms too, P5 becomes a sphere: within 2 mm."""
    from o2m.validate.muscles import MA_P95_MM, compare_muscles

    pair, conv = wrist
    report = compare_muscles(pair.osim_path, conv.xml, n_poses=30, seed=0, progress=False)
    fdpm = report.muscles["FDPM"]
    assert fdpm.max_len_pct < LEN_PCT, fdpm.max_len_pct
    arms = {c: 1e3 * e.rms for c, e in fdpm.moment_arms.items()}
    assert max(arms.values()) < MA_P95_MM, arms


def _best_target_score(pair: ModelPair, muscle: str, states: list, h: float = 1e-4) -> tuple[float, str]:
    """The smallest score over the allowed role choices (:func:`_best_role_choice`), and its
    choice: the larger of the worst length error over ``states`` over 1 % and the worst moment-arm
    RMS (central differences of ``h`` rad of each independent coordinate, OpenSim's points held
    on or off as at the state) over 2 mm, as the converter weighs them."""
    _, cond, where, active = _points(pair, muscle, states)
    truth = np.array([pair.force(muscle).getGeometryPath().getLength(s) for s in states])
    values = [pair.os_indep_values(s) for s in states]
    moved = {}
    for c in pair.indep_names:
        places = []
        for step in (h, -h):
            shifted = [pair.os_state({**v, c: v[c] + step}) for v in values]
            places.append(_points(pair, muscle, shifted)[2])
        if np.abs(places[0] - places[1]).max() > 1e-12:
            moved[c] = places
    plain = [None] * active.shape[1]  # OpenSim's own path: every point as OpenSim has it
    true_arms = {c: -(_choice_lengths((), plain, p, active) - _choice_lengths((), plain, m, active)) / (2 * h)
                 for c, (p, m) in moved.items()}
    best = (np.inf, "")
    for choice in _role_choices(cond):
        rel = np.abs(_choice_lengths(choice, cond, where, active) - truth) / truth
        arms = [np.sqrt(np.mean((-(_choice_lengths(choice, cond, p, active) - _choice_lengths(choice, cond, m, active))
                                 / (2 * h) - true_arms[c]) ** 2)) for c, (p, m) in moved.items()]
        best = min(best, (max(rel.max() / (LEN_PCT / 100), max(arms) * 1e3 / MA_P95_MM), "".join(choice)))
    return best


def test_the_wrist_flexors_moment_arm_misses_are_the_role_floor(wrist):
    """For the muscles of TARGET_FLOORS (every one the gallery lists as missing) no allowed role
    choice, a shared sphere exactly at its points included, is within both targets (length 1 %,
    moment arms 2 mm RMS) on the gallery's 30 poses: what they miss is the construction's floor
    there, not o2m's choice. The conversion is no further from the targets than measured. (On
    other poses the floor moves: over poses 1 to 50 of the 100 the length test draws, FDSI's and
    FDSM's best choices reach 0.99 and 0.97, where the quartic that carries their shared sphere
    leaves them at 1.1.)"""
    from o2m.validate.muscles import compare_muscles

    pair, conv = wrist
    states = _comparison_states(pair, n=30)  # the comparison's own 30 poses
    report = compare_muscles(pair.osim_path, conv.xml, n_poses=30, seed=0, progress=False)
    for muscle, measured in TARGET_FLOORS.items():
        floor, choice = _best_target_score(pair, muscle, states)
        e = report.muscles[muscle]
        got = max(e.max_len_pct / LEN_PCT, max(1e3 * a.rms for a in e.moment_arms.values()) / MA_P95_MM)
        assert floor > 1, (muscle, floor, choice)
        assert got <= measured, (muscle, got)


def test_the_report_marks_runs_whose_best_choice_misses_the_targets(wrist):
    """The converter records each run's best role choice as an approximation, ``floor`` where even
    that choice misses a target on its own sampled poses: FPL's and FCU's runs (their best scores
    on the gallery's poses 3.7 and 1.9, far over 1), and not FDPM's (within both targets)."""
    _, conv = wrist
    runs = {a.name: a for a in conv.report.approximations if a.element == "ConditionalPathPoint"}
    assert runs["FPL"].floor and runs["FCU"].floor
    assert not runs["FDPM"].floor
    assert runs["FPL"].max_error > 1.0  # % of the path's length, over the converter's poses
