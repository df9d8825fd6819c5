"""Jumps of tendon lengths over fine one-coordinate sweeps, and the floor OpenSim's own steps set.

A wrapped path that flips sides shows as a jump between neighbouring sweep poses. OpenSim's
own paths can step too (a wrap switching on or off); no continuous MuJoCo tendon can follow a
step, which sets a floor on the length error any conversion can reach.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Collection, Mapping, Sequence
from typing import Any

import numpy as np

from o2m.mj.posing import joint_qpos_address
from o2m.mj.tendons import tendon_length_steps
from o2m.osim.pair import ModelPair
from o2m.osim.runtime import TRANSLATIONAL, sample_bounds
from o2m.osim.spikes import (
    BAND_STEPS,
    SPIKE_LINEAR_STEP,
    SPIKE_STEP,
    one_pose_spikes,
    opensim_loops,
    opensim_windings,
    outlying_changes,
    unfair_path,
)
from o2m.validate.kinematics import jsonable
from o2m.validate.muscles import LEN_PCT

__all__ = ["continuous_tendon_front", "opensim_length_steps", "opensim_steps_around", "sweep_jumps",
           "trajectory_jumps"]


#: Coordinate distance (rad, m) either side of a bisected step at which its two lengths are read:
#: OpenSim failing at the bisection's last pose alone (its wrap iterations) makes no step.
STEP_SIDE = (1e-4, 1e-5)
#: Two opposite steps of one path closer than this (rad, m: the failure-band test's widest
#: neighbours, :data:`o2m.osim.spikes.BAND_STEPS`) whose heights cancel within
#: :data:`BAND_RETURN` of the larger are a band OpenSim's path leaves and returns from, which the
#: comparison leaves out as a failure: no floor.
BAND_WIDTH = (SPIKE_STEP * BAND_STEPS[-1], SPIKE_LINEAR_STEP * BAND_STEPS[-1])
BAND_RETURN = 0.25


def _bisect(length, a: float, b: float, la: float, lb: float, bisections: int) -> float:
    """The coordinate value (rad, m) of a step of ``length(q)`` (m) inside ``[a, b]``, bisected
    ``bisections`` times towards the larger change."""
    for _ in range(bisections):
        mid = 0.5 * (a + b)
        lm = length(mid)
        if abs(lm - la) >= abs(lb - lm):
            b, lb = mid, lm
        else:
            a, la = mid, lm
    return 0.5 * (a + b)


def _band_poses(q: np.ndarray, d: np.ndarray, odd: np.ndarray, width: float) -> np.ndarray:
    """(n + 1,) bool: the sweep poses ``q`` (n + 1,) inside a band, between two opposite outlying
    changes (``d``, ``odd``: (n,), as for :func:`o2m.osim.spikes.one_pose_spikes`) at most
    ``width`` apart whose heights cancel within :data:`BAND_RETURN`."""
    band = np.zeros(len(d) + 1, bool)
    ks = np.flatnonzero(odd)
    for k1, k2 in zip(ks[:-1], ks[1:], strict=True):
        h1, h2 = float(d[k1]), float(d[k2])
        if q[k2] - q[k1] <= width and h1 * h2 < 0 and abs(h1 + h2) <= BAND_RETURN * max(abs(h1), abs(h2)):
            band[k1 + 1:k2 + 1] = True
    return band

def _without_bands(steps: list[dict[str, Any]], width: float) -> list[dict[str, Any]]:
    """``steps`` of one path along one coordinate without those that pair up into bands."""
    steps = sorted(steps, key=lambda s: s["at"])
    band: set[int] = set()
    for j in range(len(steps) - 1):
        s, t = steps[j], steps[j + 1]
        if j in band or t["at"] - s["at"] > width or s["height"] * t["height"] >= 0:
            continue
        if abs(s["height"] + t["height"]) <= BAND_RETURN * max(abs(s["height"]), abs(t["height"])):
            band |= {j, j + 1}
    return [s for j, s in enumerate(steps) if j not in band]


def sweep_jumps(
    osim_path: str | os.PathLike,
    mjcf_path: str | os.PathLike,
    *,
    step: float = float(np.deg2rad(1)),
    linear_step: float = 1e-3,
    opensim: bool = True,
    jump_factor: float = 2.0,
    jump_atol: float = 1e-3,
    progress: bool = False,
    assembly_accuracy: float | None = 1e-12,
) -> dict[str, Any]:
    """Sweep each independent coordinate over its range (steps of ``step`` radians, or
    ``linear_step`` metres for a translational coordinate; the others at their defaults) and
    report the largest change of each tendon length between neighbouring steps.

    Returns a JSON-safe dict::

        {"osim_path", "mjcf_path", "step", "linear_step",
         "coordinates": {coordinate: {"range": [lo, hi], "steps": n, "opensim_swept": bool,
             "tendons": {tendon: {"mujoco": max |dL| (m), "mujoco_at": [q0, q1],
                                  "opensim": max |dL| (m) or None, "opensim_at": [q0, q1] or None}}}},
         "worst": {tendon: {"coordinate", "mujoco", "opensim"}},   # each tendon's largest MuJoCo jump
         "jumps": [{"tendon", "coordinate", "mujoco", "opensim", "at"}, ...]}

    ``jumps`` lists, largest first, the (tendon, coordinate) pairs whose MuJoCo jump exceeds
    ``jump_factor`` times OpenSim's plus ``jump_atol`` metres (without OpenSim, with
    ``opensim=False`` or for a tendon OpenSim lacks: ``jump_atol`` alone): wrapping flips and
    other discontinuities. OpenSim steps that fail to assemble are left out. OpenSim is swept
    only along coordinates that some OpenSim path spans or that change some MuJoCo tendon length
    (``opensim_swept``); along the others every OpenSim jump is 0 (e.g. a free base's
    translations, which would take thousands of 1 mm steps).
    """
    from tqdm.auto import tqdm

    pair = ModelPair(osim_path, mjcf_path, assembly_accuracy)
    tnames = pair.tendon_names
    os_index = {n: i for i, (n, _, _) in enumerate(pair.matched)}
    out: dict[str, Any] = {"osim_path": pair.osim_path, "mjcf_path": pair.mjcf_path, "step": float(step),
                           "linear_step": float(linear_step), "coordinates": {}, "worst": {}, "jumps": []}
    spans = pair.spanned() if opensim else {}
    desc = f"sweep {os.path.basename(pair.osim_path)}"
    for c in tqdm(pair.indep, disable=not progress, desc=desc):
        cname = pair.name(c)
        qs = pair.sweep_values(c, step, linear_step)
        l_mj = np.array([pair.mj_lengths({**pair.defaults, cname: float(q)}) for q in qs]).reshape(len(qs), -1)
        l_os = np.full((len(qs), len(pair.matched)), np.nan)
        # OpenSim only where a length can change: a path spans the coordinate in OpenSim, or a
        # MuJoCo tendon length changes; elsewhere every OpenSim length is constant (jump 0).
        os_needed = opensim and bool(pair.matched) and (
            any(cname in s for s in spans.values()) or bool(l_mj.size and np.ptp(l_mj, axis=0).max() > 1e-12))
        if os_needed:
            for k, q in enumerate(qs):
                try:
                    l_os[k] = pair.os_lengths(pair.os_state({cname: float(q)}, assemble=False))
                except Exception:
                    pass
        elif opensim:
            l_os[:] = 0.0
        d_mj = np.abs(np.diff(l_mj, axis=0))
        d_os = np.abs(np.diff(l_os, axis=0))
        tend: dict[str, Any] = {}
        for t, tn in enumerate(tnames):
            k = int(np.argmax(d_mj[:, t])) if len(d_mj) else 0
            row: dict[str, Any] = {"mujoco": float(d_mj[k, t]) if len(d_mj) else 0.0,
                                   "mujoco_at": [float(qs[k]), float(qs[k + 1])],
                                   "opensim": None, "opensim_at": None}
            i = os_index.get(tn)
            if opensim and i is not None and np.isfinite(d_os[:, i]).any():
                ko = int(np.nanargmax(d_os[:, i]))
                row["opensim"] = float(d_os[ko, i])
                row["opensim_at"] = [float(qs[ko]), float(qs[ko + 1])]
            tend[tn] = row
            limit = jump_factor * (row["opensim"] or 0.0) + jump_atol
            if row["mujoco"] > limit:
                out["jumps"].append({"tendon": tn, "coordinate": cname, "mujoco": row["mujoco"],
                                     "opensim": row["opensim"], "at": row["mujoco_at"]})
            w = out["worst"].get(tn)
            if w is None or row["mujoco"] > w["mujoco"]:
                out["worst"][tn] = {"coordinate": cname, "mujoco": row["mujoco"], "opensim": row["opensim"]}
        lo, hi = sample_bounds(c)
        out["coordinates"][cname] = {"range": [lo, hi], "steps": int(len(qs)), "opensim_swept": os_needed,
                                     "tendons": tend}
    out["jumps"].sort(key=lambda j: -j["mujoco"])
    return jsonable(out)


def opensim_length_steps(
    osim_path: str | os.PathLike,
    mjcf_path: str | os.PathLike,
    *,
    step: float = float(np.deg2rad(0.5)),
    linear_step: float = 5e-4,
    min_step: float = 5e-4,
    bisections: int = 40,
    assembly_accuracy: float | None = 1e-12,
    pair: ModelPair | None = None,
    through: Mapping[str, float] | None = None,
    paths: Collection[str] | None = None,
) -> list[dict[str, Any]]:
    """Discontinuities of OpenSim's own path lengths, and what they cost any continuous tendon.

    Each independent coordinate is swept over its range (the others at their defaults, or at the
    independent coordinate values ``through``: a pose, rad or m) in steps
    of ``step`` radians (``linear_step`` m); a neighbour interval whose length change stands out
    from its neighbours' by more than ``min_step`` / 2 is bisected ``bisections`` times towards
    the larger change. What is left (an interval of width ``range / 2**bisections``) changing by
    more than ``min_step`` metres is a step of OpenSim's length (a wrap switching on or off, a
    conditional point): a continuous function (a MuJoCo tendon without a matching flip) is at
    least half of it away from OpenSim on one side of it.

    Returns, largest ``floor_pct`` first, one dict per step::

        {"path", "coordinate", "at": q (rad or m), "height": L(after) - L(before) (m),
         "length": [L before, L after] (m), "through": ``through`` (or None),
         "floor_pct": 100 * |height| / 2 / max(length)}  # a lower bound on any continuous
                                                          # tendon's worst length error, in %

    A step's lengths are read :data:`STEP_SIDE` either side of it (OpenSim failing at one pose is
    no step), and two opposite steps that make a band (:data:`BAND_WIDTH`, :data:`BAND_RETURN`)
    are left out, as the comparison leaves such bands out, and so is a step into a path that is no
    fair test (a detour, loop or winding, or a length not that of the drawn path:
    :func:`o2m.osim.spikes.path_failure`), which the comparison leaves out too. ``paths``: the path
    forces to sweep (default all). Only steps at the sweep's poses are
    found (a step that a narrow spike makes, or one away from the other coordinates' defaults, can
    be missed): the floors are lower bounds.
    ``pair``: the two models already loaded (the paths and ``assembly_accuracy`` are then unused).
    """

    pair = pair or ModelPair(osim_path, mjcf_path, assembly_accuracy)
    names = [n for n, _, _ in pair.matched]
    out: list[dict[str, Any]] = []
    spans = pair.spanned()
    base = {**pair.defaults, **(through or {})}
    wanted = set(names if paths is None else paths)

    def state(cname: str, q: float) -> Any:
        return pair.os_state({**base, cname: float(q)}, assemble=False)

    for c in pair.indep:
        cname = pair.name(c)
        swept = [i for i, n in enumerate(names) if n in wanted and cname in spans.get(n, set())]
        if not swept:
            continue
        qs = pair.sweep_values(c, step, linear_step)
        L = np.array([_lengths_at(pair, lambda q: state(cname, q), q) for q in qs])  # noqa: B023
        linear = int(c.getMotionType() == TRANSLATIONAL)
        for i in swept:
            out += _steps_on_sweep(pair, i, qs, L[:, i], lambda q: state(cname, q),  # noqa: B023
                                   {"coordinate": cname, "through": dict(through) if through else None},
                                   min_step, bisections, STEP_SIDE[linear], BAND_WIDTH[linear])
    out.sort(key=lambda s: -s["floor_pct"])
    return out


def opensim_steps_around(
    pair: ModelPair,
    name: str,
    pose: Mapping[str, float],
    *,
    lines: int = 12,
    candidates: int = 100,
    samples: int = 121,
    seed: int = 0,
    min_step: float = 5e-4,
    bisections: int = 30,
) -> list[dict[str, Any]]:
    """Steps of OpenSim's length of the path force ``name`` along straight lines in the space of
    independent coordinates, from ``pose`` (their values, rad or m) to the ``lines`` nearest of
    ``candidates`` poses drawn uniformly over the coordinates' ranges (``seed``).

    The sweeps of :func:`opensim_length_steps` move one coordinate; a step where two or three
    move together (a finite WrapCylinder's end crossing the path, which a shoulder's three
    rotations move) is met along a line, at ``samples`` poses each, bisected as there and kept
    under the same rules (read :data:`STEP_SIDE` either side, no band, no unfair side). Returns
    the steps as :func:`opensim_length_steps` does, with ``"coordinate"`` None, ``"at"`` the
    distance along the line (in the coordinates' units), ``"through"`` ``pose`` and
    ``"towards"`` the line's other end."""
    names = [n for n, _, _ in pair.matched]
    index = names.index(name)
    bounds = np.array([sample_bounds(c) for c in pair.indep], dtype=float).reshape(-1, 2)
    start = np.array([pose.get(n, pair.defaults[n]) for n in pair.indep_names])
    draws = np.random.default_rng(seed).uniform(bounds[:, 0], bounds[:, 1], size=(candidates, len(bounds)))
    out: list[dict[str, Any]] = []
    apart = np.linalg.norm(draws - start, axis=1)
    nearest = [k for k in np.argsort(apart) if apart[k] > 1e-9][:lines]  # ``pose`` may be a draw
    for end in draws[nearest]:
        span = float(np.linalg.norm(end - start))

        def state(d: float, end: np.ndarray = end, span: float = span) -> Any:
            return pair.os_state(dict(zip(pair.indep_names, start + d / span * (end - start), strict=True)),
                                 assemble=False)

        ds = np.linspace(0.0, span, samples)
        L = np.array([_lengths_at(pair, state, d)[index] for d in ds])
        out += _steps_on_sweep(pair, index, ds, L, state,
                               {"coordinate": None, "through": dict(pose),
                                "towards": dict(zip(pair.indep_names, end.tolist(), strict=True))},
                               min_step, bisections, STEP_SIDE[0], BAND_WIDTH[0])
    out.sort(key=lambda s: -s["floor_pct"])
    return out


def _steps_on_sweep(pair: ModelPair, index: int, qs: np.ndarray, L: np.ndarray, state: Callable[[float], Any],
                    meta: dict[str, Any], min_step: float, bisections: int, side: float,
                    width: float) -> list[dict[str, Any]]:
    """The steps of OpenSim's length of path ``index`` (into ``pair.matched``) over a sweep:
    ``L`` (n,) its lengths (m) at the sweep's parameters ``qs`` (n,), ``state(q)`` the realised
    state at ``q``. Each outlying change is bisected, its lengths read ``side`` either side, and
    kept if over ``min_step`` with a fair path on both sides; then bands ``width`` wide are left
    out. Each step's dict: ``meta`` and "path", "at", "height", "length", "floor_pct"."""
    name = pair.matched[index][0]
    found = []
    for k in np.flatnonzero(outlying_changes(np.diff(L), min_step / 2)):
        at = _bisect(lambda q: float(_lengths_at(pair, state, q)[index]), float(qs[k]), float(qs[k + 1]),
                     float(L[k]), float(L[k + 1]), bisections)
        try:
            sides = [state(at + sgn * side) for sgn in (-1, 1)]
        except Exception:  # OpenSim cannot assemble beside it: no step measured (a floor is a lower bound)
            continue
        la, lb = (float(pair.os_lengths(s)[index]) for s in sides)
        if abs(lb - la) > min_step and not any(_unfair(pair, s, name) for s in sides):
            found.append({**meta, "path": name, "at": at, "height": lb - la, "length": [la, lb],
                          "floor_pct": 100.0 * abs(lb - la) / 2.0 / max(la, lb)})
    return _without_bands(found, width)


def _lengths_at(pair: ModelPair, state: Callable[[float], Any], q: float) -> np.ndarray:
    """OpenSim's path lengths (m, (n paths,)) in ``state(q)``; NaN where it cannot assemble
    (NaN changes are no outlying change: a step next to a failure goes unmeasured)."""
    try:
        return pair.os_lengths(state(q))
    except Exception:
        return np.full(len(pair.matched), np.nan)


def _unfair(pair: ModelPair, state: Any, name: str) -> bool:
    """Whether OpenSim's path ``name`` in realised ``state`` is no fair test of a tendon: it
    detours, loops or winds, or its length is not that of the path it draws
    (:func:`o2m.osim.spikes.unfair_path`)."""
    return unfair_path(pair.os_model, state, name, float(pair.force(name).getLength(state))) is not None


def continuous_tendon_front(
    osim_path: str | os.PathLike,
    mjcf_path: str | os.PathLike,
    muscle: str,
    coordinate: str,
    *,
    pcts: Sequence[float] = (LEN_PCT,),
    n: int = 600,
    assembly_accuracy: float | None = 1e-12,
    pair: ModelPair | None = None,
    steps: Sequence[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """What any continuous tendon can reach against OpenSim, for one path along one coordinate.

    A MuJoCo tendon has one length, and its moment arm is ``-dL/dq`` of it. OpenSim's length can
    step (wraps switching), and its ``computeMomentArm`` need not be ``-dL/dq`` of its length
    (several wraps on one segment; a MovingPathPoint next to a point of its own body). Sweeping
    ``coordinate`` (``n`` poses over its range, the others at their defaults), this finds, for
    each length tolerance p in ``pcts`` (% of OpenSim's length at every pose), the least RMS and
    the largest moment-arm error against ``computeMomentArm`` of any continuous length within it
    (a bounded least-squares problem over the length at the sweep poses,
    :func:`scipy.optimize.lsq_linear`), or None where OpenSim's largest step leaves none within p
    (:func:`opensim_length_steps`). OpenSim's one-pose spikes (two opposite outlying changes, as
    :func:`o2m.lengthvia.outlying_changes` finds them) and the poses inside a band (two opposite
    ones close together, :data:`BAND_WIDTH`) are no target. These are lower bounds for
    the comparison's errors, which sample every coordinate.

    Returns ``{"q", "length", "moment_arm"`` (computeMomentArm) ``: (n,) arrays; "steps": the
    path's steps along the coordinate; "spikes": [q]; "inconsistency_rms", "inconsistency_max":
    computeMomentArm - (-dL/dq) away from outlying length changes (steps, spikes) (m);
    "floor_pct": the largest step's floor; "front": {p: {"rms", "max"} (m) or None}}``. ``pair``: the two
    models already loaded; ``steps``: :func:`opensim_length_steps` of the whole model, already
    measured (both save reloading and re-sweeping when many paths are asked about).
    """
    from scipy.optimize import lsq_linear

    pair = pair or ModelPair(osim_path, mjcf_path, assembly_accuracy)
    c = pair.coord(coordinate)
    force = pair.force(muscle)
    lo, hi = sample_bounds(c)
    qs = np.linspace(lo, hi, n)
    h = float(qs[1] - qs[0])
    length, arm = [], []
    for q in qs:
        state = pair.os_state({**pair.defaults, coordinate: float(q)}, assemble=False)
        length.append(force.getLength(state))
        arm.append(force.computeMomentArm(state, c))
    length_a, arm_a = np.array(length), np.array(arm)
    arm_mid = 0.5 * (arm_a[1:] + arm_a[:-1])
    d = np.diff(length_a)
    odd = outlying_changes(d)
    width = BAND_WIDTH[int(c.getMotionType() == TRANSLATIONAL)]
    spike = one_pose_spikes(d, odd) | _band_poses(qs, d, odd, width)
    spiky = spike[:-1] | spike[1:]
    if steps is None:
        steps = opensim_length_steps(osim_path, mjcf_path, pair=pair)
    steps = [s for s in steps if s["path"] == muscle and s["coordinate"] == coordinate]
    diff = (arm_mid + d / h)[~odd]  # away from every outlying change: steps, spikes, kinks
    floor = max((st["floor_pct"] for st in steps), default=0.0)
    D = (np.eye(n, k=1) - np.eye(n))[:-1] / h
    front: dict[float, dict[str, float] | None] = {}
    for p in pcts:
        if p <= floor:
            front[float(p)] = None
            continue
        lo_b = np.where(spike, 0.0, length_a * (1 - p / 100))
        hi_b = np.where(spike, 2.0 * length_a, length_a * (1 + p / 100))
        r = lsq_linear(-D[~spiky], arm_mid[~spiky], bounds=(lo_b, hi_b))
        res = -D[~spiky] @ r.x - arm_mid[~spiky]
        front[float(p)] = {"rms": float(np.sqrt(np.mean(res**2))), "max": float(np.max(np.abs(res)))}
    return {"q": qs, "length": length_a, "moment_arm": arm_a, "steps": steps, "spikes": qs[spike].tolist(),
            "inconsistency_rms": float(np.sqrt(np.mean(diff**2))) if diff.size else 0.0,
            "inconsistency_max": float(np.max(np.abs(diff))) if diff.size else 0.0, "floor_pct": floor,
            "front": front}




def trajectory_jumps(osim_path: str | os.PathLike, mjcf_path: str | os.PathLike, qpos: np.ndarray, *,
                     jump_atol: float = 1e-3, window: int = 25,
                     assembly_accuracy: float | None = 1e-12) -> dict[str, Any]:
    """Tendon lengths that jump along MuJoCo trajectories (a path flipping round its wrap), and
    whether OpenSim's path changes as much at the same MuJoCo poses, ``window`` samples either side.

    Args:
        qpos: shape (B, T, nq), MuJoCo states of B trajectories (e.g. ``Trajectories.qpos``).
        jump_atol: a step whose length change its Jacobian leaves unexplained by more than this
            (metres) is a jump (see :func:`o2m.mj.tendons.tendon_length_jumps`).
        window: OpenSim shares a jump when its path steps within this many samples either side
            (the two simulators' paths may switch sides at slightly different poses).
    Returns a JSON-safe dict ``{"jumps": [{"tendon", "trajectory", "step", "mujoco", "opensim",
    "opensim_step"}], "flips": [...], "at_opensim_failures": [...]}``: every tendon's largest jump per trajectory above
    ``jump_atol`` (metres), with OpenSim's length over the window around it, the independent
    coordinates set from MuJoCo's joints: ``opensim``, its change over the window less MuJoCo's
    smooth change there (a step or a steep stretch OpenSim shares), and ``opensim_step``, its
    largest such change between neighbouring poses (None where OpenSim does not assemble).
    ``flips`` keeps the jumps OpenSim does not share (``opensim`` under half of MuJoCo's jump):
    a path round the wrong side. Of those, a jump where OpenSim's own path, at the pose before or
    after it, winds or loops round a wrap (:func:`o2m.osim.spikes.opensim_windings`,
    :func:`~o2m.osim.spikes.opensim_loops`: no reference there, as in
    :func:`o2m.validate.muscles.compare_muscles`) goes to ``at_opensim_failures`` instead, with
    that evidence under ``"opensim_failure"``.
    """
    pair = ModelPair(osim_path, mjcf_path, assembly_accuracy)
    model, qpos = pair.mj_model, np.asarray(qpos, float).reshape(-1, *np.shape(qpos)[-2:])
    adr = {c: joint_qpos_address(model, c) for c in pair.indep_names}
    os_index = {n: i for i, (n, _, _) in enumerate(pair.matched)}
    jumps = []
    for b, traj in enumerate(qpos):
        change, explained = tendon_length_steps(model, traj)
        excess = np.abs(change - explained)
        for t in np.flatnonzero(excess.max(axis=0, initial=0.0) > jump_atol):
            k, name = int(np.argmax(excess[:, t])), pair.tendon_names[t]
            row = {"tendon": name, "trajectory": b, "step": k, "mujoco": float(excess[k, t]),
                   "opensim": None, "opensim_step": None}
            if name in os_index:
                lo, hi = max(k - window, 0), min(k + 1 + window, len(traj) - 1)
                found = _opensim_steps(pair, traj[lo:hi + 1], adr, os_index[name], explained[lo:hi, t])
                if found is not None:
                    row["opensim"], row["opensim_step"] = found
            jumps.append(row)
    jumps.sort(key=lambda j: -j["mujoco"])
    flips, at_failures = [], []
    for j in jumps:
        if j["opensim"] is None or j["opensim"] < 0.5 * j["mujoco"]:
            failure = _opensim_failure(pair, qpos[j["trajectory"]], j["step"], adr, os_index.get(j["tendon"]))
            if failure is None:
                flips.append(j)
            else:
                at_failures.append({**j, "opensim_failure": failure})
    return jsonable({"osim_path": pair.osim_path, "mjcf_path": pair.mjcf_path, "jump_atol": jump_atol,
                     "jumps": jumps, "flips": flips, "at_opensim_failures": at_failures})


def _opensim_failure(pair: ModelPair, traj: np.ndarray, step: int, adr: dict[str, int],
                     index: int | None) -> dict[str, Any] | None:
    """OpenSim's path ``index`` (into ``pair.matched``) winding or looping round a wrap at the
    MuJoCo pose ``traj[step]`` or ``traj[step + 1]`` (``{"test", "wrap", ...}``), else None."""
    if index is None:
        return None
    for q in traj[step:step + 2]:
        values = {c: float(q[a]) for c, a in adr.items()}
        for test in (opensim_windings, opensim_loops):
            try:
                found = test(pair, values, [index])
            except Exception:  # OpenSim fails to assemble there: no evidence
                found = {}
            if index in found:
                return found[index]
    return None


def _opensim_steps(pair: ModelPair, poses: np.ndarray, adr: dict[str, int], index: int,
                   explained: np.ndarray) -> tuple[float, float] | None:
    """OpenSim's length along MuJoCo poses (n, nq) against ``explained`` (n - 1,), MuJoCo's
    smooth change between neighbours: ``(|its change over all poses less explained's sum|,
    its largest such step between neighbours)``, metres; None if a pose fails to assemble."""
    try:
        lengths = np.array([pair.os_lengths(pair.os_state({c: float(q[a]) for c, a in adr.items()}))[index]
                            for q in poses])
    except Exception:
        return None
    return float(abs(lengths[-1] - lengths[0] - explained.sum())), float(np.abs(np.diff(lengths) - explained).max())
