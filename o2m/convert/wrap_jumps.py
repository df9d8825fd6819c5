"""Side switches a fitted tendon makes between its fitting poses, and whether OpenSim's path makes them.

The wrap fit scores a tendon at sampled poses only. Between them MuJoCo's path may go round the
other side of a geom (a side site's choice flipping, a sphere's shorter way switching) where
OpenSim's path does not: no error at the poses shows it, and a simulation meets it as a jump of
the tendon's length, a force that steps. So each fitted variant's tendon is walked along the
straight lines between consecutive fitting poses in MuJoCo (:func:`segment_jumps`, in the fit's
workers, MuJoCo only), and OpenSim's length at each jump's two ends (:func:`count_flips`, in the
parent) tells a flip, which OpenSim does not share, from a step OpenSim's path makes too (a wrap
switching on, a winding). :func:`o2m.convert.wrap_choice.best_variant` then prefers a variant
that does not flip.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

from o2m.mj.tendons import tendon_length_steps

#: A length change between neighbouring samples that the tendon's Jacobian leaves unexplained by
#: more than this (m) is a jump (as :func:`o2m.validate.jumps.trajectory_jumps` counts them).
JUMP_ATOL = 1e-3
#: Samples along each line between two consecutive fitting poses.
SEGMENT_SAMPLES = 60
#: OpenSim shares a jump when its own length change over the jump's two samples differs from
#: MuJoCo's smooth (Jacobian-explained) change by at least this fraction of MuJoCo's jump.
SHARED_FRACTION = 0.5


def segment_jumps(model: mujoco.MjModel, qpos: np.ndarray, *, tendon: int = 0,
                  samples: int = SEGMENT_SAMPLES, atol: float = JUMP_ATOL) -> list[dict[str, Any]]:
    """The largest jump of tendon ``tendon`` on each line between consecutive rows of ``qpos``.

    Args:
        model: a MuJoCo model whose geoms and sites are already those of the fit.
        qpos: shape (N, nq), poses; each line is walked in ``samples`` steps (``mj_integratePos``,
            so ball and free joints stay unit quaternions).
    Returns:
        One dict per line with a jump over ``atol`` (m): ``before`` and ``after`` (the two
        samples, lists of nq floats), ``explained`` (m, the change the Jacobian explains there)
        and ``excess`` (m, the rest).
    """
    qpos = np.atleast_2d(np.asarray(qpos, dtype=float))
    found = []
    dq = np.empty(model.nv)
    for a, b in zip(qpos[:-1], qpos[1:], strict=True):
        mujoco.mj_differentiatePos(model, dq, 1.0, a, b)
        line = np.empty((samples, model.nq))
        for k, s in enumerate(np.linspace(0.0, 1.0, samples)):
            line[k] = a
            mujoco.mj_integratePos(model, line[k], dq, s)
        change, explained = tendon_length_steps(model, line)
        excess = np.abs(change[:, tendon] - explained[:, tendon])
        k = int(np.argmax(excess))
        if excess[k] > atol:
            found.append({"before": line[k].tolist(), "after": line[k + 1].tolist(),
                          "explained": float(explained[k, tendon]), "excess": float(excess[k])})
    return found


def count_flips(osim_path: str | os.PathLike, xml_path: str | os.PathLike, fits: Sequence[Any]) -> None:
    """Set each fit's ``flips``: how many of its ``jumps`` (:func:`segment_jumps`) OpenSim's path
    does not share. OpenSim's length at a jump's two samples (its independent coordinates read
    from MuJoCo's joints of the same names) shares the jump when it changes by the MuJoCo jump's
    :data:`SHARED_FRACTION` or more beyond MuJoCo's smooth change; a sample OpenSim cannot
    assemble counts as shared (no reference there). ``xml_path``: the MJCF file of the model the
    fits' poses are of."""
    if not any(f.jumps for f in fits):
        return
    from o2m.mj.posing import joint_qpos_address
    from o2m.osim.pair import ModelPair

    pair = ModelPair(osim_path, os.fspath(xml_path))
    adr = {c: joint_qpos_address(pair.mj_model, c) for c in pair.indep_names}
    col = {n: i for i, (n, _, _) in enumerate(pair.matched)}

    def length(q: list[float], tendon: str) -> float | None:
        try:
            return float(pair.os_lengths(pair.os_state({c: q[a] for c, a in adr.items()}))[col[tendon]])
        except Exception:  # noqa: BLE001 - OpenSim cannot assemble there: no reference
            return None

    for f in fits:
        if f.tendon not in col:
            continue
        f.flips = sum(not opensim_shares(length(j["before"], f.tendon), length(j["after"], f.tendon), j)
                      for j in f.jumps)


def opensim_shares(before: float | None, after: float | None, jump: dict[str, Any]) -> bool:
    """Whether OpenSim's lengths (m) at a jump's two samples step with it: they change by at least
    :data:`SHARED_FRACTION` of MuJoCo's ``excess`` beyond MuJoCo's ``explained`` change, or one of
    them is missing (OpenSim could not assemble: no reference)."""
    if before is None or after is None:
        return True
    return abs(after - before - jump["explained"]) >= SHARED_FRACTION * jump["excess"]


__all__ = ["JUMP_ATOL", "SEGMENT_SAMPLES", "count_flips", "opensim_shares", "segment_jumps"]
