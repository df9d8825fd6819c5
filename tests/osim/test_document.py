"""Reading .osim documents (o2m.osim.document): what the parser refuses, deep nesting, component
paths and components that share one.

The documents are Tug_of_War (through the model registry) with one thing changed in its text.
"""

from __future__ import annotations

import copy
import re
import time
from pathlib import Path

import pytest
from lxml import etree

from o2m import models
from o2m.convert.converter import convert
from o2m.errors import ModelFileError, UnsupportedElementError
from o2m.osim.document import load_document
from tests.helpers import convert_options, require_models

TUG = "opensim-models/Models/Tug_of_War/Tug_of_War.osim"
FAST = {"fit_mechanics": False, "fit_wraps": False}


@pytest.fixture(scope="module")
def tug() -> str:
    require_models()
    return models.fetch(TUG).read_text()


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / f"{name}.osim"
    path.write_text(text)
    return path


def _nested(tug: str, depth: int) -> str:
    """Tug_of_War with ``depth`` nested unknown elements at the end of its <Model>."""
    i = tug.index("</Model>")
    return tug[:i] + "<a>" * depth + "</a>" * depth + tug[i:]


def test_deep_nesting_converts(tug, tmp_path):
    """1000 nested elements (beyond Python's recursion limit; OpenSim reads the file) index and convert."""
    path = _write(tmp_path, "deep", _nested(tug, 1000))
    doc = load_document(path)
    assert doc.path_of(doc.model.find("BodySet/objects/Body")) == "/bodyset/block"
    conv = convert(path, tmp_path / "out", convert_options(**FAST))
    assert conv.xml.exists()


def test_excessive_nesting_is_refused_fast(tug, tmp_path):
    path = _write(tmp_path, "deeper", _nested(tug, 3000))
    t0 = time.perf_counter()
    with pytest.raises(ModelFileError, match="not well-formed XML"):
        load_document(path)
    assert time.perf_counter() - t0 < 1.0


def test_entity_expansion_bomb_is_refused_fast(tug, tmp_path):
    ents = '<!ENTITY e0 "0123456789">' + "".join(
        f'<!ENTITY e{k} "{("&e" + str(k - 1) + ";") * 10}">' for k in range(1, 10))
    body = tug.split("\n", 1)[1].replace('<Model name="Tug_of_War">', '<Model name="&e9;">')
    path = _write(tmp_path, "bomb", f'<?xml version="1.0"?>\n<!DOCTYPE OpenSimDocument [{ents}]>\n{body}')
    t0 = time.perf_counter()
    with pytest.raises(ModelFileError, match="not well-formed XML"):
        load_document(path)
    assert time.perf_counter() - t0 < 1.0


@pytest.mark.parametrize("how", ["entity", "dtd", "xinclude"])
def test_no_external_resource_is_read(how, tug, tmp_path):
    """An external entity, an external DTD and an XInclude never bring in another file's text."""
    secret = tmp_path / "secret.txt"
    secret.write_text("SECRET-TEXT")
    body = tug.split("\n", 1)[1]
    if how == "entity":
        text = (f'<?xml version="1.0"?>\n<!DOCTYPE OpenSimDocument [<!ENTITY x SYSTEM "{secret.as_uri()}">]>\n'
                + body.replace('<Model name="Tug_of_War">', '<Model name="&x;">'))
    elif how == "dtd":
        dtd = tmp_path / "evil.dtd"
        dtd.write_text(f'<!ENTITY x SYSTEM "{secret.as_uri()}">')
        text = f'<?xml version="1.0"?>\n<!DOCTYPE OpenSimDocument SYSTEM "{dtd.as_uri()}">\n' + body
    else:
        text = '<?xml version="1.0"?>\n' + body.replace(
            '<Model name="Tug_of_War">',
            '<Model name="Tug_of_War" xmlns:xi="http://www.w3.org/2001/XInclude">'
            f'<xi:include href="{secret.name}" parse="text"/>')
    path = _write(tmp_path, how, text)
    try:
        doc = load_document(path)
    except ModelFileError as exc:
        assert "SECRET" not in str(exc)
        return
    assert "SECRET" not in etree.tostring(doc.model, encoding="unicode")


def _duplicated(tug: str, xpath: str) -> tuple[str, int, int]:
    """Tug_of_War with the element at ``xpath`` copied right after itself (as the file's text),
    the line of the original and of its copy."""
    root = etree.fromstring(tug.encode())
    (el,) = root.xpath(xpath)
    el.addnext(copy.deepcopy(el))
    text = '<?xml version="1.0" encoding="UTF-8" ?>\n' + etree.tostring(root, encoding="unicode")
    first, second = etree.fromstring(text.encode()).xpath(xpath)
    return text, first.sourceline, second.sourceline


