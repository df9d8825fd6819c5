"""Reading .osim files: XML parsing, 3.x upgrade, component paths and source lines.

o2m reads OpenSim 4.x documents with lxml. A 3.x document (``Version`` below 40000, such as
MoBL-ARMS) is first upgraded by OpenSim itself (``opensim.Model(path).printToXML``), so that
one reader serves both formats; errors in an upgraded document still point at the line of
the user's original file where the element (matched by tag and name) can be found there.
"""

from __future__ import annotations

import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from lxml import etree

from o2m.errors import ModelFileError, O2MError, UnsupportedElementError
from o2m.osim import runtime
from o2m.osim.kinds import count_text, default_coordinates, renamed_type, unknown_classes

#: First document version of the OpenSim 4.x format.
VERSION_4 = 40000
#: The largest magnitude a number of the model may have (MuJoCo's mjMAXVAL: its simulation treats
#: larger positions, speeds and accelerations as diverged); a length of 1e300 m would pass every
#: other check and give a model that fails at its first step, a spline value of 1e300 a joint
#: equality of infinite coefficients.
MAX_MAGNITUDE = 1e10

#: Default component names of the model's sets, used when a set has no name attribute.
_SET_NAMES = {
    "BodySet": "bodyset",
    "JointSet": "jointset",
    "ConstraintSet": "constraintset",
    "ForceSet": "forceset",
    "MarkerSet": "markerset",
    "ContactGeometrySet": "contactgeometryset",
    "ControllerSet": "controllerset",
    "ProbeSet": "probeset",
    "ComponentSet": "componentset",
    "WrapObjectSet": "wrapobjectset",
}


#: Elements whose named children are not components of the model: object groups and 3.x defaults.
_NOT_COMPONENTS = frozenset({"groups", "defaults"})


def _is_component(el: etree._Element) -> bool:
    """True for XML elements that are OpenSim objects with a component name."""
    if not isinstance(el.tag, str) or not el.tag[:1].isupper():
        return False
    return el.get("name") is not None or el.tag in _SET_NAMES


def _component_name(el: etree._Element) -> str:
    return el.get("name") or _SET_NAMES.get(el.tag, el.tag.lower())


