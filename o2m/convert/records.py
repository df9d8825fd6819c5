"""What a conversion records about its MuJoCo joints and approximations (the report lists them)."""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco


@dataclass
class Approximation:
    """A place where the MuJoCo model only approximates OpenSim, with the measured error."""

    element: str
    name: str
    what: str
    max_error: float
    units: str
    detail: str = ""
    joint: str = ""  # the MuJoCo joint whose motion is approximated, if any
    #: For a coupling: the worst and RMS error of d joint / d coordinate over the coordinate's
    #: range, in ``slope_units`` (for a path point's location against an angle, m/rad: a
    #: moment-arm error); None otherwise.
    slope_error: float | None = None
    slope_rms: float | None = None
    slope_units: str = ""
    #: True where no construction o2m tried is within the issue's targets here (over the
    #: converter's sampled poses): the error is the floor of o2m's constructions, not a fit left short.
    floor: bool = False


@dataclass
class JointRecord:
    """One MuJoCo joint: what drives it and how."""

    name: str
    kind: str  # "hinge" or "slide"
    opensim_joint: str
    axis: str
    coordinate: str | None  # the OpenSim coordinate whose value this joint is, if any
    driven_by: str | None  # MuJoCo joint of the equality that drives it, if any
    relation: str  # "coordinate", "linear", "quartic fit"


@dataclass
class BuildResult:
    """The MuJoCo spec being built, with the records of its joints, approximations and notes, and
    the activation each muscle actuator starts from in OpenSim's default state (name -> activation;
    the ``default-pose`` keyframe's ``act``)."""

    spec: mujoco.MjSpec
    joints: list[JointRecord] = field(default_factory=list)
    approximations: list[Approximation] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    activations: dict[str, float] = field(default_factory=dict)


def unique_name(name: str, taken: set[str]) -> str:
    """``name``, or ``name_1``, ``name_2``, ... when taken; added to ``taken``."""
    out, k = name, 1
    while out in taken:
        out, k = f"{name}_{k}", k + 1
    taken.add(out)
    return out
