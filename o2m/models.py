"""Fetch third-party OpenSim models listed in ``registry.tsv`` into a local cache.

The models are not part of o2m. Every file o2m can use is one row of the packaged
``registry.tsv`` (registry path, sha256, url). :func:`fetch` copies a file into the cache
(``$O2M_CACHE``, else the user's cache folder) from a local mirror (``$O2M_MODEL_MIRROR``, a
folder laid out like ``registry.tsv``) or, without a mirror, downloads it from its URL. Every
file is checked against its sha256 and written atomically, so the cache never holds a file
that looks valid but is not.

:func:`fetch_model` fetches a bundled model (see :data:`BUNDLED`) with the meshes it references.
"""

from __future__ import annotations

import difflib
import functools
import hashlib
import logging
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from importlib import resources
from pathlib import Path, PurePosixPath
from typing import NamedTuple

from o2m.errors import FetchError, ModelFileError
from o2m.osim.document import parse_xml

__all__ = [
    "BUNDLED",
    "BundledModel",
    "CACHE_ENV",
    "Entry",
    "FetchedModel",
    "MIRROR_ENV",
    "Registry",
    "bundled_model",
    "cache_dir",
    "fetch",
    "fetch_all",
    "fetch_model",
    "fetch_model_with_geometry",
    "get_registry",
    "mirror_dir",
    "referenced_meshes",
    "sha256_of",
]

log = logging.getLogger(__name__)

CACHE_ENV = "O2M_CACHE"
"""Environment variable naming the cache folder (default: ``pooch.os_cache("o2m")``)."""
MIRROR_ENV = "O2M_MODEL_MIRROR"
"""Environment variable naming a local folder laid out like ``registry.tsv`` to copy files from."""

_PROGRESS_MIN_FILES = 5  # show a progress bar only when fetching more files than this


# --------------------------------------------------------------------------- registry


@dataclass(frozen=True)
class Entry:
    """One registry row: a file's registry path, its sha256 (hex) and where to download it."""

    path: str
    sha256: str
    url: str


class Registry:
    """The files o2m can fetch, keyed by registry path (POSIX, relative, e.g. ``mobl-arms/license.txt``)."""

    def __init__(self, entries: Iterable[Entry]):
        self._entries: dict[str, Entry] = {e.path: e for e in entries}

    @classmethod
    def from_text(cls, text: str, source: str = "registry.tsv") -> Registry:
        """Parse tab-separated ``path  sha256  url`` rows (a header row starting with ``path`` is skipped)."""
        entries = []
        for lineno, line in enumerate(text.splitlines(), 1):
            if not line.strip() or line.startswith("#"):
                continue
            cols = line.rstrip("\r\n").split("\t")
            if lineno == 1 and cols[0] == "path":
                continue
            if len(cols) != 3 or len(cols[1]) != 64:
                raise FetchError(f"{source}:{lineno}: expected 'path<TAB>sha256<TAB>url', got {line!r}")
            entries.append(Entry(cols[0], cols[1].lower(), cols[2]))
        return cls(entries)

    @classmethod
    def packaged(cls) -> Registry:
        """The registry shipped inside the o2m package."""
        text = resources.files("o2m").joinpath("registry.tsv").read_text(encoding="utf-8")
        return cls.from_text(text)

    @property
    def paths(self) -> list[str]:
        """Every registry path, in file order."""
        return list(self._entries)

    def __contains__(self, path: object) -> bool:
        return isinstance(path, str) and _normalize(path) in self._entries

    def __iter__(self) -> Iterator[Entry]:
        return iter(self._entries.values())

    def __len__(self) -> int:
        return len(self._entries)

    def get(self, path: str) -> Entry | None:
        """The entry for ``path``, or None."""
        return self._entries.get(_normalize(path))

    def lookup(self, path: str) -> Entry:
        """The entry for ``path``; :class:`FetchError` with close matches when it is unknown."""
        entry = self.get(path)
        if entry is not None:
            return entry
        norm = _normalize(path)
        close = difflib.get_close_matches(norm, self._entries, n=3, cutoff=0.8)
        if not close:  # try on the file name alone, e.g. a mesh given without its folder
            name = PurePosixPath(norm).name
            by_name = {PurePosixPath(p).name: p for p in self._entries}
            close = [by_name[n] for n in difflib.get_close_matches(name, by_name, n=3, cutoff=0.6)]
        hint = ("Did you mean: " + ", ".join(close) + "?") if close else \
            "See o2m/registry.tsv for the files o2m can fetch."
        raise FetchError(f"{path!r} is not in o2m's model registry. {hint}")

    def under(self, folder: str) -> list[str]:
        """Registry paths anywhere below ``folder``."""
        prefix = _normalize(folder).rstrip("/") + "/"
        return [p for p in self._entries if p.startswith(prefix)]


