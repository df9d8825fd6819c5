"""OpenSim's own muscles in a converted model: Schutte1993 muscles as ``o2m.schutte`` actuator plugins.

:func:`o2m.convert.convert` gives every muscle a MuJoCo muscle fitted to OpenSim's static curves
(a rigid tendon, no fibre state). :func:`write_opensim_muscles` writes beside that MJCF a second
one, ``<stem>_opensim_muscles.xml``, in which each Schutte1993Muscle_Deprecated is OpenSim's
muscle itself (:mod:`o2m.mj.schutte_plugin`: elastic tendon, activation and fibre length as the
plugin's state, each muscle's own parameters and curves), started where OpenSim starts a
simulation of the model: its default state, muscles in static equilibrium
(:meth:`o2m.osim.schutte.SchutteMuscle.equilibrium`, OpenSim's ``computeIsometricForce``) on the
tendons MuJoCo has there, which are OpenSim's lengths but where a path is approximate. Muscles
OpenSim disables stay the conversion's disabled MuJoCo muscles, and muscles of other types stay
MuJoCo muscles, listed in the result. Opening the file needs o2m's plugin loaded:
``o2m.mj.schutte_plugin.load(folder)`` (compiled there with the machine's C compiler).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import mujoco

from o2m.errors import O2MError
from o2m.mj.schutte_plugin import with_schutte_muscles
from o2m.osim.schutte import default_states, muscle_types, schutte_muscles

__all__ = ["LENGTH_TOLERANCE", "OpenSimMuscles", "SUPPORTED", "default_lengths", "disabled_actuators",
           "write_opensim_muscles"]

#: A tendon further than this (m) from OpenSim's length at the default pose is reported.
LENGTH_TOLERANCE = 1e-4
#: The OpenSim muscle classes o2m can run as themselves in MuJoCo.
SUPPORTED = ("Schutte1993Muscle_Deprecated",)


@dataclass(frozen=True)
class OpenSimMuscles:
    """What :func:`write_opensim_muscles` wrote: the file, the muscles that are OpenSim's own in it,
    and the others (``{name: OpenSim class}``), which stay MuJoCo muscles."""

    xml: Path
    muscles: list[str]
    kept: dict[str, str] = field(default_factory=dict)
    #: muscles OpenSim disables (``appliesForce`` false), left as the conversion's MuJoCo muscles
    #: in its disabled actuator group: MuJoCo 4.0 applies a plugin actuator's force whatever its group
    disabled: list[str] = field(default_factory=list)
    #: the muscles whose MuJoCo tendon at the default pose is not OpenSim's length, by how much
    #: (m, MuJoCo minus OpenSim; over :data:`LENGTH_TOLERANCE`): their fibres start at the
    #: equilibrium on MuJoCo's length, not at OpenSim's fibre length
    offsets: dict[str, float] = field(default_factory=dict)


def write_opensim_muscles(osim: str | os.PathLike[str], xml: str | os.PathLike[str],
                          out: str | os.PathLike[str] | None = None) -> OpenSimMuscles:
    """Write ``out`` (default ``<xml stem>_opensim_muscles.xml`` beside ``xml``, the conversion of
    ``osim``) with every muscle of a :data:`SUPPORTED` class an ``o2m.schutte`` actuator. The
    plugin must be loaded first (:func:`o2m.mj.schutte_plugin.load`). Raises :class:`O2MError`
    when the model has no such muscle or ``xml`` has no actuator for one
    (:func:`o2m.mj.schutte_plugin.with_schutte_muscles` says which)."""
    xml = Path(xml)
    out = Path(out) if out is not None else xml.with_name(xml.stem + "_opensim_muscles.xml")
    types = muscle_types(osim)
    names = [n for n, t in types.items() if t in SUPPORTED]
    if not names:
        raise O2MError(f"{osim}: no muscle is one o2m runs as OpenSim's own ({', '.join(SUPPORTED)}); its muscles "
                       f"are {sorted(set(types.values())) or 'none'}")
    model = mujoco.MjModel.from_xml_path(str(xml))
    disabled = sorted(set(names) & disabled_actuators(model))
    names = [n for n in names if n not in disabled]
    if not names:
        raise O2MError(f"{osim}: every {', '.join(SUPPORTED)} muscle is disabled (appliesForce false)")
    muscles = schutte_muscles(osim, names)
    lengths = default_lengths(model, names)
    start, offsets = {}, {}
    for name, (activation, _, length) in default_states(osim, names).items():
        # in equilibrium on the tendon MuJoCo has (OpenSim's fibre length where it is OpenSim's
        # length, to 5e-8 m): a stiff tendon turns a path's millimetres into a start at many
        # times the muscle's force (a wrapped MoBL-ARMS's LAT1, 500 N at rest)
        start[name] = (activation, muscles[name].equilibrium(activation, lengths[name]))
        if abs(lengths[name] - length) > LENGTH_TOLERANCE:
            offsets[name] = lengths[name] - length
    with_schutte_muscles(xml, out, muscles, start=start)
    return OpenSimMuscles(out, names, {n: t for n, t in types.items() if t not in SUPPORTED}, disabled, offsets)


def default_lengths(model: mujoco.MjModel, names: list[str]) -> dict[str, float]:
    """The length (m) of each actuator ``names`` of ``model`` at its first keyframe (the
    converter's ``default-pose``: OpenSim's default pose)."""
    data = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    return {n: float(data.actuator_length[model.actuator(n).id]) for n in names}


def disabled_actuators(model: mujoco.MjModel) -> set[str]:
    """The actuators of ``model`` in a group its ``actuatorgroupdisable`` option disables."""
    return {model.actuator(a).name for a in range(model.nu)
            if 0 <= model.actuator_group[a] < 31 and model.opt.disableactuator & (1 << int(model.actuator_group[a]))}