@pytest.mark.parametrize("xpath", ["//Ground/components/PhysicalOffsetFrame[@name='ground_geom_frame_2']",
                                   "//SliderJoint/frames/PhysicalOffsetFrame[@name='block_offset']",
                                   "//ForceSet/objects/Thelen2003Muscle[@name='muscle1']"],
                         ids=["ground-frame", "joint-frame", "muscle"])
def test_duplicate_component_names_the_duplicate(xpath, tug, tmp_path):
    """Two components at one path (OpenSim renames the second): the error names the second, its
    line, and the first's line."""
    text, first, second = _duplicated(tug, xpath)
    path = _write(tmp_path, "dup", text)
    with pytest.raises(UnsupportedElementError) as info:
        convert(path, tmp_path / "out", convert_options(**FAST))
    e = info.value
    assert e.line == second and f"at line {first}" in str(e), str(e)
    assert e.element == xpath.rsplit("/", 1)[-1].split("[")[0] and e.path == str(path)
    assert "Model" not in (e.element or "")
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_groups_may_repeat_names(tug, tmp_path):
    """Object groups (not components of the model) may repeat a name, as ToyLanding's do."""
    group = '<ObjectGroup name="g"><objects>muscle1</objects></ObjectGroup>'
    text = tug.replace("<groups />\n\t\t</ForceSet>", f"<groups>{group}{group}</groups>\n\t\t</ForceSet>")
    assert text != tug
    conv = convert(_write(tmp_path, "groups", text), tmp_path / "out", convert_options(**FAST))
    assert conv.xml.exists()


def test_an_unnamed_element_of_an_upgraded_document_keeps_its_line(tmp_path):
    """OpenSim names an unnamed 3.x object when it upgrades the document ("weldconstraint"); its
    errors still point at its line in the user's file, found by its place among its tag's elements."""
    from o2m.osim.document import OsimDocument

    original = etree.ElementTree(etree.fromstring(
        "<OpenSimDocument Version=\"30000\">\n<Model name=\"m\">\n<ConstraintSet><objects>\n"
        "<WeldConstraint name=\"first\"/>\n<WeldConstraint>\n</WeldConstraint>\n</objects></ConstraintSet>\n"
        "</Model>\n</OpenSimDocument>"))
    upgraded = etree.fromstring(
        "<Model name=\"m\"><ConstraintSet><objects><WeldConstraint name=\"first\"/>"
        "<WeldConstraint name=\"weldconstraint\"/></objects></ConstraintSet></Model>")
    doc = OsimDocument(path=tmp_path / "m.osim", model=upgraded, version=30000, original=original)
    first, second = upgraded.iter("WeldConstraint")
    assert doc.line_of(first) == 4 and doc.line_of(second) == 5
    assert "m.osim:line 5: <WeldConstraint name=\"weldconstraint\">" in str(doc.error(second, "x"))
    # counts that differ (a 3.x <defaults> entry the upgrade drops) give no line rather than a wrong one
    original.getroot().find("Model").insert(0, etree.fromstring("<defaults><WeldConstraint/></defaults>"))
    assert doc.line_of(second) is None


def test_a_3x_document_with_several_plugin_classes_names_them_all(tmp_path):
    """OpenSim's 3.x upgrade stops at the first class it does not know; the refusal lists every
    one in the document's sets, so one run tells the user all that is missing."""
    path = tmp_path / "plugins.osim"
    path.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n<OpenSimDocument Version="30000">\n<Model name="m">\n'
        "<ForceSet><objects>\n"
        '<PistonActuator name="p1"/>\n<ControllableSpring name="s1"/>\n<ControllableSpring name="s2"/>\n'
        '<CoordinateLimitForce name="ok"/>\n'
        "</objects></ForceSet>\n</Model>\n</OpenSimDocument>\n")
    with pytest.raises(ModelFileError) as err:
        load_document(path)
    assert "PistonActuator (1), ControllableSpring (2)" in str(err.value)
    assert "CoordinateLimitForce" not in str(err.value).split("does not know")[-1]


def test_a_comment_is_read_as_opensim_reads_it(tug, tmp_path):
    """A comment ends at the first ``-->`` whatever it holds, ``--`` included, as OpenSim's
    parser reads it (osim-rl's ue_RL.osim: a ``<!--`` left open before a one-line comment); the
    lines after it keep their numbers in errors."""
    i = tug.index("<BodySet")
    commented = tug[:i] + "<!--\n\t\t<!--Bodies of the model.-->\n" + tug[i:]
    plain, odd = _write(tmp_path, "plain", tug), _write(tmp_path, "odd", commented)
    def text(path: Path) -> bytes:  # the document without its layout
        return re.sub(rb"\s+", b"", etree.tostring(load_document(path).model))

    assert text(odd) == text(plain)
    broken = commented.replace("<BodySet", "<BodySet <", 1)
    line = commented[:commented.index("<BodySet")].count("\n") + 1
    with pytest.raises(ModelFileError, match=rf"broken.osim:{line}: not well-formed XML"):
        load_document(_write(tmp_path, "broken", broken))