@dataclass
class OsimDocument:
    """An .osim document ready to read: the 4.x ``<Model>`` element and where it came from.

    ``path`` is the file the user gave. ``model`` is the ``<Model>`` element of a 4.x document
    (the upgraded copy for a 3.x file). ``version`` is the original document version.
    """

    path: Path
    model: etree._Element
    version: int
    original: etree._ElementTree | None = None
    _paths: dict[etree._Element, str] = field(default_factory=dict, repr=False)
    _by_path: dict[str, etree._Element] = field(default_factory=dict, repr=False)
    _firsts: dict[etree._Element, etree._Element] = field(default_factory=dict, repr=False)

    @property
    def upgraded(self) -> bool:
        return self.version < VERSION_4

    # -- locating elements -------------------------------------------------------------
    def line_of(self, el: etree._Element) -> int | None:
        """Line of ``el`` in the user's file (for an upgraded 3.x document, the line of the
        element with the same tag and name in the original, when there is one; else, as OpenSim
        names an unnamed object when it upgrades it, the one at the same place among the elements
        of that tag, when both documents have as many)."""
        if not self.upgraded:
            return el.sourceline
        if self.original is None:
            return None
        name = el.get("name")
        for cand in self.original.iter(el.tag):
            if name is not None and cand.get("name") == name:
                return cand.sourceline
        ours, theirs = list(self.model.iter(el.tag)), list(self.original.iter(el.tag))
        if len(ours) == len(theirs) and el in ours:
            return theirs[ours.index(el)].sourceline
        return None

    def error(self, el: etree._Element, message: str) -> UnsupportedElementError:
        """An error about element ``el`` that names its tag, name, file and line."""
        return UnsupportedElementError(
            message, element=el.tag, name=el.get("name"), line=self.line_of(el), path=str(self.path)
        )

    # -- component paths ---------------------------------------------------------------
    def _index(self) -> None:
        """Index every component by its path, walking the tree in document order without recursion
        (a document may nest deeper than Python's recursion limit). The maps hold the elements
        themselves, which keeps lxml's proxies (and so their identity) alive. A later component at
        a path already taken is recorded in ``_firsts`` (but not in groups or defaults, which name
        no component of the model)."""
        if self._by_path:
            return
        self._paths[self.model] = "/"
        self._by_path["/"] = self.model
        stack: list[tuple[etree._Element, str, bool]] = [
            (c, "/", False) for c in reversed(self.model) if isinstance(c.tag, str)]
        while stack:  # popped in document order, each element before its children (as a recursion would)
            el, path, quiet = stack.pop()
            quiet = quiet or el.tag in _NOT_COMPONENTS
            if _is_component(el):
                path = f"{path.rstrip('/')}/{_component_name(el)}"
                self._paths[el] = path
                first = self._by_path.setdefault(path, el)
                if first is not el and not quiet:
                    self._firsts[el] = first
            stack.extend((c, path, quiet) for c in reversed(el) if isinstance(c.tag, str))

    def check_unique(self, el: etree._Element) -> None:
        """Raise when component ``el`` shares its path (its name among its siblings) with an earlier one.

        OpenSim renames such a component (``name_0``) when it loads the file; o2m refuses it
        instead, naming both: MuJoCo needs unique names, and a socket or a muscle name that
        means one of two components is ambiguous to the reader of the file.
        """
        self._index()
        first = self._firsts.get(el)
        if first is not None:
            raise self.error(el, f"has the same path {self._paths[el]} as the <{first.tag}> at line "
                                 f"{self.line_of(first)} (OpenSim would rename it '{el.get('name')}_0'): "
                                 f"give it a name of its own")

    def component(self, path: str) -> etree._Element | None:
        """The component at absolute ``path``, or else the nearest enclosing one the document has
        (OpenSim names components the document may not have, such as a muscle's default path);
        None when not even the first part of the path is one."""
        self._index()
        parts = [p for p in path.split("/") if p]
        while parts:
            el = self._by_path.get("/" + "/".join(parts))
            if el is not None:
                return el
            parts.pop()
        return None

    def path_of(self, el: etree._Element) -> str:
        """Absolute OpenSim component path of ``el`` (e.g. ``/jointset/elbow/r_humerus_offset``)."""
        self._index()
        return self._paths[el]

    def owner_of(self, el: etree._Element) -> etree._Element:
        """Nearest enclosing component of ``el`` (for a socket element: the socket's owner)."""
        self._index()
        parent = el.getparent()
        while parent is not None and parent not in self._paths:
            parent = parent.getparent()
        if parent is None:
            return self.model
        return parent

    def resolve(self, socket: etree._Element) -> etree._Element:
        """The component a socket element (e.g. ``<socket_parent_frame>``) points at.

        Paths are resolved as OpenSim does: absolute from the model, or relative to the
        component that owns the socket; a bare name that is not found that way is looked up
        among all components and must be unique.
        """
        self._index()
        target = (socket.text or "").strip()
        owner = self.owner_of(socket)
        self.check_unique(owner)
        if not target:
            raise self.error(owner, f"has an empty <{socket.tag}>")
        base = "/" if target.startswith("/") else self._paths[owner]
        parts = [p for p in base.split("/") if p]
        for seg in target.split("/"):
            if seg in ("", "."):
                continue
            if seg == "..":
                if parts:
                    parts.pop()
                continue
            parts.append(seg)
        found = self._by_path.get("/" + "/".join(parts))
        if found is not None:
            self._check_target(found)
            return found
        name = target.rstrip("/").split("/")[-1]
        matches = [el for p, el in self._by_path.items() if p.rsplit("/", 1)[-1] == name]
        if len(matches) == 1:
            self._check_target(matches[0])
            return matches[0]
        why = "no component has that name" if not matches else f"{len(matches)} components share that name"
        raise self.error(owner, f"<{socket.tag}> refers to '{target}', which cannot be resolved: {why}")


    def _check_target(self, found: etree._Element) -> None:
        """Raise when a socket's target path is shared by several components (naming the second)."""
        second = next((el for el, first in self._firsts.items() if first is found), None)
        if second is not None:
            self.check_unique(second)


