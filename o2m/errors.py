"""Errors o2m raises for bad input. Each names the offending element and, when known, its line."""

from __future__ import annotations

import os
from collections.abc import Iterable


class O2MError(Exception):
    """Base class of every error o2m raises on purpose."""


class ModelFileError(O2MError):
    """An .osim file is missing, unreadable or not well-formed XML."""


class UnsupportedElementError(O2MError):
    """The document holds an element o2m does not know or cannot convert faithfully.

    ``element`` is the XML tag, ``name`` the element's name attribute, ``line`` its line in
    the file the user gave (None when it cannot be located), ``message`` what is wrong (the
    text after the element).
    """

    def __init__(self, message: str, *, element: str | None = None, name: str | None = None,
                 line: int | None = None, path: str | None = None):
        self.element, self.name, self.line, self.path = element, name, line, path
        self.message = message
        where = []
        if path:
            where.append(str(path))
        if line:
            where.append(f"line {line}")
        prefix = ":".join(where)
        what = f"<{element} name=\"{name}\">" if element and name else (f"<{element}>" if element else "")
        super().__init__(" ".join(p for p in (prefix + ":" if prefix else "", what, message) if p))


class FetchError(O2MError):
    """A model file could not be fetched or failed its sha256 check."""


class ValidationError(O2MError):
    """The two models cannot be compared (a model fails to load, or they do not correspond)."""


class MissingJointError(ValidationError):
    """Independent OpenSim coordinates have no MuJoCo joint of the same name.

    ``missing`` lists the coordinate names.
    """

    def __init__(self, missing: Iterable[str], mjcf_path: str | os.PathLike | None = None):
        self.missing = sorted(missing)
        where = f" in {os.fspath(mjcf_path)}" if mjcf_path is not None else ""
        super().__init__(
            f"{len(self.missing)} independent OpenSim coordinate(s) have no MuJoCo hinge/slide joint "
            f"of the same name{where}: {', '.join(self.missing)}"
        )