@functools.cache
def get_registry() -> Registry:
    """The packaged registry (loaded once)."""
    return Registry.packaged()


def _normalize(path: str | os.PathLike[str]) -> str:
    """Registry spelling of a path: POSIX separators, no leading ``./``."""
    text = os.fspath(path).replace("\\", "/")
    while text.startswith("./"):
        text = text[2:]
    return text


# --------------------------------------------------------------------------- folders


def cache_dir(cache: str | os.PathLike[str] | None = None) -> Path:
    """The cache folder: ``cache`` if given, else ``$O2M_CACHE``, else ``pooch.os_cache("o2m")``."""
    if cache is not None:
        return Path(cache).expanduser()
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).expanduser()
    import pooch

    return Path(pooch.os_cache("o2m"))


def mirror_dir(mirror: str | os.PathLike[str] | None = None) -> Path | str | None:
    """The mirror: ``mirror`` if given, else ``$O2M_MODEL_MIRROR``, else None (download from the
    registry's URLs). A mirror is a folder laid out like ``registry.tsv`` or, given as an
    ``http(s)://`` URL, a server laid out the same way (returned as the URL string)."""
    value = os.fspath(mirror) if mirror is not None else os.environ.get(MIRROR_ENV)
    if not value:
        return None
    if value.startswith(("http://", "https://")):
        return value.rstrip("/")
    return Path(value).expanduser()


# --------------------------------------------------------------------------- fetching


def sha256_of(path: str | os.PathLike[str]) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def fetch(path: str, *, mirror: str | os.PathLike[str] | None = None,
          cache: str | os.PathLike[str] | None = None) -> Path:
    """Return the cached copy of registry file ``path``, fetching it first if needed.

    A cached copy whose sha256 matches is used as is. Otherwise the file is copied from
    ``<mirror>/<path>`` (``mirror`` or ``$O2M_MODEL_MIRROR``) or, with no mirror, downloaded
    from its registry URL. The new copy is checked against the registry's sha256 before it
    replaces anything in the cache. Raises :class:`FetchError` on any failure.
    """
    entry = get_registry().lookup(path)
    return _fetch_entry(entry, mirror_dir(mirror), cache_dir(cache))


