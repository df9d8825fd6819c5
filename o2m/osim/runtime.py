"""The one place o2m imports OpenSim: the module, model loading, and casts every caller needs.

OpenSim is imported on first use (it takes about a second and is not needed to read a
document or to simulate in MuJoCo). Its log goes at ``error`` level and to no file: o2m reports
what matters itself, and OpenSim's warnings (massless bodies, locked coordinates) would flood a
terminal. A program that wants OpenSim's log (``python -m o2m paper``, the speed step, the
simulation workers) runs the OpenSim work inside :func:`opensim_log`, which sends it to a file.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import math
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from o2m.errors import ModelFileError

__all__ = ["TRANSLATIONAL", "geometry_path", "is_held", "load_model", "opensim", "opensim_log", "path_force",
           "sample_bounds"]

TRANSLATIONAL = 2
"""``opensim.Coordinate.Translational``, the motion type of a coordinate in metres."""


@functools.cache
def opensim() -> Any:
    """The ``opensim`` module (4.6), imported once, its log at ``error`` level and to no file
    (OpenSim would otherwise write ``opensim.log`` into the current folder)."""
    import opensim as module

    module.Logger.setLevelString("error")
    module.Logger.removeFileSink()
    return module


def _flush_c_streams() -> None:
    """Flush C's stdio buffers (OpenSim's console sink writes through them)."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).fflush(None)


def _fileno(stream: Any) -> int | None:
    try:
        return stream.fileno()
    except (AttributeError, OSError, ValueError):  # Jupyter's and pytest's streams have no descriptor
        return None


@contextlib.contextmanager
def opensim_log(log_file: str | os.PathLike[str], level: str = "info") -> Iterator[Path]:
    """Within the block, OpenSim logs at ``level`` into ``log_file`` (appended), not the terminal.

    OpenSim 4.6 has no call that drops its console sink, so the block points this process's
    file descriptors 1 and 2 at the log file (other C-level output, MuJoCo's included, goes there
    too). Python's ``sys.stdout``/``sys.stderr`` keep writing where they wrote before, so prints
    and progress bars still reach the terminal. Everything is restored on exit. Yields the path.
    """
    osim = opensim()
    path = Path(log_file)
    path.parent.mkdir(parents=True, exist_ok=True)
    names = {1: "stdout", 2: "stderr"}
    for name in names.values():
        getattr(sys, name).flush()
    _flush_c_streams()
    saved = {fd: os.dup(fd) for fd in names}
    saved_level = osim.Logger.getLevelString()  # a block nested in another restores the outer one's level
    python_streams = {name: getattr(sys, name) for fd, name in names.items() if _fileno(getattr(sys, name)) == fd}
    log_fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    try:
        for name, stream in python_streams.items():  # Python keeps the terminal, on a copy of its descriptor
            fd = saved[1 if name == "stdout" else 2]
            setattr(sys, name, open(os.dup(fd), "w", buffering=1, encoding=stream.encoding,  # noqa: SIM115
                                    errors=stream.errors))
        for fd in names:
            os.dup2(log_fd, fd)
        osim.Logger.setLevelString(level)
        yield path
    finally:
        osim.Logger.setLevelString(saved_level)
        _flush_c_streams()
        for fd in names:
            os.dup2(saved[fd], fd)
            os.close(saved[fd])
        os.close(log_fd)
        for name, stream in python_streams.items():
            getattr(sys, name).close()
            setattr(sys, name, stream)


def load_model(osim_path: str | os.PathLike, assembly_accuracy: float | None = None) -> tuple[Any, Any]:
    """An OpenSim model and its initial state (``initSystem``).

    ``assembly_accuracy`` overrides the file's assembly accuracy (None keeps it). Raises
    :class:`~o2m.errors.ModelFileError` when the file is missing or OpenSim cannot load it.
    """
    osim = opensim()
    osim_path = os.fspath(osim_path)
    if not os.path.isfile(osim_path):
        raise ModelFileError(f"{osim_path}: no such file")
    try:
        model = osim.Model(osim_path)
        if assembly_accuracy is not None:
            model.set_assembly_accuracy(float(assembly_accuracy))
        state = model.initSystem()
    except Exception as exc:  # OpenSim raises RuntimeError/IOException subclasses
        raise ModelFileError(f"{osim_path}: OpenSim could not load the model: {exc}") from exc
    return model, state


def sample_bounds(coord: Any) -> tuple[float, float]:
    """Sampling interval of an OpenSim coordinate (radians or metres): its range, with an
    infinite bound replaced by +-1 m (translational) or +-pi (otherwise). A rotation's range
    wider than a turn (OpenSim's "unbounded" +-99999.9) is the turn centred on its default value:
    a turn holds every pose of it, where samples 1e5 rad out would only put the functions of it
    (splines of a coupled axis) far beyond their knots."""
    lo, hi = float(coord.getRangeMin()), float(coord.getRangeMax())
    rotation = coord.getMotionType() != TRANSLATIONAL
    default = math.pi if rotation else 1.0
    lo = lo if math.isfinite(lo) else -default
    hi = hi if math.isfinite(hi) else default
    lo, hi = (lo, hi) if lo <= hi else (hi, lo)
    if rotation and hi - lo > 2.0 * math.pi:
        centre = min(max(float(coord.getDefaultValue()), lo), hi)
        lo, hi = max(lo, centre - math.pi), min(hi, centre + math.pi)
    return lo, hi


def is_held(coord: Any, state: Any) -> bool:
    """Whether OpenSim holds coordinate ``coord`` in ``state`` whatever value is set: locked, or
    prescribed (a function of time, which overrides ``setValue``)."""
    return bool(coord.getLocked(state) or coord.isPrescribed(state))


def path_force(force: Any) -> Any | None:
    """A force downcast to the class that owns a path (PathActuator, muscles included, Ligament,
    PathSpring), or None for a force without one."""
    osim = opensim()
    for cls in (osim.PathActuator, osim.Ligament, osim.PathSpring):
        obj = cls.safeDownCast(force)
        if obj is not None:
            return obj
    return None


def geometry_path(model: Any, name: str) -> Any:
    """The GeometryPath of the path force ``name`` of ``model``; KeyError if it has none."""
    obj = path_force(model.getForceSet().get(name))
    if obj is None:
        raise KeyError(f"{name!r} is not an OpenSim path force")
    return obj.getGeometryPath()
