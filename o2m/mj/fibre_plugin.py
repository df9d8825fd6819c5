"""The ``o2m.fibre`` MuJoCo plugin: OpenSim's passive Schutte fibre, with its memory, inside MuJoCo.

A never-excited Schutte1993 muscle's fibre lengthens but never shortens (:mod:`o2m.osim.fibres`),
which no MuJoCo element reproduces: MuJoCo 4.0's actuator dynamics see only the control and the
activation, and its springs, dampers and friction are symmetric. A plugin can carry state, so
``fibre_plugin.c`` (shipped with o2m) keeps each fibre's length in ``mjData.plugin_state`` and adds
its tendon's pull to ``qfrc_passive``. It is compiled here with the machine's C compiler against
the headers of the installed ``mujoco`` wheel (which ships them), since MuJoCo loads plugins only
from shared libraries; models that use it then step with ``mj_step`` and ``mujoco.rollout``
(the fibre lengths are part of ``mjSTATE_FULLPHYSICS``).
"""

from __future__ import annotations

import hashlib
import shutil
import subprocess
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np
from lxml import etree

from o2m.errors import O2MError

if TYPE_CHECKING:
    from o2m.osim.fibres import PassiveFibre

__all__ = ["PLUGIN", "build", "load", "with_fibres"]

PLUGIN = "o2m.fibre"
SOURCE = Path(__file__).with_name("fibre_plugin.c")
#: The equilibrium table spans the actuator's lengthrange widened by this much (m) on each side.
TABLE_MARGIN = 0.05
TABLE_POINTS = 600


def build(folder: str | Path) -> Path:
    """The plugin library in ``folder`` (compiled there if this source and MuJoCo version have none)."""
    wheel = Path(mujoco.__file__).parent
    key = hashlib.sha256(SOURCE.read_bytes() + mujoco.__version__.encode()).hexdigest()[:12]
    lib = Path(folder) / f"libo2mfibre-{key}.so"
    if lib.exists():
        return lib
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    libmujoco = sorted(wheel.glob("libmujoco.so*")) + sorted(wheel.glob("libmujoco*.dylib"))
    if cc is None or not libmujoco:
        raise O2MError(f"the {PLUGIN} plugin needs a C compiler and MuJoCo's library (found: compiler {cc}, "
                       f"library {[p.name for p in libmujoco]})")
    lib.parent.mkdir(parents=True, exist_ok=True)
    cmd = [cc, "-shared", "-fPIC", "-O2", "-I", str(wheel / "include"), "-o", str(lib), str(SOURCE),
           str(libmujoco[0]), f"-Wl,-rpath,{wheel}", "-lm"]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise O2MError(f"compiling the {PLUGIN} plugin failed: {res.stderr.strip()[:500]}")
    return lib


def load(folder: str | Path) -> Path:
    """Build the plugin (:func:`build`) and load it into this process's MuJoCo; returns the library."""
    lib = build(folder)
    try:
        mujoco.mj_loadPluginLibrary(str(lib))
    except mujoco.FatalError as err:  # built and loaded before in this process (another folder)
        if "already registered" not in str(err):
            raise
    return lib


def with_fibres(xml_in: str | Path, xml_out: str | Path, fibres: dict[str, PassiveFibre],
                fibre_lengths: dict[str, float]) -> Path:
    """Write ``xml_out``: ``xml_in`` with each muscle of ``fibres`` pulling as that fibre (an
    ``o2m.fibre`` instance on its tendon, starting at ``fibre_lengths`` m) instead of its tendon's
    spring and damper; its actuator stays for its active force. ``xml_out`` goes beside ``xml_in``
    (the meshes' relative paths)."""
    model = mujoco.MjModel.from_xml_path(str(xml_in))
    tree = etree.parse(str(xml_in))
    root = tree.getroot()
    ext = root.find("extension")
    ext = etree.SubElement(root, "extension") if ext is None else ext
    plugin = etree.SubElement(ext, "plugin", plugin=PLUGIN)
    for name, fibre in fibres.items():
        a = model.actuator(name).id
        tendon = model.tendon(int(model.actuator_trnid[a, 0])).name
        spatial = root.find(f".//tendon/spatial[@name='{tendon}']")
        for attr in ("stiffness", "damping", "springlength"):
            spatial.attrib.pop(attr, None)
        lo, hi = model.actuator_lengthrange[a]
        lengths = np.linspace(lo - TABLE_MARGIN, hi + TABLE_MARGIN, TABLE_POINTS)
        config = {"tendon": tendon, "f0": fibre.max_isometric_force, "l0": fibre.optimal_fiber_length,
                  "lts": fibre.tendon_slack_length, "sina0": fibre.sin_pennation_at_optimal,
                  "fibre0": fibre_lengths[name], "strain": fibre.strains, "tendonf": fibre.tendon,
                  "length": lengths, "equilibrium": fibre.equilibrium(lengths)}
        instance = etree.SubElement(plugin, "instance", name=f"fibre_{name}")
        for key, value in config.items():
            text = value if isinstance(value, str) else " ".join(f"{x:.12g}" for x in np.atleast_1d(value))
            etree.SubElement(instance, "config", key=key, value=text)
    tree.write(str(xml_out), pretty_print=True)
    return Path(xml_out)

