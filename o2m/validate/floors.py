"""Which of a converted model's missed targets are OpenSim's own floors, and which are o2m's.

A target is impossible for any MuJoCo tendon where OpenSim's own path forbids it: its length
steps (a wrap switching) by more than twice the length target, so a continuous tendon is further
than the target on one side of the step; or its dynamic moment arm (``computeMomentArm``) is not
the derivative of its length, so no tendon within the length target has that moment arm (a
tendon's moment arm is always ``-dL/dq`` of its own length). :func:`target_misses` lists every
path and (path, coordinate) pair of a :class:`~o2m.validate.muscles.MuscleReport` that misses the
targets, each with the floor measured along one coordinate (:mod:`o2m.validate.jumps`), from the
defaults and, for a length, through the pose of the path's worst error and along lines from it in
the space of all coordinates; a floor found there is a lower bound, so a miss without one may
still be OpenSim's.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from o2m.osim.pair import ModelPair
from o2m.validate.jumps import continuous_tendon_front, opensim_length_steps, opensim_steps_around
from o2m.validate.muscles import LEN_PCT, MA_MAX_MM, MA_P95_MM, MuscleReport

__all__ = ["TargetMiss", "length_misses", "target_misses"]

#: Poses of the one-coordinate sweep that measures a moment-arm floor.
FRONT_POSES = 301


@dataclass
class TargetMiss:
    """One missed target: a path's worst length (``coordinate`` None, ``value`` and ``target``
    in % of OpenSim's length) or a (path, coordinate) moment-arm RMS (m).

    ``floor``: what no continuous tendon can beat, in the same unit: for a length, half the
    largest step of OpenSim's length along any coordinate (``floor_coordinate``; the others at
    their defaults, or at the path's worst pose where ``floor_through_worst``) or along a line
    from the worst pose (``floor_coordinate`` "a line",
    :func:`~o2m.validate.jumps.opensim_steps_around`); for a moment
    arm, the least RMS from ``computeMomentArm`` of any tendon within the length target (or, where
    a length step leaves none, within that step's floor) along ``coordinate``. None where none
    was found. ``target_impossible``: the floor is beyond the target, so no tendon meets it;
    ``at_floor``: moreover the value is within the target of that floor (the target applies on
    top of what OpenSim forces), so the miss is OpenSim's, not o2m's.
    """

    path: str
    coordinate: str | None
    value: float
    target: float
    floor: float | None = None
    floor_coordinate: str | None = None
    floor_through_worst: bool = False

    @property
    def target_impossible(self) -> bool:
        return self.floor is not None and self.floor > self.target

    @property
    def at_floor(self) -> bool:
        return self.target_impossible and self.value - self.floor <= self.target

    def describe(self) -> str:
        """One line, e.g. ``FPL length 4.32 % > 1 % (OpenSim step floor 2.10 % along flexion)``."""
        if self.coordinate is None:
            what = f"{self.path} length {self.value:.3g} % > {self.target:g} %"
            where = ((" from" if self.floor_coordinate == "a line" else " through") + " its worst pose"
                     if self.floor_through_worst else "")
            floor = (f"OpenSim step floor {self.floor:.3g} % along {self.floor_coordinate}{where}"
                     if self.floor is not None else "no step in OpenSim's length")
        else:
            what = (f"{self.path} moment arm about {self.coordinate} {self.value * 1e3:.3g} mm RMS "
                    f"> {self.target * 1e3:g} mm")
            floor = (f"any tendon at least {self.floor * 1e3:.3g} mm" if self.floor is not None
                     else "no floor measured")
        verdict = ("OpenSim's floor" if self.at_floor else
                   "o2m's, above OpenSim's floor" if self.target_impossible else "o2m's")
        return f"{what} ({floor}: {verdict})"


def length_misses(osim_path: str | os.PathLike, mjcf_path: str | os.PathLike, report: MuscleReport, *,
                  pair: ModelPair | None = None, steps: list[dict] | None = None,
                  assembly_accuracy: float | None = 1e-12) -> list[TargetMiss]:
    """Every path of ``report`` (:func:`~o2m.validate.compare_muscles` of the two models) over the
    length target, largest first, with the largest step of OpenSim's length along one coordinate
    from the defaults (``steps``, measured where None) or through the pose of the path's worst
    error, or, where those leave the miss o2m's, along lines from that pose (its floor).
    ``pair``: the two models already loaded."""
    pair = pair or ModelPair(osim_path, mjcf_path, assembly_accuracy)
    steps = opensim_length_steps(osim_path, mjcf_path, pair=pair) if steps is None else steps
    out = []
    for name, err in report.muscles.items():
        if err.max_len_pct <= LEN_PCT:
            continue
        own = [s for s in steps if s["path"] == name]
        if err.worst_pose:
            own += opensim_length_steps(pair.osim_path, pair.mjcf_path, pair=pair, through=err.worst_pose,
                                        paths=[name])
            if not _length_miss(name, err.max_len_pct, own).at_floor:  # the lines cost most: only if they can tell
                own += opensim_steps_around(pair, name, err.worst_pose)
        out.append(_length_miss(name, err.max_len_pct, own))
    return sorted(out, key=lambda m: -m.value)


def _length_miss(name: str, value: float, steps: list[dict]) -> TargetMiss:
    """The length miss ``value`` (%) of path ``name`` with its largest step among ``steps`` as floor."""
    top = max(steps, key=lambda s: s["floor_pct"], default=None)
    return TargetMiss(name, None, value, LEN_PCT, top and top["floor_pct"], top and (top["coordinate"] or "a line"),
                      bool(top and top.get("through")))


def _arm_misses(report: MuscleReport, pair: ModelPair, steps: list[dict], poses: int) -> list[TargetMiss]:
    if report.ma_p95 * 1e3 > MA_P95_MM:
        above = MA_P95_MM
    elif report.ma_max * 1e3 > MA_MAX_MM:
        above = MA_MAX_MM
    else:
        return []
    out = []
    for name, err in report.muscles.items():
        for cname, arm in err.moment_arms.items():
            if arm.rms * 1e3 <= above or cname not in pair.indep_names:
                continue
            target = (MA_MAX_MM if arm.rms * 1e3 > MA_MAX_MM else MA_P95_MM) * 1e-3
            step = max((s["floor_pct"] for s in steps if s["path"] == name and s["coordinate"] == cname), default=0.0)
            pct = max(LEN_PCT, 1.05 * step)  # within a length step's own floor where it leaves none within 1 %
            front = continuous_tendon_front(pair.osim_path, pair.mjcf_path, name, cname, pcts=(pct,), n=poses,
                                            pair=pair, steps=steps)["front"][pct]
            out.append(TargetMiss(name, cname, arm.rms, target, front and front["rms"]))
    return out


def target_misses(osim_path: str | os.PathLike, mjcf_path: str | os.PathLike, report: MuscleReport, *,
                  poses: int = FRONT_POSES, assembly_accuracy: float | None = 1e-12) -> list[TargetMiss]:
    """Every missed length and moment-arm target of ``report`` (:func:`~o2m.validate.compare_muscles`
    of the same two models), each with OpenSim's floor for it: lengths over
    :data:`~o2m.validate.muscles.LEN_PCT`; where the moment arms' 95th percentile misses
    :data:`~o2m.validate.muscles.MA_P95_MM`, every pair above it, else where their maximum misses
    :data:`~o2m.validate.muscles.MA_MAX_MM`, every pair above that (a pair above both is held to
    the larger). The median's target is not attributed to pairs. Floors come from sweeps of
    one coordinate, the others at their defaults (``poses`` poses for a moment arm) or, for a
    length, at the pose of the path's worst error, and from lines from that pose. Lengths first,
    then moment arms, each largest first."""
    if report.max_len_pct <= LEN_PCT and report.ma_p95 * 1e3 <= MA_P95_MM and report.ma_max * 1e3 <= MA_MAX_MM:
        return []
    pair = ModelPair(osim_path, mjcf_path, assembly_accuracy)
    steps = opensim_length_steps(osim_path, mjcf_path, pair=pair)
    lengths = length_misses(osim_path, mjcf_path, report, pair=pair, steps=steps)
    arms = sorted(_arm_misses(report, pair, steps, poses), key=lambda m: -m.value)
    return lengths + arms
