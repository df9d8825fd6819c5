"""The ``o2m.fibre`` MuJoCo plugin: OpenSim's passive Schutte fibre, with its memory, inside MuJoCo.

A never-excited Schutte1993 muscle's fibre lengthens but never shortens (:mod:`o2m.osim.fibres`),
which no MuJoCo element reproduces: MuJoCo 4.0's actuator dynamics see only the control and the
activation, and its springs, dampers and friction are symmetric. A plugin can carry state, so
``fibre_plugin.c`` (shipped with o2m) keeps each fibre's length in ``mjData.plugin_state`` and adds
its tendon's pull to ``qfrc_passive`` in place of the tendon's spring and damper; a negative
length switches an instance off (an excited muscle, which pulls as the MuJoCo muscle it is). It is
compiled here with the machine's C compiler against the headers of the installed ``mujoco`` wheel
(which ships them), since MuJoCo loads plugins only from shared libraries; models that use it then
step with ``mj_step`` and ``mujoco.rollout`` (the fibre lengths are part of ``mjSTATE_FULLPHYSICS``).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np
from lxml import etree

from o2m.errors import O2MError
from o2m.mj import plugins

if TYPE_CHECKING:
    from o2m.osim.fibres import PassiveFibre

__all__ = ["OFF", "PLUGIN", "build", "fibre_instances", "fibre_state", "instance_name", "load", "with_fibres"]

PLUGIN = "o2m.fibre"
SOURCE = plugins.SOURCES[PLUGIN]
#: The equilibrium table spans the actuator's lengthrange widened by this much (m) on each side.
TABLE_MARGIN = 0.05
TABLE_POINTS = 600
#: The fibre length (m) of an instance that is off.
OFF = -1.0


def build(folder: str | Path) -> Path:
    """The plugin library in ``folder`` (compiled there if this source and MuJoCo version have none)."""
    return plugins.build(SOURCE, folder)


def load(folder: str | Path) -> Path:
    """Build the plugin (:func:`build`) and load it into this process's MuJoCo; returns the library."""
    return plugins.load(SOURCE, folder)


def with_fibres(xml_in: str | Path, xml_out: str | Path, fibres: dict[str, PassiveFibre],
                fibre_lengths: dict[str, float] | None = None) -> Path:
    """Write ``xml_out``: ``xml_in`` with an ``o2m.fibre`` instance on the tendon of each muscle of
    ``fibres``, starting at ``fibre_lengths`` m (default, and where missing: off, -1). An instance
    that is on pulls as its fibre instead of the tendon's spring and damper; the actuator stays for
    the active force. Switch instances per run with :func:`fibre_state`. ``xml_out`` goes beside
    ``xml_in`` (the meshes' relative paths)."""
    fibre_lengths = fibre_lengths or {}
    model = mujoco.MjModel.from_xml_path(str(xml_in))
    tree = etree.parse(str(xml_in))
    root = tree.getroot()
    ext = root.find("extension")
    ext = etree.SubElement(root, "extension") if ext is None else ext
    plugin = etree.SubElement(ext, "plugin", plugin=PLUGIN)
    for name, fibre in fibres.items():
        a = model.actuator(name).id
        t = int(model.actuator_trnid[a, 0])
        if np.any(model.tendon_dampingpoly[t] != 0):
            raise O2MError(f"{name}: the {PLUGIN} plugin cancels a tendon's linear damping only, and its tendon "
                           "has polynomial damping")
        lo, hi = model.actuator_lengthrange[a]
        lengths = np.linspace(lo - TABLE_MARGIN, hi + TABLE_MARGIN, TABLE_POINTS)
        config = {"tendon": model.tendon(t).name, "f0": fibre.max_isometric_force, "l0": fibre.optimal_fiber_length,
                  "lts": fibre.tendon_slack_length, "sina0": fibre.sin_pennation_at_optimal,
                  "fibre0": fibre_lengths.get(name, OFF), "strain": fibre.strains, "tendonf": fibre.tendon,
                  "length": lengths, "equilibrium": fibre.equilibrium(lengths)}
        instance = etree.SubElement(plugin, "instance", name=instance_name(name))
        for key, value in config.items():
            text = value if isinstance(value, str) else " ".join(f"{x:.12g}" for x in np.atleast_1d(value))
            etree.SubElement(instance, "config", key=key, value=text)
    tree.write(str(xml_out), pretty_print=True)
    return Path(xml_out)


def instance_name(muscle: str) -> str:
    """The ``o2m.fibre`` instance :func:`with_fibres` writes for ``muscle``."""
    return f"fibre_{muscle}"


def fibre_instances(model: mujoco.MjModel) -> dict[int, str]:
    """``{plugin instance id: muscle}`` of the fibres :func:`with_fibres` wrote into ``model``."""
    names = {i: mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_PLUGIN, i) or "" for i in range(model.nplugin)}
    return {i: n[len(instance_name("")):] for i, n in names.items() if n.startswith(instance_name(""))}


def fibre_state(model: mujoco.MjModel, state: np.ndarray, fibre_lengths: dict[str, float]) -> np.ndarray:
    """``state`` (mjSTATE_TIME | mjSTATE_PHYSICS of ``model``, as a model without plugins has it as
    mjSTATE_FULLPHYSICS) with the fibres: each instance of :func:`with_fibres` on at its muscle's
    ``fibre_lengths`` (m) entry, off where the muscle has none. Returns mjSTATE_FULLPHYSICS, shape (nstate,)."""
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, state, mujoco.mjtState.mjSTATE_TIME | mujoco.mjtState.mjSTATE_PHYSICS)
    for i, muscle in fibre_instances(model).items():
        data.plugin_state[model.plugin_stateadr[i]] = fibre_lengths.get(muscle, OFF)
    out = np.zeros(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, data, out, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return out