#: OpenSim names some nested classes' tags ``Outer::Inner`` (``<HuntCrossleyForce::ContactParametersSet>``),
#: which is not an XML name: read as ``Outer__Inner`` (the document's lines stay where they are).
_NESTED_TAG = re.compile(rb"<(/?)([A-Za-z_][\w.-]*)::(?=[A-Za-z_])")
NESTED_SEPARATOR = "__"
#: An XML comment as OpenSim's parser (TinyXML, in SimTK) reads one: from ``<!--`` to the first
#: ``-->``, whatever it holds. XML forbids ``--`` inside a comment, so a commented-out line left
#: inside another comment (osim-rl's ``ue_RL.osim``: ``<!--`` then ``<!--Markers in the model.-->``)
#: stops a strict parser where OpenSim reads on.
_COMMENT = re.compile(rb"<!--.*?-->", re.DOTALL)


def parse_xml(path: Path) -> etree._ElementTree:
    """An .osim file's XML tree (OpenSim's ``Outer::Inner`` tags read as ``Outer__Inner``); a
    :class:`~o2m.errors.ModelFileError` naming the file and line when it cannot be read."""
    if not path.exists():
        raise ModelFileError(f"{path}: no such file")
    if path.is_dir():
        raise ModelFileError(f"{path}: is a folder, expected an .osim file")
    try:
        data = _NESTED_TAG.sub(rb"<\1\2" + NESTED_SEPARATOR.encode(), _without_comments(path.read_bytes()))
        parser = etree.XMLParser(remove_blank_text=False, huge_tree=True)
        return etree.ElementTree(etree.fromstring(data, parser, base_url=str(path)))
    except etree.XMLSyntaxError as exc:
        line = exc.lineno if exc.lineno else "?"
        raise ModelFileError(f"{path}:{line}: not well-formed XML: {exc.msg}") from None
    except OSError as exc:
        raise ModelFileError(f"{path}: cannot be read: {exc}") from None


def _without_comments(data: bytes) -> bytes:
    """``data`` with each comment (:data:`_COMMENT`) replaced by its line breaks, so that the
    document's lines stay where they are."""
    return _COMMENT.sub(lambda m: b"\n" * m.group().count(b"\n"), data)


def _upgrade_with_opensim(path: Path) -> etree._ElementTree:
    """Let OpenSim read a 3.x document and print it in the 4.x format."""
    opensim = runtime.opensim()
    try:
        model = opensim.Model(str(path))
    except Exception as exc:  # OpenSim raises a generic RuntimeError
        unknown = unknown_classes(el for holder in parse_xml(path).getroot().iter("objects") for el in holder)
        listed = (f"; classes in its sets OpenSim 4.6 does not know (misspelt, or from a plugin): "
                  f"{count_text(unknown)}" if unknown else "")  # OpenSim's upgrade names the first only
        raise ModelFileError(f"{path}: OpenSim could not read this 3.x document: {exc}{listed}") from None
    with tempfile.TemporaryDirectory(prefix="o2m-upgrade-") as tmp:
        out = Path(tmp) / path.name
        model.printToXML(str(out))
        return parse_xml(out)


def opensim_reason(exc: Exception) -> tuple[str | None, str]:
    """(the component path OpenSim's error ``exc`` names, or None; its reason, on one line)."""
    text = str(exc).strip()
    reason = text.split("': ", 1)[-1].split("\n\tIn Component")[0].replace("\n", " ").strip()
    m = re.search(r"In Component '(/[^']*)'", text) or re.search(r"(/(?:bodyset|jointset|forceset)/[^ ').,]+)", text)
    return (m.group(1).rstrip(".") if m else None), reason