def _fetch_entry(entry: Entry, mirror: Path | str | None, cache: Path) -> Path:
    target = cache / entry.path
    if target.is_file():
        try:
            if sha256_of(target) == entry.sha256:
                return target
        except OSError:
            pass
        log.info("cached %s does not match its sha256; fetching it again", target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise FetchError(f"cannot create cache folder {target.parent}: {e}. "
                         f"Set {CACHE_ENV} to a writable folder.") from e
    with tempfile.TemporaryDirectory(dir=target.parent, prefix=".o2m-fetch-") as tmpdir:
        tmp = Path(tmpdir) / target.name
        if isinstance(mirror, str):  # a server laid out like the registry
            source = _download(Entry(entry.path, entry.sha256, f"{mirror}/{entry.path}"), tmp)
        elif mirror is not None:
            source = _copy_from_mirror(entry, mirror, tmp)
        else:
            source = _download(entry, tmp)
        got = sha256_of(tmp)
        if got != entry.sha256:
            raise _mismatch(entry, source, got)
        os.replace(tmp, target)  # atomic: the cache holds the old file or the verified new one
    return target


def _copy_from_mirror(entry: Entry, mirror: Path, tmp: Path) -> str:
    src = mirror / entry.path
    if not src.is_file():
        where = "" if mirror.is_dir() else f" (the mirror folder {mirror} itself does not exist)"
        raise FetchError(
            f"{entry.path}: not found in the model mirror at {src}{where}. {MIRROR_ENV} (or the "
            f"mirror argument) must point at a folder laid out like o2m/registry.tsv, i.e. holding "
            f"<mirror>/{entry.path}. Fix the mirror or unset {MIRROR_ENV} to download from {entry.url}."
        )
    try:
        shutil.copyfile(src, tmp)
    except OSError as e:
        raise FetchError(f"{entry.path}: cannot copy {src} into the cache: {e}") from e
    return str(src)


def _download(entry: Entry, tmp: Path) -> str:
    import pooch
    import requests

    pooch_log = pooch.get_logger()
    level = pooch_log.level
    pooch_log.setLevel(logging.WARNING)  # its "Downloading ..." line names our temporary file
    try:
        pooch.retrieve(entry.url, known_hash=f"sha256:{entry.sha256}", fname=tmp.name,
                       path=tmp.parent, progressbar=False)
    except ValueError as e:  # pooch's hash check; it keeps no bad file
        if "hash" in str(e).lower():
            raise FetchError(
                f"{entry.path}: sha256 mismatch for the file downloaded from {entry.url} "
                f"(expected {entry.sha256}): {e}. The bad file was not kept; the upstream file "
                "changed or the download was corrupted.") from e
        raise FetchError(f"{entry.path}: cannot download {entry.url}: {e}") from e
    except (requests.RequestException, OSError) as e:
        raise FetchError(
            f"{entry.path}: cannot download {entry.url}: {type(e).__name__}: {e}. Check the network "
            f"connection, or set {MIRROR_ENV} to a local copy of the models laid out like "
            "o2m/registry.tsv.") from e
    finally:
        pooch_log.setLevel(level)
    return entry.url


def _mismatch(entry: Entry, source: str, got: str) -> FetchError:
    return FetchError(
        f"{entry.path}: sha256 mismatch for {source}: expected {entry.sha256}, got {got}. "
        "The bad file was not kept in the cache. Replace the source file with the registry's "
        f"version (from {entry.url}).")


def _fetch_many(paths: list[str], mirror: Path | str | None, cache: Path, progress: bool,
                desc: str) -> list[Path]:
    registry = get_registry()
    entries = [registry.lookup(p) for p in paths]
    show = progress and len(entries) > _PROGRESS_MIN_FILES
    if not show:
        return [_fetch_entry(e, mirror, cache) for e in entries]
    from tqdm.auto import tqdm

    out = []
    with tqdm(total=len(entries), desc=desc, unit="file") as bar:
        for e in entries:
            out.append(_fetch_entry(e, mirror, cache))
            bar.update(1)
    return out


def fetch_all(*, mirror: str | os.PathLike[str] | None = None,
              cache: str | os.PathLike[str] | None = None, progress: bool = True) -> list[Path]:
    """Fetch every file of the registry (e.g. to warm a CI cache); return the cached paths."""
    return _fetch_many(get_registry().paths, mirror_dir(mirror), cache_dir(cache), progress, "o2m models")


# --------------------------------------------------------------------------- bundled models


@dataclass(frozen=True)
class BundledModel:
    """A model o2m knows: short name, registry path of its .osim, registry folder of its meshes."""

    name: str
    osim: str
    geometry: str

    @property
    def folder(self) -> str:
        """Registry folder holding the .osim."""
        return str(PurePosixPath(self.osim).parent)

    def extras(self, registry: Registry | None = None) -> list[str]:
        """Registry files beside the .osim that go with it (setup files, states, license; no other .osim)."""
        registry = registry or get_registry()
        return [p for p in registry.paths
                if str(PurePosixPath(p).parent) == self.folder and not p.endswith(".osim")]


_OSM = "opensim-models"
_MODELS = f"{_OSM}/Models"
_OSM_GEOMETRY = f"{_OSM}/Geometry"
_MOBL_GEOMETRY = "mobl-arms/Geometry"

BUNDLED: dict[str, str] = {
    "tug_of_war": f"{_MODELS}/Tug_of_War/Tug_of_War.osim",
    "arm26": f"{_MODELS}/Arm26/arm26.osim",
    "leg6dof9musc": f"{_MODELS}/Leg6Dof9Musc/leg6dof9musc.osim",
    "gait10dof18musc": f"{_MODELS}/Gait10dof18musc/gait10dof18musc.osim",
    "gait2354": f"{_MODELS}/Gait2354_Simbody/gait2354_simbody.osim",
    "gait2392": f"{_MODELS}/Gait2392_Simbody/gait2392_thelen2003muscle.osim",
    "mobl_arms": "mobl-arms/MoBL_ARMS_model_for_testing_opensim.osim",
    "mobl_arms_no_wrap": "mobl-arms/MoBL_ARMS_model_for_testing_opensim_no_wrap.osim",
}
"""Short name -> registry path of the model's main .osim."""


def _geometry_folder(osim: str) -> str:
    return _MOBL_GEOMETRY if osim.startswith("mobl-arms/") else _OSM_GEOMETRY


BUNDLED_MODELS: dict[str, BundledModel] = {
    name: BundledModel(name, osim, _geometry_folder(osim)) for name, osim in BUNDLED.items()
}
"""Short name -> :class:`BundledModel`."""


def bundled_model(name: str) -> BundledModel:
    """The :class:`BundledModel` for a short name (see :data:`BUNDLED`) or for a registry .osim path."""
    if name in BUNDLED_MODELS:
        return BUNDLED_MODELS[name]
    registry = get_registry()
    norm = _normalize(name)
    if norm.endswith(".osim") and norm in registry:
        return BundledModel(PurePosixPath(norm).stem, norm, _geometry_folder(norm))
    close = difflib.get_close_matches(name, list(BUNDLED), n=3, cutoff=0.5)
    hint = f" Did you mean {', '.join(close)}?" if close else ""
    raise FetchError(f"unknown model {name!r}.{hint} Known models: {', '.join(BUNDLED)}; "
                     "a registry .osim path (see o2m/registry.tsv) also works.")


_MESH_TAGS = {"mesh_file", "geometry_file", "geometry_files"}


def referenced_meshes(osim: str | os.PathLike[str]) -> list[str]:
    """Mesh file names an .osim references (``<mesh_file>``, 3.x ``<geometry_file>``), in order, unique."""
    try:
        tree = parse_xml(Path(osim))
    except ModelFileError as e:
        raise FetchError(f"cannot read {osim} to find its meshes: {e}") from e
    seen: dict[str, None] = {}
    for el in tree.iter():
        tag = el.tag.rsplit("}", 1)[-1] if isinstance(el.tag, str) else ""
        if tag in _MESH_TAGS and el.text:
            for name in el.text.split() if tag == "geometry_files" else [el.text.strip()]:
                if name:
                    seen.setdefault(name, None)
    return list(seen)


def _mesh_registry_paths(model: BundledModel, osim_file: Path, registry: Registry) -> list[str]:
    """Registry paths of the meshes the model references; meshes not in the registry are skipped."""
    out: dict[str, None] = {}
    for mesh in referenced_meshes(osim_file):
        norm = _normalize(mesh)
        candidates = [f"{model.geometry}/{PurePosixPath(norm).name}", f"{model.folder}/{norm}",
                      f"{model.folder}/Geometry/{norm}"]
        hit = next((c for c in candidates if c in registry), None)
        if hit is None:
            log.debug("%s: mesh %r is not in the registry; skipped", model.name, mesh)
        else:
            out.setdefault(hit, None)
    return list(out)


class FetchedModel(NamedTuple):
    """A fetched model: cached .osim path and the cached geometry folder to search for meshes."""

    osim: Path
    geometry_dir: Path


def fetch_model_with_geometry(name: str, *, mirror: str | os.PathLike[str] | None = None,
                              cache: str | os.PathLike[str] | None = None, geometry: bool = True,
                              progress: bool = True) -> FetchedModel:
    """Fetch a model (short name or registry .osim path), its companion files and its meshes.

    Meshes are the registry files under the model's geometry folder that the .osim references;
    a referenced mesh missing from the registry is skipped (the converter reports it). Returns
    the cached .osim and geometry folder: for MoBL the folder is ``Geometry`` beside the .osim,
    for opensim-models it is ``opensim-models/Geometry``, two levels up, so pass it to the
    converter as an extra mesh search folder. With ``geometry=False`` that folder may not exist.
    """
    model = bundled_model(name)
    registry = get_registry()
    mirror_path, cache_path = mirror_dir(mirror), cache_dir(cache)
    osim = _fetch_entry(registry.lookup(model.osim), mirror_path, cache_path)
    paths = model.extras(registry)
    if geometry:
        paths += _mesh_registry_paths(model, osim, registry)
    _fetch_many(paths, mirror_path, cache_path, progress, model.name)
    return FetchedModel(osim, cache_path / model.geometry)


def fetch_model(name: str, *, mirror: str | os.PathLike[str] | None = None,
                cache: str | os.PathLike[str] | None = None, geometry: bool = True,
                progress: bool = True) -> Path:
    """Fetch a model as :func:`fetch_model_with_geometry` does; return the cached .osim path."""
    return fetch_model_with_geometry(name, mirror=mirror, cache=cache, geometry=geometry,
                                     progress=progress).osim
