"""MJCF text with one precision rule: every number o2m computed is written in full.

MuJoCo's XML writer prints about 6 significant digits, which alone would put 1e-6 m errors into a
model. The builders keep each value they set (metres, radians, kg, kg m², in MuJoCo's Z-up frames)
by (MJCF tag, name), and a precision-restore pass writes them back with 17 significant digits,
enough for every double to read back unchanged.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping

import numpy as np
from lxml import etree

#: The exact values of a model's elements: attribute -> value (a number or an array), by (tag, name).
Exact = Mapping[tuple[str, str], Mapping[str, object]]


def number_text(value) -> str:
    """``value`` (a number or an array) as MJCF attribute text: each number with 17 significant digits."""
    return " ".join(f"{float(x):.17g}" for x in np.atleast_1d(np.asarray(value, dtype=float)))


def set_numbers(el: etree._Element, values: Mapping[str, object]) -> None:
    """Set each attribute of ``values`` on element ``el``, written in full."""
    for attr, v in values.items():
        el.set(attr, number_text(v))


def parse(xml: str) -> etree._Element:
    """The root element of MJCF text."""
    return etree.fromstring(xml.encode())


def to_text(root: etree._Element) -> str:
    """MJCF text of ``root``, indented as every o2m pass writes it."""
    return etree.tostring(root, encoding="unicode", pretty_print=True)


def _tag_and_name(el: etree._Element) -> tuple[str, str]:
    return el.tag, el.get("name")


def restore_numbers(xml: str, exact: Exact, tags: Iterable[str],
                    key: Callable[[etree._Element], tuple[str, str]] = _tag_and_name) -> str:
    """MJCF text ``xml`` with the attributes ``exact[key(el)]`` of every element ``el`` of the
    given ``tags`` written in full (``key``: the element's tag and name unless given)."""
    root = parse(xml)
    for el in root.iter(*tags):
        vals = exact.get(key(el))
        if vals is not None:
            set_numbers(el, vals)
    return to_text(root)


def restore_tree_numbers(xml: str, exact: Exact) -> str:
    """MJCF text ``xml`` with the exact values of its bodies (``("body", name)``, and their
    inertials: ``("inertial", name)``), joints, sites and joint equalities (``("equality", name)``)
    written in full. A body's inertial is written even where MuJoCo's writer left it out (tiny)."""
    root = parse(xml)
    for el in root.iter("body", "joint", "site"):
        name = el.get("name")
        tag = "equality" if el.getparent().tag == "equality" else el.tag
        vals = exact.get((tag, name))
        if vals is None:
            continue
        set_numbers(el, vals)
        if el.tag == "body" and ("inertial", name) in exact:
            inertial = el.find("inertial")
            if inertial is None:  # MuJoCo's writer leaves out tiny inertials
                inertial = etree.Element("inertial")
                el.insert(0, inertial)
            for attr in ("quat", "diaginertia", "fullinertia"):
                inertial.attrib.pop(attr, None)
            set_numbers(inertial, exact[("inertial", name)])
    return to_text(root)


#: MJCF attributes that hold names or paths, never numbers (a body named "inf" is no number).
_TEXT_ATTRIBUTES = frozenset({
    "name", "model", "file", "meshdir", "texturedir", "assetdir", "class", "childclass", "content_type",
    "joint", "joint1", "joint2", "body", "body1", "body2", "site", "site1", "site2", "tendon", "tendon1",
    "tendon2", "geom", "geom1", "geom2", "mesh", "target", "sidesite", "material", "texture", "prefix",
})


def non_finite(xml: str) -> list[tuple[str, str | None, str, str]]:
    """Every attribute of MJCF text ``xml`` that holds numbers, one of them NaN or infinite:
    (tag, the element's name, attribute, its text)."""
    out = []
    for el in parse(xml).iter():
        if not isinstance(el.tag, str):
            continue
        for attr, text in el.attrib.items():
            if attr in _TEXT_ATTRIBUTES:
                continue
            try:
                values = [float(tok) for tok in text.split()]
            except ValueError:
                continue  # a keyword ("true", "auto", ...), not numbers
            if not all(np.isfinite(values)):
                out.append((el.tag, el.get("name"), attr, text))
    return out
