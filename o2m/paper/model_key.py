"""Which compiled model a cached result belongs to, up to rounding.

A result computed for one model (the paper's corrective controls, minutes per excitation set) is
reused for the same model. "The same" cannot mean bit for bit: the conversion's fits round
differently under another BLAS, so the same ``.osim`` converted on two machines gives float
arrays that agree only to rounding (and to a fit's tolerance), and a sha256 of the arrays then
misses a cache that is valid. So a model is identified by two things:

- :func:`model_structure`: a sha256 of everything that is not a measured float (integer and text
  arrays, the shapes of the float arrays, the options set in the XML);
- :func:`model_values`: its float arrays, which :func:`same_values` compares element by element
  within :data:`FIELD_RTOL`.

Arrays MuJoCo derives from the others (the bounding volumes ``bvh_*``) are left out; float
arrays of more than :data:`MAX_COMPARED` values (meshes, read from files) are hashed exactly, as
are the asset paths (MuJoCo keeps them absolute: they name the folder, not the model).
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping

import mujoco
import numpy as np

__all__ = ["FIELD_ATOL", "FIELD_RTOL", "MAX_COMPARED", "model_structure", "model_values", "same_values",
           "value_difference"]

#: Two values of a float array are the same within this fraction of their magnitude. A real edit
#: of a model changes a value by more; rounding between machines changes fitted values by less.
FIELD_RTOL = 1e-4
#: ... or within this fraction of the array's largest magnitude (values rounding left near 0).
FIELD_ATOL = 1e-9
#: Float arrays with more values than this are hashed exactly instead of compared.
MAX_COMPARED = 100_000


def _fields(model: mujoco.MjModel):
    """(name, array) of every array field of ``model`` that identifies it."""
    for name in sorted(dir(model)):
        if name.startswith("_") or name == "paths" or name.endswith("pathadr") or name.startswith("bvh_"):
            continue
        value = getattr(model, name)
        if isinstance(value, bytes | np.ndarray):
            yield name, value


def _compared(value) -> bool:
    return isinstance(value, np.ndarray) and value.dtype.kind == "f" and value.size <= MAX_COMPARED


def model_structure(model: mujoco.MjModel) -> str:
    """sha256 of ``model``'s integer and text arrays, its float arrays' shapes (the values of the
    larger ones too, see :data:`MAX_COMPARED`) and its ``opt`` and ``vis.global_`` settings."""
    digest = hashlib.sha256()
    for name, value in _fields(model):
        digest.update(name.encode())
        if _compared(value):
            digest.update(repr(value.shape).encode())
        else:
            digest.update(value if isinstance(value, bytes) else np.ascontiguousarray(value).tobytes())
    for struct in (model.opt, model.vis.global_):
        for name in sorted(dir(struct)):
            value = getattr(struct, name)
            if not name.startswith("_") and isinstance(value, int | float | np.ndarray):
                digest.update(name.encode())
                digest.update(np.asarray(value).tobytes())
    return digest.hexdigest()


def model_values(model: mujoco.MjModel) -> dict[str, np.ndarray]:
    """``model``'s float arrays that :func:`same_values` compares, by field name (copies), and
    its computed statistics (``stat.<name>``)."""
    values = {name: np.array(value, dtype=np.float64) for name, value in _fields(model) if _compared(value)}
    for name in sorted(dir(model.stat)):
        value = getattr(model.stat, name)
        if not name.startswith("_") and isinstance(value, int | float | np.ndarray):
            values[f"stat.{name}"] = np.array(value, dtype=np.float64)
    return values


def same_values(stored: Mapping[str, np.ndarray], values: Mapping[str, np.ndarray]) -> bool:
    """Whether two :func:`model_values` are the same fields of the same shapes, each value within
    :data:`FIELD_RTOL` of its magnitude or :data:`FIELD_ATOL` of its array's largest magnitude."""
    return value_difference(stored, values) is None


def value_difference(stored: Mapping[str, np.ndarray], values: Mapping[str, np.ndarray]) -> str | None:
    """Where two :func:`model_values` differ beyond rounding (the first field, in words), or None
    when they are the same model (:func:`same_values`)."""
    if set(stored) != set(values):
        return f"other fields ({', '.join(sorted(set(stored) ^ set(values))[:3])})"
    for name, a in values.items():
        b = np.asarray(stored[name], dtype=np.float64)
        if a.shape != b.shape:
            return f"{name}: shape {b.shape} -> {a.shape}"
        if a.size == 0:
            continue
        ok = np.isfinite(a)
        if not (np.array_equal(ok, np.isfinite(b)) and np.array_equal(a[~ok], b[~ok], equal_nan=True)):
            return f"{name}: other non-finite values"
        scale = float(np.max(np.abs(a[ok]), initial=0.0))
        off = np.abs(a[ok] - b[ok]) - (FIELD_RTOL * np.abs(a[ok]) + FIELD_ATOL * scale)
        if np.any(off > 0):
            k = int(np.argmax(off))
            return f"{name}: {b[ok][k]:.6g} -> {a[ok][k]:.6g}"
    return None
