"""The ``o2m.schutte`` MuJoCo plugin: OpenSim's Schutte1993 muscle, whole, as a MuJoCo actuator.

MuJoCo's muscle has a rigid tendon and no fibre state. OpenSim's Schutte1993Muscle_Deprecated
(:mod:`o2m.osim.schutte`) has an elastic tendon in series with a fibre whose length is a state, so
its tendon force lags its activation and a passive fibre stays long after a stretch. No fit of
MuJoCo's muscle parameters reproduces either; ``schutte_plugin.c`` (shipped with o2m) is that
muscle as an actuator plugin: the actuator keeps its tendon and its control (the excitation),
and the plugin's state (activation, fibre length in m) is part of ``mjSTATE_FULLPHYSICS``, so
``mj_step`` and ``mujoco.rollout`` carry it. The plugin's time step is the Euler integrator's
(``advance`` runs after it); other integrators would step the fibre once per MuJoCo step all the
same. Compiled at first use (:mod:`o2m.mj.plugins`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np
from lxml import etree

from o2m.errors import O2MError
from o2m.mj import plugins

if TYPE_CHECKING:
    from o2m.osim.schutte import SchutteMuscle

__all__ = ["PLUGIN", "load", "schutte_actuators", "schutte_state", "with_schutte_muscles", "with_schutte_starts"]

PLUGIN = "o2m.schutte"
SOURCE = plugins.SOURCES[PLUGIN]


def load(folder: str | Path) -> Path:
    """Build the plugin into ``folder`` and load it into this process's MuJoCo; returns the library."""
    return plugins.load(SOURCE, folder)


def _config(muscle: SchutteMuscle, start: tuple[float, float] | None) -> dict[str, str]:
    activation0, fibre0 = start if start is not None else (0.0, muscle.optimal_fiber_length)
    numbers = {"f0": muscle.max_isometric_force, "l0": muscle.optimal_fiber_length,
               "lts": muscle.tendon_slack_length, "sina0": np.sin(muscle.pennation_angle_at_optimal),
               "time_scale": muscle.time_scale, "activation1": muscle.activation1,
               "activation2": muscle.activation2, "damping": muscle.damping, "activation0": activation0,
               "fibre0": fibre0}
    return ({k: f"{float(v):.17g}" for k, v in numbers.items()}
            | {"tendon_curve": muscle.tendon.config(), "active_curve": muscle.active.config(),
               "passive_curve": muscle.passive.config()})


def with_schutte_muscles(xml_in: str | Path, xml_out: str | Path, muscles: Mapping[str, SchutteMuscle],
                         start: Mapping[str, tuple[float, float]] | None = None) -> Path:
    """Write ``xml_out``: ``xml_in`` with each tendon actuator named in ``muscles`` replaced, in
    place (the controls keep their layout), by an ``o2m.schutte`` actuator plugin on the same
    tendon, control in [0, 1] (the excitation). The replaced actuators' tendons must have no spring
    or damping of their own (the muscle's passive force is the plugin's). ``start``: per muscle the
    (activation, fibre length m) ``mj_resetData`` starts from (default 0 and the optimal fibre
    length); keyframes drop the replaced actuators' activations. Set each run's initial
    activations and fibre lengths with :func:`schutte_state`. ``xml_out`` goes beside ``xml_in``
    (the meshes' relative paths)."""
    model = mujoco.MjModel.from_xml_path(str(xml_in))
    tree = etree.parse(str(xml_in))
    actuators = tree.getroot().find("actuator")
    missing = set(muscles)
    for element in [] if actuators is None else list(actuators):
        name = element.get("name")
        if name not in muscles:
            continue
        a = model.actuator(name).id
        if model.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_TENDON:
            raise O2MError(f"{xml_in}: actuator '{name}' pulls on no tendon, so {PLUGIN} cannot replace it")
        t = int(model.actuator_trnid[a, 0])
        if model.tendon_stiffness[t] or model.tendon_damping[t] or np.any(model.tendon_stiffnesspoly[t]) \
                or np.any(model.tendon_dampingpoly[t]):
            raise O2MError(f"{xml_in}: the tendon of '{name}' has a spring or damper, which {PLUGIN}'s muscle "
                           "would pull beside; convert without them")
        plugin = etree.Element("plugin", name=name, plugin=PLUGIN, tendon=model.tendon(t).name,
                               ctrllimited="true", ctrlrange="0 1")
        for key, value in _config(muscles[name], (start or {}).get(name)).items():
            etree.SubElement(plugin, "config", key=key, value=value)
        plugin.tail = element.tail
        actuators.replace(element, plugin)
        missing.discard(name)
    if missing:
        raise O2MError(f"{xml_in} has no actuators named {sorted(missing)}")
    root = tree.getroot()
    _drop_key_activations(root, model, set(muscles))
    extension = root.find("extension")
    extension = etree.SubElement(root, "extension") if extension is None else extension
    if not any(p.get("plugin") == PLUGIN for p in extension.findall("plugin")):
        etree.SubElement(extension, "plugin", plugin=PLUGIN)
    tree.write(str(xml_out), pretty_print=True)
    return Path(xml_out)


