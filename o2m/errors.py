"""Errors o2m raises for bad input. Each names the offending element and, when known, its line."""

from __future__ import annotations


class O2MError(Exception):
    """Base class of every error o2m raises on purpose."""


class ModelFileError(O2MError):
    """An .osim file is missing, unreadable or not well-formed XML."""


class UnsupportedElementError(O2MError):
    """The document holds an element o2m does not know or cannot convert faithfully.

    ``element`` is the XML tag, ``name`` the element's name attribute, ``line`` its line in
    the file the user gave (None when it cannot be located).
    """

    def __init__(self, message: str, *, element: str | None = None, name: str | None = None,
                 line: int | None = None, path: str | None = None):
        self.element, self.name, self.line, self.path = element, name, line, path
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
