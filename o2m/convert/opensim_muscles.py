"""OpenSim's own muscles in a converted model: Schutte1993 muscles as ``o2m.schutte`` actuator plugins.

:func:`o2m.convert.convert` gives every muscle a MuJoCo muscle fitted to OpenSim's static curves
(a rigid tendon, no fibre state). :func:`write_opensim_muscles` writes beside that MJCF a second
one, ``<stem>_opensim_muscles.xml``, in which each Schutte1993Muscle_Deprecated is OpenSim's
muscle itself (:mod:`o2m.mj.schutte_plugin`: elastic tendon, activation and fibre length as the
plugin's state, each muscle's own parameters and curves), started where OpenSim starts a
simulation of the model (its default state, muscles in equilibrium; a muscle whose equilibrium
OpenSim leaves at fibre length 0, where its tendon would take the whole unit's length in the
plugin, at its static equilibrium instead, :meth:`o2m.osim.schutte.SchutteMuscle.equilibrium`). Muscles
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

__all__ = ["OpenSimMuscles", "SUPPORTED", "disabled_actuators", "write_opensim_muscles"]

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
    #: muscles whose equilibrium OpenSim leaves at a fibre length of 0, started instead at their
    #: static equilibrium: {name: fibre length m}
    equilibrated: dict[str, float] = field(default_factory=dict)


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
    disabled = sorted(set(names) & disabled_actuators(xml))
    names = [n for n in names if n not in disabled]
    if not names:
        raise O2MError(f"{osim}: every {', '.join(SUPPORTED)} muscle is disabled (appliesForce false)")
    muscles = schutte_muscles(osim, names)
    start, equilibrated = {}, {}
    for name, (activation, fibre, length) in default_states(osim, names).items():
        if not fibre > 0.0:  # no fibre: a pennation of 0 over 0, which OpenSim's muscle never leaves
            fibre = equilibrated[name] = muscles[name].equilibrium(activation, length)
        start[name] = (activation, fibre)
    with_schutte_muscles(xml, out, muscles, start=start)
    return OpenSimMuscles(out, names, {n: t for n, t in types.items() if t not in SUPPORTED}, disabled, equilibrated)


def disabled_actuators(xml: str | os.PathLike[str]) -> set[str]:
    """The actuators of the MJCF ``xml`` in a group its ``actuatorgroupdisable`` option disables."""
    model = mujoco.MjModel.from_xml_path(str(xml))
    return {model.actuator(a).name for a in range(model.nu)
            if 0 <= model.actuator_group[a] < 31 and model.opt.disableactuator & (1 << int(model.actuator_group[a]))}