def opensim_refusal(path: str | Path, exc: Exception) -> Exception:
    """The error for OpenSim's refusal (``exc``) to load the file at ``path``: naming the component
    OpenSim names ("In Component '/forceset/m1'"), its line and OpenSim's reason when the file's
    document has that component; else a ModelFileError naming the file."""
    component, reason = opensim_reason(exc)
    try:
        doc = load_document(path)
        el = doc.component(component) if component else None
    except O2MError:
        el = None
    if el is None:
        return ModelFileError(f"{path}: OpenSim could not load the model: {str(exc).strip()}")
    return doc.error(el, f"makes OpenSim refuse the model: {reason}")


def _rename_old_types(model: etree._Element) -> None:
    """Give every element whose tag is an old type name OpenSim still reads (a 4.x file may say
    ``<Schutte1993Muscle>``) the tag of the type OpenSim reads it as, so that o2m's handlers,
    which dispatch on the tag, see what OpenSim sees."""
    for el in model.iter(etree.Element):  # elements only, not comments
        new = renamed_type(el.tag)
        if new is not None:
            el.tag = new


def _add_implicit_components(model: etree._Element) -> None:
    """Add the components OpenSim creates for a 4.x document that leaves them out: the ground frame,
    and the coordinates of a joint without a ``<coordinates>`` list (named as OpenSim names them,
    ``_coord_0`` ..., at their defaults; an empty list OpenSim refuses, and so does o2m). The added
    elements have no source line."""
    if model.find("Ground") is None:
        model.insert(0, etree.Element("Ground", name="ground"))
    for holder in (*model.findall("JointSet/objects"), *model.findall("components")):
        for joint in holder:
            if not isinstance(joint.tag, str) or joint.find("coordinates") is not None:
                continue
            names = default_coordinates(joint.tag)
            if names:
                listed = etree.SubElement(joint, "coordinates")
                for name in names:
                    etree.SubElement(listed, "Coordinate", name=name)


def load_document(path: str | Path) -> OsimDocument:
    """Read an .osim file (4.x, or 3.x upgraded through OpenSim) into an :class:`OsimDocument`."""
    path = Path(path)
    tree = parse_xml(path)
    root = tree.getroot()
    if root.tag != "OpenSimDocument":
        raise ModelFileError(
            f"{path}:{root.sourceline}: root element is <{root.tag}>, expected <OpenSimDocument>"
        )
    try:
        version = int(root.get("Version", "0"))
    except ValueError:
        raise ModelFileError(f"{path}: Version attribute '{root.get('Version')}' is not a number") from None
    original = None
    if version < VERSION_4:
        original = tree
        tree = _upgrade_with_opensim(path)
        root = tree.getroot()
    model = root.find("Model")
    if model is None:
        raise ModelFileError(f"{path}: <OpenSimDocument> holds no <Model>")
    if original is None:  # OpenSim's upgrade of a 3.x document already wrote the current names
        _rename_old_types(model)
    _add_implicit_components(model)
    return OsimDocument(path=path, model=model, version=version, original=original)


def _floats(el: etree._Element | None, n: int | None, doc: OsimDocument, what: str,
            default: tuple[float, ...] | np.ndarray | None = None) -> np.ndarray:
    """Property element ``el`` as n floats; ``default`` (when given) for an absent or empty one, as
    OpenSim keeps a property's default when its element holds no value ("Failed to read ... the
    data have been ignored")."""
    if el is None or not (el.text or "").strip():
        if default is not None:
            return np.array(default, dtype=float)
        raise doc.error(el.getparent() if el is not None else doc.model, f"lacks <{what}>")
    try:
        vals = np.array([float(v) for v in el.text.split()])
    except ValueError:
        raise doc.error(el.getparent(), f"<{what}> holds '{el.text.strip()}', not numbers") from None
    if n is not None and vals.size != n:
        raise doc.error(el.getparent(), f"<{what}> has {vals.size} numbers, expected {n}")
    if not np.all(np.isfinite(vals)):
        raise doc.error(el.getparent(), f"<{what}> holds a non-finite number")
    if np.any(np.abs(vals) > MAX_MAGNITUDE):
        raise doc.error(el.getparent(), f"<{what}> holds {vals[np.argmax(np.abs(vals))]:g}, beyond "
                                        f"{MAX_MAGNITUDE:g}, MuJoCo's largest value")
    return vals
