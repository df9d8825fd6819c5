"""Reading and writing OpenSim Storage (``.sto``) and motion (``.mot``) files.

Both are text: a header ending in a line ``endheader``, a line of tab-separated column labels
starting with ``time``, then one row of numbers per time. ``inDegrees=yes`` in the header means
rotational coordinates are in degrees; :func:`read_sto` leaves values as written and reports
the flag, so the caller (who knows which columns are rotations) converts.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from o2m.errors import ModelFileError

__all__ = ["Storage", "read_sto", "write_sto"]


@dataclass(frozen=True)
class Storage:
    """A table over time.

    Attributes:
        name: the table's name (the file's first header line).
        times: shape (T,), seconds.
        columns: labels of the data columns (``time`` excluded), length C.
        data: shape (T, C).
        in_degrees: whether the header says rotations are in degrees.
    """

    name: str
    times: np.ndarray
    columns: tuple[str, ...]
    data: np.ndarray
    in_degrees: bool

    def column(self, label: str) -> np.ndarray:
        """One column, shape (T,); KeyError naming close labels when absent."""
        try:
            return self.data[:, self.columns.index(label)]
        except ValueError:
            import difflib

            close = difflib.get_close_matches(label, self.columns, n=3)
            raise KeyError(f"no column {label!r} in {self.name!r}" +
                           (f"; did you mean {', '.join(close)}?" if close else "")) from None

    def first_row(self) -> dict[str, float]:
        """The first row as ``{label: value}``."""
        return dict(zip(self.columns, map(float, self.data[0]), strict=False))


def read_sto(path: str | os.PathLike[str]) -> Storage:
    """Read a ``.sto`` or ``.mot`` file; :class:`ModelFileError` if it is not one."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as exc:
        raise ModelFileError(f"cannot read {path}: {exc.strerror}") from exc
    try:
        end = next(i for i, line in enumerate(lines) if line.strip().lower() == "endheader")
    except StopIteration:
        raise ModelFileError(f"{path}: no 'endheader' line; not an OpenSim storage file") from None
    header = lines[:end]
    in_degrees = any(h.replace(" ", "").lower() == "indegrees=yes" for h in header)
    name = header[0].strip() if header else path.stem
    labels = [c.strip() for c in lines[end + 1].strip("\r\n").split("\t") if c.strip()]
    if not labels or labels[0].lower() != "time":
        raise ModelFileError(f"{path}:{end + 2}: expected column labels starting with 'time', got {labels[:3]}")
    rows = []
    for lineno, line in enumerate(lines[end + 2:], end + 3):
        if not line.strip():
            continue
        try:
            values = [float(v) for v in line.split()]
        except ValueError as exc:
            raise ModelFileError(f"{path}:{lineno}: {exc}") from None
        if len(values) != len(labels):
            raise ModelFileError(f"{path}:{lineno}: {len(values)} values for {len(labels)} columns")
        rows.append(values)
    if not rows:
        raise ModelFileError(f"{path}: no data rows")
    table = np.asarray(rows, float)
    return Storage(name, table[:, 0], tuple(labels[1:]), table[:, 1:], in_degrees)


def write_sto(path: str | os.PathLike[str], times: np.ndarray, columns: list[str] | tuple[str, ...],
              data: np.ndarray, *, name: str | None = None, in_degrees: bool = False) -> Path:
    """Write a table as an OpenSim 4 ``.sto`` file (17 significant digits); returns the path."""
    path = Path(path)
    data = np.asarray(data, float)
    times = np.asarray(times, float)
    if data.shape != (len(times), len(columns)):
        raise ValueError(f"data shape {data.shape} does not match {len(times)} times x {len(columns)} columns")
    head = [name or path.stem, "version=1", f"nRows={len(times)}", f"nColumns={len(columns) + 1}",
            f"inDegrees={'yes' if in_degrees else 'no'}", "endheader", "\t".join(["time", *columns])]
    body = np.column_stack([times, data])
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(head) + "\n")
        np.savetxt(f, body, fmt="%.17g", delimiter="\t")
    return path