def _drop_key_activations(root: etree._Element, model: mujoco.MjModel, replaced: set[str]) -> None:
    """Keyframes' ``act`` without the entries of the ``replaced`` actuators (which have no MuJoCo
    activation once they are plugins)."""
    keep = [i for a in range(model.nu) if model.actuator_actadr[a] >= 0 and model.actuator(a).name not in replaced
            for i in range(model.actuator_actadr[a], model.actuator_actadr[a] + model.actuator_actnum[a])]
    for key in root.iter("key"):
        if key.get("act") is None:
            continue
        act = np.array(key.get("act").split(), float)
        if keep:
            key.set("act", " ".join(f"{x:.17g}" for x in act[keep]))
        else:
            del key.attrib["act"]


#: The smallest model with one ``o2m.schutte`` actuator: compiling it tells the plugin's slot.
_PROBE = """<mujoco><extension><plugin plugin="o2m.schutte"/></extension><worldbody><site name="a"/>
<body><joint type="slide"/><geom size="0.1"/><site name="b" pos="0 0 1"/></body></worldbody>
<tendon><spatial name="t"><site site="a"/><site site="b"/></spatial></tendon>
<actuator><plugin plugin="o2m.schutte" tendon="t">""" + "".join(
    f'<config key="{k}" value="{v}"/>' for k, v in (
        ("f0", 1), ("l0", 1), ("lts", 1), ("sina0", 0), ("time_scale", 0.1), ("activation1", 1), ("activation2", 1),
        ("damping", 0.1), ("activation0", 0), ("fibre0", 1), ("tendon_curve", "0 1 0 1"),
        ("active_curve", "0 1 1 1"), ("passive_curve", "0 1 0 0"))) + "</plugin></actuator></mujoco>"


def schutte_actuators(model: mujoco.MjModel) -> dict[int, int]:
    """``{actuator id: plugin instance id}`` of the ``o2m.schutte`` actuators of ``model`` (the
    plugin loaded)."""
    if not model.nplugin:
        return {}
    try:
        slot = int(mujoco.MjModel.from_xml_string(_PROBE).plugin[0])
    except ValueError:  # the plugin is not loaded, so no model in this process has its actuators
        return {}
    return {a: int(model.actuator_plugin[a]) for a in range(model.nu)
            if model.actuator_plugin[a] >= 0 and model.plugin[model.actuator_plugin[a]] == slot}


def schutte_state(model: mujoco.MjModel, plain: mujoco.MjModel, state: np.ndarray,
                  fibre_lengths: Mapping[str, float]) -> np.ndarray:
    """``model``'s full physics state for a run that ``plain`` (the model before
    :func:`with_schutte_muscles`) starts from ``state`` (its mjSTATE_FULLPHYSICS, (nstate,) or one
    per run, (n, nstate)): the same time, positions and velocities, each ``o2m.schutte`` actuator
    at the activation its namesake has in ``state`` and at its ``fibre_lengths`` entry (m).
    Returns the same shape with ``model``'s nstate."""
    states = np.atleast_2d(np.asarray(state, float))
    src, data = mujoco.MjData(plain), mujoco.MjData(model)
    names = [model.actuator(a).name for a in schutte_actuators(model)]
    for name in names:
        if name not in fibre_lengths:
            raise O2MError(f"no initial fibre length for the {PLUGIN} actuator '{name}'")
    acts = {n: int(plain.actuator_actadr[plain.actuator(n).id]) for n in names}
    out = np.zeros((len(states), mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)))
    starts = []  # per run: each actuator's (activation in the plain model's state, fibre length)
    for row, s in zip(out, states, strict=True):
        mujoco.mj_setState(plain, src, s, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        data.time, data.qpos[:], data.qvel[:] = src.time, src.qpos, src.qvel
        mujoco.mj_getState(model, data, row, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        starts.append({n: (float(src.act[acts[n]]), fibre_lengths[n]) for n in names})
    out = with_schutte_starts(model, out, starts)
    return out if np.ndim(state) == 2 else out[0]


def with_schutte_starts(model: mujoco.MjModel, states: np.ndarray,
                        starts: Sequence[Mapping[str, tuple[float, float]]]) -> np.ndarray:
    """``states`` (``model``'s mjSTATE_FULLPHYSICS, (n, nstate)) with each ``o2m.schutte``
    actuator of run k at ``starts[k][name]``, (activation, fibre length m); an actuator a run does
    not name keeps its state."""
    data = mujoco.MjData(model)
    out = np.array(states, dtype=float, copy=True)
    plugged = {model.actuator(a).name: int(model.plugin_stateadr[i]) for a, i in schutte_actuators(model).items()}
    if not plugged:
        return out
    for row, start in zip(out, starts, strict=True):
        mujoco.mj_setState(model, data, row, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        for name, adr in plugged.items():
            if name in start:
                data.plugin_state[adr:adr + 2] = start[name]
        mujoco.mj_getState(model, data, row, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return out
