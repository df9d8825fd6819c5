"""OpenSim's targets for the wrap fit (:mod:`o2m.convert.wrapfit`): sampled poses, each tendon's
length and moment arms there, and the points where its path touches its wrap objects.

* Poses: every independent coordinate drawn uniformly in its range (seeded); OpenSim poses each
  (:meth:`~o2m.osim.pair.ModelPair.os_state`), MuJoCo's equality-driven joints follow.
* Lengths: OpenSim ``getLength`` (m); for a tendon whose same-body segments are held, its held
  length; for one with length via points (:mod:`o2m.convert.lengthvia`), its designed length.
* Moment arms: ``-dL/dq`` by central differences in OpenSim, steps of :data:`OS_FD_STEP` and ten
  times that (a pair that disagrees, a wrap flipping within the step, is no target); the drawn
  path's where OpenSim's length is not it (:mod:`o2m.convert.drawn_arms`).
* A pose where OpenSim's own path fails for a tendon (:func:`o2m.osim.spikes.opensim_failures`)
  or draws non-finite points is no target for that tendon.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from o2m.convert.drawn_arms import drawn_gaps, drawn_path_arms, drawn_targets

#: Central-difference step of OpenSim's moment arms (radians or metres).
OS_FD_STEP = 1e-5
#: OpenSim moment arms by steps of 1 and 10 OS_FD_STEP that differ by more than this (m) are left out.
MA_CONSISTENCY = 1e-3


def _held_correction(pair: Any, state: Any, held: dict[str, dict], col: dict[str, int]) -> np.ndarray:
    """(n paths,) what a held tendon's length differs from OpenSim's getLength in ``state``: its
    held length minus the current length of its held same-body segments (0 for other paths)."""
    out = np.zeros(len(col))
    for name, h in held.items():
        if name not in col:
            continue
        pps = pair.force(name).getGeometryPath().getPathPointSet()
        now = sum(float(np.linalg.norm(pps.get(a).getLocationInGround(state).to_numpy()
                                       - pps.get(b).getLocationInGround(state).to_numpy())) for a, b in h["pairs"])
        out[col[name]] = h["length"] - now
    return out


def _designed_correction(pair: Any, state: Any, designed: dict[str, list], col: dict[str, int]) -> np.ndarray:
    """(n paths,) what a tendon with length via points differs from OpenSim's getLength in
    ``state`` (:func:`o2m.lengthvia.designed_correction`; 0 for other paths)."""
    from o2m.convert.lengthvia import designed_correction

    out = np.zeros(len(col))
    for name, vias in designed.items():
        if name in col:
            out[col[name]] = sum(designed_correction(pair.os_model, state, v) for v in vias)
    return out


def fit_targets(osim_path: str, xml_path: str, tendons: Sequence[str], n_poses: int, seed: int,
                held: dict[str, dict] | None = None, contacts: dict[str, set[str]] | None = None,
                n_contact: int = 0, designed: dict[str, list] | None = None, n_arms: int | None = None
                ) -> tuple[Any, dict[str, dict[str, Any]]]:
    """Sample poses; return the MuJoCo model and per tendon the qpos, dv, lengths and moment arms
    (of the held tendon, for the paths in ``held``; of the designed length, for the paths in
    ``designed``) and, over the first ``n_contact`` poses, the wrap-arc points of each tendon's
    wrap objects named in ``contacts`` (tendon -> wrap names). Poses after the first ``n_arms``
    (default: every pose) get lengths only: no moment arms (NaN; each pose's cost two OpenSim
    assemblies per coordinate and step) and the tests of OpenSim's own failures only for the
    samples the converted model misses by over 5 % (:func:`~o2m.osim.spikes.band_suspects`), not
    for every suspect (a model whose paths are far from OpenSim has many): for choosing among fits
    on poses they were not fitted on, not as targets."""
    from o2m.mj.posing import joint_qpos_address, resolve_joint_equalities
    from o2m.mj.tendons import coordinate_direction, qpos_to_dof
    from o2m.osim.pair import ModelPair
    from o2m.osim.runtime import sample_bounds
    from o2m.osim.spikes import SPIKE_TOL, band_suspects, opensim_failures, wrap_contacts

    pair = ModelPair(osim_path, xml_path)
    m = pair.mj_model
    names = [n for n, _, _ in pair.matched]
    col = {n: i for i, n in enumerate(names)}
    spans = pair.spanned()
    wanted = [t for t in tendons if t in col]
    held = {t: h for t, h in (held or {}).items() if t in wanted}
    designed = {t: v for t, v in (designed or {}).items() if t in wanted}

    def corrections(state: Any) -> np.ndarray:  # what each target differs from getLength by
        return _held_correction(pair, state, held, col) + _designed_correction(pair, state, designed, col)
    coords = sorted(set().union(*[spans.get(t, set()) for t in wanted]) if wanted else set(),
                    key=pair.indep_names.index)
    rng = np.random.default_rng(seed)
    bounds = np.array([sample_bounds(c) for c in pair.indep], dtype=float).reshape(-1, 2)
    qpos, lengths, arms, valid, drawn_arms, gaps = [], [], [], [], [], []  # the last two: drawn_arms's
    touched: list[dict[str, dict[str, list[np.ndarray]]]] = []  # per pose: tendon -> wrap -> points
    contacts = {t: w for t, w in (contacts or {}).items() if t in wanted and w}
    wanted_idx = np.array([col[t] for t in wanted], dtype=int)
    plain = {col[t]: spans.get(t, set()) for t in wanted if t not in held and t not in designed}  # others: own targets
    attempts = 0
    while len(qpos) < n_poses and attempts < 4 * n_poses:
        attempts += 1
        values = dict(zip(pair.indep_names, rng.uniform(bounds[:, 0], bounds[:, 1]), strict=True))
        try:
            state = pair.os_state(values)
            values = pair.os_indep_values(state)
            raw = pair.os_lengths(state)
            base = raw + corrections(state)
            arm = np.full((len(names), len(coords)), np.nan)
            asm = bool(pair.dependent)
            stepped = {}  # coordinate -> its states at +-10 OS_FD_STEP, which drawn_path_arms reuses
            lengths_only = n_arms is not None and len(qpos) >= n_arms
            for j, c in enumerate([] if lengths_only else coords):
                ma = []
                for h in (OS_FD_STEP, 10 * OS_FD_STEP):
                    s_up = pair.os_state({**values, c: values[c] + h}, assemble=asm)
                    up = pair.os_lengths(s_up) + corrections(s_up)
                    s_dn = pair.os_state({**values, c: values[c] - h}, assemble=asm)
                    dn = pair.os_lengths(s_dn) + corrections(s_dn)
                    ma.append(-(up - dn) / (2 * h))
                stepped[c] = (s_up, s_dn)
                # a length discontinuity within the step (a wrap flipping) is no moment arm
                arm[:, j] = np.where(np.abs(ma[0] - ma[1]) <= MA_CONSISTENCY, ma[0], np.nan)
            drawn_arm = drawn_path_arms(pair, state, values, coords, plain, arm, 10 * OS_FD_STEP, stepped)
            gap = drawn_gaps(pair, state, plain, raw)
        except Exception:  # assembly failure: draw another pose
            continue
        # OpenSim's own length spiking here (a wrap going the wrong way round) is no target
        ok = np.ones(len(names), dtype=bool)
        converted = pair.mj_lengths(values)[pair.tendon_ids]
        err = np.abs(converted - base)
        suspects = wanted_idx[err[wanted_idx] > SPIKE_TOL]
        banded = np.intersect1d(band_suspects(converted, base), wanted_idx)
        # lengths-only poses: the samples far off only (a spike there can decide a choice)
        for i in opensim_failures(pair, values, banded if lengths_only else suspects, raw, banded):
            ok[i] = False
        # a wrap arc OpenSim draws with non-finite points (MoBL_ARMS_model_for_mujoco.osim's DELT3 at
        # one pose of the full fit's): no target, and one NaN would spread to every pose's
        ok &= np.isfinite(raw) & np.isfinite(gap)
        valid.append(ok)
        touched.append({t: wrap_contacts(pair, state, t, w) for t, w in contacts.items()}
                       if len(touched) < n_contact else {})
        q = np.array(m.qpos0, dtype=float)
        for n, v in values.items():
            q[joint_qpos_address(m, n)] = v
        resolve_joint_equalities(m, q, pair.plan)
        qpos.append(q)
        lengths.append(base)
        arms.append(arm)
        drawn_arms.append(drawn_arm)
        gaps.append(gap)
    qpos_a, len_a, arm_a, ok_a = np.array(qpos), np.array(lengths), np.array(arms), np.array(valid)
    dv_all = np.array([[qpos_to_dof(m, coordinate_direction(m, q, joint_qpos_address(m, c), pair.plan))
                        for c in coords] for q in qpos_a]).reshape(len(qpos_a), len(coords), m.nv)
    out = {}
    for t in wanted:
        cs = [j for j, c in enumerate(coords) if c in spans.get(t, set())]
        rows = ok_a[:, col[t]]
        length, arm = drawn_targets(len_a[rows, col[t]], np.array(gaps)[rows, col[t]], arm_a[rows, col[t]][:, cs],
                                    np.array(drawn_arms)[rows, col[t]][:, cs])
        out[t] = {"qpos": qpos_a[rows], "dv": dv_all[rows][:, cs, :], "length": length,
                  "arm": arm, "coordinates": [coords[j] for j in cs],
                  "spikes": int(np.sum(~rows)), "contacts": {}}
        for k, pose in enumerate(touched):
            if ok_a[k, col[t]]:
                for w, pts in pose.get(t, {}).items():
                    out[t]["contacts"].setdefault(w, []).extend(pts)
    return m, out


__all__ = ["MA_CONSISTENCY", "OS_FD_STEP", "fit_targets"]
