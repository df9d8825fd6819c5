"""The wrap fit's targets where OpenSim's length is not that of the path it draws.

OpenSim has two moment arms for a path: ``computeMomentArm`` (its MomentArmSolver, the one it
applies in forward dynamics: from the directions of the path it draws) and ``-dL/dq`` of its
``getLength``. They differ where OpenSim's length is not that of the path it draws: over several
wraps on one segment its wrap iterations can keep an arc length from an earlier iteration
(Rajagopal2016's gasmed_r, both wraps touched at knee angles 0-0.43 rad: ``getLength`` 456.7 mm
for a drawn path of 463.4 mm at 0 rad, ``-dL/dq`` 0-9 mm where ``computeMomentArm`` is 18-20 mm
and the drawn path's ``-dL/dq`` 19-20 mm). They also differ, by design, where a MovingPathPoint
moves along a same-body segment (:mod:`o2m.convert.pathforces`): there the length is that of the
drawn path and ``-dL/dq`` its moment arm. Where the two disagree, :func:`drawn_path_arms`
takes the one nearer the drawn path's ``-dL/dq`` (central differences of
:func:`o2m.osim.spikes.drawn_length`).

A tendon has one length, and its moment arm is ``-dL/dq`` of it: it cannot follow both OpenSim's
``getLength`` and ``computeMomentArm`` where they disagree. :func:`drawn_targets` fits it to the
drawn path (its length and moment arms, consistent) shortened by the midrange of the drawn path's
excess over ``getLength``, where that excess spreads by over 1 mm. Its length then stays within
half the spread of ``getLength``; where half the spread is over 0.8 % (:data:`DRAWN_GATE`: the
1 % length target less a fifth for the fit's own residual), the targets go only the share of the
way from ``getLength`` and ``-dL/dq`` that keeps them there, length and moment arms alike, and
where that share would be under :data:`MIN_SHARE` they stay ``getLength`` and ``-dL/dq`` (a
two-cylinder path up to 29 mm, over 5 %, short of its drawn path: following it all the way cost
1.22 % of length for 17.5 mm of moment arm instead of 19.9).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from o2m.osim.spikes import drawn_length

#: Largest spread (fraction of the length) of the drawn path's excess over getLength for which a
#: tendon follows the drawn path all the way (:func:`drawn_targets`; beyond, a share of the way),
#: and the smallest spread (m) for which it follows it at all.
DRAWN_GATE = 0.016
MIN_SPREAD = 1e-3
#: Below this share of the way (a spread over twice the gate) the drawn path and getLength disagree
#: by more than a tendon could split, and the targets stay getLength and -dL/dq.
MIN_SHARE = 0.5
#: OpenSim's two moment arms (m) closer than this are taken to agree (K3's median target: below it
#: the choice does not matter; where they agree they differ by about 1e-8 m).
MA_AGREEMENT = 5e-4


def drawn_path_arms(pair: Any, state: Any, values: Mapping[str, float], coords: Sequence[str],
                    paths: Mapping[int, set[str]], dldq: np.ndarray, step: float,
                    stepped: Mapping[str, tuple[Any, Any]] | None = None) -> np.ndarray:
    """``dldq`` ((n paths, n coords), m; OpenSim's ``-dL/dq`` at ``state``, the pose of independent
    ``values``) with, for the paths ``paths`` (index into ``pair.matched`` -> the coordinates it
    spans), each moment arm about a spanned coordinate that
    ``computeMomentArm`` disagrees with by over :data:`MA_AGREEMENT` replaced by it when it is the
    nearer of the two to the drawn path's ``-dL/dq`` (central differences of step ``step``).
    NaN entries (a step of OpenSim's length inside
    the difference) stay NaN. ``stepped``: coordinate -> the OpenSim states (``pair.os_state``)
    with it moved by ``+step`` and ``-step``, where the caller has them already (each costs an
    assembly)."""
    out = dldq.copy()
    for j, cname in enumerate(coords):
        coord = pair.coord(cname)
        drawn: dict[int, float] | None = None
        for i, spanned in paths.items():
            if cname not in spanned or not np.isfinite(dldq[i, j]):
                continue
            force = pair.matched[i][2]
            dynamic = float(force.computeMomentArm(state, coord))
            if abs(dynamic - dldq[i, j]) <= MA_AGREEMENT:
                continue
            drawn = drawn if drawn is not None else _drawn_slopes(pair, values, cname, paths, step,
                                                                  (stepped or {}).get(cname))
            if abs(dynamic - drawn[i]) < abs(dldq[i, j] - drawn[i]):
                out[i, j] = dynamic
    return out


def _drawn_slopes(pair: Any, values: Mapping[str, float], cname: str, paths: Sequence[int],
                  step: float, stepped: tuple[Any, Any] | None = None) -> dict[int, float]:
    """Path index -> ``-d(drawn length)/dq`` about ``cname`` (m) by central differences; ``stepped``:
    the states at ``cname`` +-``step`` when made already."""
    asm = bool(pair.dependent)
    up = stepped[0] if stepped else pair.os_state({**values, cname: values[cname] + step}, assemble=asm)
    up_len = {i: drawn_length(pair.os_model, up, pair.matched[i][0]) for i in paths}
    dn = stepped[1] if stepped else pair.os_state({**values, cname: values[cname] - step}, assemble=asm)
    return {i: -(up_len[i] - drawn_length(pair.os_model, dn, pair.matched[i][0])) / (2 * step) for i in paths}


def drawn_gaps(pair: Any, state: Any, paths: Mapping[int, set[str]], lengths: np.ndarray) -> np.ndarray:
    """(n paths,) the drawn path's length minus OpenSim's ``lengths`` (getLength) in ``state``, m,
    for the paths ``paths`` (indices into ``pair.matched``); 0 for the others."""
    out = np.zeros(len(lengths))
    for i in paths:
        out[i] = drawn_length(pair.os_model, state, pair.matched[i][0]) - lengths[i]
    return out


def drawn_targets(length: np.ndarray, gap: np.ndarray, arm: np.ndarray,
                  drawn_arm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One tendon's length (n poses,) and moment-arm ((n, n coords)) targets, m: OpenSim's
    ``length`` and ``-dL/dq`` ``arm`` where the spread of ``gap`` (drawn length minus ``length``)
    is at most :data:`MIN_SPREAD` or over ``DRAWN_GATE / MIN_SHARE`` of the length; else the drawn
    path shortened by the midrange of ``gap`` and ``drawn_arm`` (:func:`drawn_path_arms`),
    blended towards ``length`` and ``arm`` where the spread is over :data:`DRAWN_GATE` of the
    length: a share ``DRAWN_GATE * min(length) / spread`` of the way, so that the length target
    stays within half that gate of ``length`` and the two targets stay consistent (the blended
    length's ``-dL/dq`` is the blended arm)."""
    spread = float(np.max(gap) - np.min(gap)) if len(gap) else 0.0
    if spread <= MIN_SPREAD:
        return length, arm
    offset = gap - 0.5 * float(np.max(gap) + np.min(gap))
    share = min(1.0, DRAWN_GATE * float(np.min(length)) / spread)
    if share < MIN_SHARE:
        return length, arm
    if share == 1.0:
        return length + offset, drawn_arm
    return length + share * offset, arm + share * (drawn_arm - arm)


__all__ = ["DRAWN_GATE", "MA_AGREEMENT", "MIN_SHARE", "MIN_SPREAD", "drawn_gaps", "drawn_path_arms", "drawn_targets"]
