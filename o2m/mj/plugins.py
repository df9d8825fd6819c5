"""Build and load o2m's MuJoCo plugins (C sources shipped with o2m) with the machine's C compiler.

MuJoCo's Python wheel loads plugins only from shared libraries, and ships the headers to build
them against, so a plugin is compiled at first use, once per source and MuJoCo version.
"""

from __future__ import annotations

import hashlib
import shutil
import subprocess
from pathlib import Path

import mujoco

from o2m.errors import O2MError

__all__ = ["SOURCES", "build", "load", "load_used"]

#: o2m's plugins by the name an MJCF file gives them, and their C sources.
SOURCES = {"o2m.fibre": Path(__file__).with_name("fibre_plugin.c"),
           "o2m.schutte": Path(__file__).with_name("schutte_plugin.c")}


def build(source: str | Path, folder: str | Path) -> Path:
    """The shared library of the plugin ``source`` (a C file) in ``folder``, compiled there unless
    this source and MuJoCo version already have one."""
    source, wheel = Path(source), Path(mujoco.__file__).parent
    key = hashlib.sha256(source.read_bytes() + mujoco.__version__.encode()).hexdigest()[:12]
    lib = Path(folder) / f"lib{source.stem.replace('_', '')}-{key}.so"
    if lib.exists():
        return lib
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    libmujoco = sorted(wheel.glob("libmujoco.so*")) + sorted(wheel.glob("libmujoco*.dylib"))
    if cc is None or not libmujoco:
        raise O2MError(f"the MuJoCo plugin {source.name} needs a C compiler and MuJoCo's library (found: "
                       f"compiler {cc}, library {[p.name for p in libmujoco]})")
    lib.parent.mkdir(parents=True, exist_ok=True)
    cmd = [cc, "-shared", "-fPIC", "-O2", "-I", str(wheel / "include"), "-o", str(lib), str(source),
           str(libmujoco[0]), f"-Wl,-rpath,{wheel}", "-lm"]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise O2MError(f"compiling the MuJoCo plugin {source.name} failed: {res.stderr.strip()[:500]}")
    return lib


def load(source: str | Path, folder: str | Path) -> Path:
    """Build the plugin ``source`` (:func:`build`) into ``folder`` and load it into this process's
    MuJoCo; returns the library."""
    lib = build(source, folder)
    try:
        mujoco.mj_loadPluginLibrary(str(lib))
    except mujoco.FatalError as err:  # built and loaded before in this process (another folder)
        if "already registered" not in str(err):
            raise
    return lib


def load_used(mjcf_path: str | Path) -> list[Path]:
    """Load each of o2m's plugins (:data:`SOURCES`) that the MJCF file ``mjcf_path`` names in its
    ``<extension>``, built in the file's folder (where ``convert --opensim-muscles`` and the paper's
    pipeline build them); returns their libraries."""
    from lxml import etree

    root = etree.parse(str(mjcf_path)).getroot()
    names = {p.get("plugin") for ext in root.iter("extension") for p in ext.iter("plugin")}
    return [load(SOURCES[n], Path(mjcf_path).parent) for n in sorted(names & set(SOURCES))]
