"""The one place o2m imports OpenSim: the module, model loading, and casts every caller needs.

OpenSim is imported on first use (it takes about a second and is not needed to read a
document or to simulate in MuJoCo). Its log goes at ``error`` level: o2m reports what matters
itself, and OpenSim's warnings (massless bodies, locked coordinates) would flood a terminal.
"""

from __future__ import annotations

import functools
import math
import os
from typing import Any

from o2m.errors import ModelFileError

__all__ = ["TRANSLATIONAL", "geometry_path", "load_model", "opensim", "path_force", "sample_bounds"]

TRANSLATIONAL = 2
"""``opensim.Coordinate.Translational``, the motion type of a coordinate in metres."""


@functools.cache
def opensim() -> Any:
    """The ``opensim`` module (4.6), imported once, its log at ``error`` level."""
    import opensim as module

    module.Logger.setLevelString("error")
    return module


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
    infinite bound replaced by +-1 m (translational) or +-pi (otherwise)."""
    lo, hi = float(coord.getRangeMin()), float(coord.getRangeMax())
    default = 1.0 if coord.getMotionType() == TRANSLATIONAL else math.pi
    lo = lo if math.isfinite(lo) else -default
    hi = hi if math.isfinite(hi) else default
    return (lo, hi) if lo <= hi else (hi, lo)


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
