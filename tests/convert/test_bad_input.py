"""Bad input: each case raises a clear O2MError (naming the element, its name and its line),
makes the CLI exit with status 1 and the message on stderr, and writes no output file.

The cases start from one valid model (built with the opensim API and printed) and break one
thing in its text. A missing mesh file is not an error: the model converts and the report
lists the mesh as skipped.
"""

from __future__ import annotations

import copy
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import opensim as osim
import pytest
from lxml import etree

from o2m.convert import converter
from o2m.convert.converter import convert
from o2m.errors import ModelFileError, O2MError, UnsupportedElementError
from tests.helpers import convert_options

osim.Logger.setLevelString("error")

SPLINE = ('<SimmSpline name="function"><x>-2 -1 0 0.5</x><y>0.001 0.004 -0.002 -0.005</y></SimmSpline>')


def _build_base(path: Path, *, mesh: str | None = None, ellipsoid: bool = False, muscle: bool = False) -> str:
    """ground -PinJoint j1-> b1 -CustomJoint knee-> b2, offsets on both sides; the knee's
    translation1 is a SimmSpline. ``mesh`` attaches a Mesh geometry file to b1;
    ``ellipsoid`` makes j1 an EllipsoidJoint; ``muscle`` adds a Thelen2003Muscle m1 from b1 to
    b2 that wraps a WrapCylinder cyl on b1."""
    m = osim.Model()
    m.setName(path.stem)
    b1 = osim.Body("b1", 2.0, osim.Vec3(0.05, -0.2, 0.01), osim.Inertia(0.03, 0.012, 0.028, 0.0015, -0.0008, 0.002))
    b2 = osim.Body("b2", 1.5, osim.Vec3(-0.02, -0.15, 0.03), osim.Inertia(0.02, 0.009, 0.021, -0.001, 0.0012, 0.0))
    m.addBody(b1)
    m.addBody(b2)
    args = (m.getGround(), osim.Vec3(0.1, 0.8, -0.05), osim.Vec3(0.3, -0.2, 0.5), b1, osim.Vec3(0.02, 0.3, 0.01),
            osim.Vec3(0.1, 0.4, -0.3))
    if ellipsoid:
        j1 = osim.EllipsoidJoint("j1", *args, osim.Vec3(0.1, 0.2, 0.15))
    else:
        j1 = osim.PinJoint("j1", *args)
    m.addJoint(j1)
    st = osim.SpatialTransform()
    axes = [(0, 0, 1), (1, 0, 0), (0, 1, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    for i, ax in enumerate(axes):
        ta = st.updTransformAxis(i)
        names = osim.ArrayStr()
        if i in (0, 3):
            names.append("knee")
        ta.setCoordinateNames(names)
        ta.setAxis(osim.Vec3(*ax))
        ta.set_function(osim.LinearFunction(1.0, 0.0) if i in (0, 3) else osim.Constant(0.0))
    knee = osim.CustomJoint("knee", b1, osim.Vec3(0.03, -0.4, 0.02), osim.Vec3(-0.6, 0.2, 0.1), b2,
                            osim.Vec3(0.01, 0.25, -0.01), osim.Vec3(0.2, -0.1, 0.7), st)
    m.addJoint(knee)
    knee.upd_coordinates(0).setRangeMin(-2.0)
    knee.upd_coordinates(0).setRangeMax(0.5)
    if mesh:
        b1.attachGeometry(osim.Mesh(mesh))
    if muscle:
        _add_muscle(m, b1, b2)
    m.finalizeConnections()
    m.printToXML(str(path))
    tree = etree.parse(str(path))
    (ta,) = tree.xpath("//CustomJoint[@name='knee']/SpatialTransform/TransformAxis[@name='translation1']")
    ta.remove(ta.find("LinearFunction"))
    ta.append(etree.fromstring(SPLINE))
    tree.write(str(path), xml_declaration=True, encoding="UTF-8")
    return path.read_text()


def _add_muscle(m, b1, b2) -> None:
    """Thelen2003Muscle m1 (300 N) from b1 to b2, over WrapCylinder cyl (radius 0.02 m) on b1."""
    mus = osim.Thelen2003Muscle("m1", 300.0, 0.1, 0.2, 0.1)
    mus.addNewPathPoint("m1-origin", b1, osim.Vec3(0.02, -0.1, 0.03))
    mus.addNewPathPoint("m1-insertion", b2, osim.Vec3(0.0, -0.1, 0.02))
    m.addForce(mus)
    cyl = osim.WrapCylinder()
    cyl.setName("cyl")
    cyl.set_radius(0.02)
    cyl.set_length(0.1)
    cyl.set_translation(osim.Vec3(0.04, -0.35, 0.02))
    b1.addWrapObject(cyl)
    mus.updGeometryPath().addPathWrap(cyl)


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> str:
    """Text of the valid model; checks that it converts."""
    d = tmp_path_factory.mktemp("base")
    text = _build_base(d / "base.osim")
    conv = convert(d / "base.osim", d / "out", convert_options())
    assert conv.xml.exists()
    return text


def line_of(text: str, needle: str) -> int:
    """Line (1-based) of the first occurrence of ``needle`` in ``text``."""
    i = text.index(needle)
    return text.count("\n", 0, i) + 1


@dataclass
class Case:
    """A broken document: ``text`` (None: no file at all), the error class, strings its message
    must contain (the element, its name, its line)."""

    text: str | None
    error: type[O2MError]
    expect: list[str]


def _case(name: str, base: str, tmp_path: Path) -> Case:
    if name == "missing-file":
        return Case(None, ModelFileError, ["no such file"])
    if name == "truncated":
        text = base[: len(base) // 2]
        return Case(text, ModelFileError, ["not well-formed XML", f":{text.count(chr(10)) + 1}:"])
    if name == "empty":
        return Case("", ModelFileError, ["not well-formed XML", ":1:"])
    if name == "not-opensim":
        text = '<?xml version="1.0"?>\n<mujoco model="m">\n  <worldbody/>\n</mujoco>\n'
        return Case(text, ModelFileError, ["<mujoco>", "OpenSimDocument"])
    if name == "unknown-joint":
        marker = '<JointSet name="jointset">\n\t\t\t<objects>\n'
        assert marker in base
        text = base.replace(marker, marker + '\t\t\t\t<FooJoint name="x">\n\t\t\t\t</FooJoint>\n', 1)
        return Case(text, UnsupportedElementError,
                    ['<FooJoint name="x">', f"line {line_of(text, '<FooJoint')}", "not an element OpenSim"])
    if name == "ellipsoid-joint":  # without its radii (OpenSim's default: NaN)
        text = _build_base(tmp_path / "ellipsoid_src.osim", ellipsoid=True)
        text = re.sub(r"<radii_x_y_z>[^<]*</radii_x_y_z>", "", text)
        return Case(text, UnsupportedElementError,
                    ['<EllipsoidJoint name="j1">', f"line {line_of(text, '<EllipsoidJoint')}", "lacks <radii_x_y_z>"])
    if name == "scapulothoracic-joint":  # a PinJoint renamed: one coordinate of four
        text = base.replace("<PinJoint ", "<ScapulothoracicJoint ").replace("</PinJoint>", "</ScapulothoracicJoint>")
        return Case(text, UnsupportedElementError,
                    ['<ScapulothoracicJoint name="j1">', f"line {line_of(text, '<ScapulothoracicJoint')}",
                     "has 1 coordinates; a ScapulothoracicJoint has 4"])
    if name == "unknown-function":
        text = base.replace("<SimmSpline ", "<FooFunction ").replace("</SimmSpline>", "</FooFunction>")
        return Case(text, UnsupportedElementError,
                    ["<FooFunction", f"line {line_of(text, '<FooFunction')}"])
    if name == "bad-joint-socket":
        sock = "<socket_parent_frame>b1_offset</socket_parent_frame>"
        assert sock in base
        text = base.replace(sock, "<socket_parent_frame>no_such_frame</socket_parent_frame>")
        return Case(text, UnsupportedElementError,
                    ['<CustomJoint name="knee">', f"line {line_of(text, '<CustomJoint')}", "no_such_frame"])
    if name == "bad-frame-socket":
        sock = "<socket_parent>/bodyset/b1</socket_parent>"
        text = base.replace(sock, "<socket_parent>/bodyset/nobody</socket_parent>", 1)  # j1's child frame
        tag = '<PhysicalOffsetFrame name="b1_offset">'
        return Case(text, UnsupportedElementError, [tag, f"line {line_of(text, tag)}", "/bodyset/nobody"])
    if name == "mass-text":
        text = base.replace("<mass>2</mass>", "<mass>heavy</mass>")
        tag = '<Body name="b1">'
        return Case(text, UnsupportedElementError, [tag, f"line {line_of(text, tag)}", "heavy", "mass"])
    if name == "inertia-text":
        old = text_between(base, '<Body name="b2">', "<inertia>", "</inertia>")
        text = base.replace(f"<inertia>{old}</inertia>", "<inertia>0.02 0.009 abc 0 0 0</inertia>")
        tag = '<Body name="b2">'
        return Case(text, UnsupportedElementError, [tag, f"line {line_of(text, tag)}", "abc", "inertia"])
    if name in MORE_CASES:
        return MORE_CASES[name](base, tmp_path)
    raise ValueError(name)


#: A mesh file (a tetrahedron, OBJ) the mesh cases write beside the model.
OBJ = "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
MESH_FILE = "<mesh_file>bone.obj</mesh_file>"


def _mesh_case(tmp_path: Path, extra: str, expect: str) -> Case:
    """The base model with b1's Mesh (whose file exists) given ``extra`` properties."""
    text = _build_base(tmp_path / "mesh_src.osim", mesh="bone.obj").replace(MESH_FILE, extra + MESH_FILE)
    (tmp_path / "bone.obj").write_text(OBJ)
    tag = '<Mesh name="b1_geom_1">'
    return Case(text, UnsupportedElementError, [tag, f"line {line_of(text, tag)}", expect])


def _muscle_case(tmp_path: Path, prop: str, value: str) -> Case:
    """The base model with muscle m1 whose ``prop`` is ``value``."""
    text = _build_base(tmp_path / "muscle_src.osim", muscle=True)
    old = text_between(text, '<Thelen2003Muscle name="m1">', f"<{prop}>", f"</{prop}>")
    text = text.replace(f"<{prop}>{old}</{prop}>", f"<{prop}>{value}</{prop}>", 1)
    tag = '<Thelen2003Muscle name="m1">'
    return Case(text, UnsupportedElementError, [tag, f"line {line_of(text, tag)}", prop])


def _zero_radius_wrap(base: str, tmp_path: Path) -> Case:
    text = _build_base(tmp_path / "wrap_src.osim", muscle=True).replace("<radius>0.02</radius>", "<radius>0</radius>")
    tag = '<WrapCylinder name="cyl">'
    return Case(text, UnsupportedElementError, [tag, f"line {line_of(text, tag)}", "radius", "positive"])


def _huge_spline(base: str, tmp_path: Path) -> Case:
    text = base.replace("<y>0.001 0.004 -0.002 -0.005</y>", "<y>0.001 1e300 -0.002 -0.005</y>")
    return Case(text, UnsupportedElementError,
                ['<SimmSpline name="function">', f"line {line_of(text, '<SimmSpline')}", "1e+300"])


def _huge_location(base: str, tmp_path: Path) -> Case:
    text = _build_base(tmp_path / "far_src.osim", muscle=True)
    old = text_between(text, '<PathPoint name="m1-insertion">', "<location>", "</location>")
    text = text.replace(f"<location>{old}</location>", "<location>0 1e300 0</location>")
    tag = '<PathPoint name="m1-insertion">'
    return Case(text, UnsupportedElementError, [tag, f"line {line_of(text, tag)}", "1e+300"])


def _massless(base: str, tmp_path: Path) -> Case:
    """b1 and b2 massless: OpenSim refuses the model (a terminal massless body), o2m too."""
    text = base
    for body in ("b1", "b2"):
        mass = text_between(text, f'<Body name="{body}">', "<mass>", "</mass>")
        inertia = text_between(text, f'<Body name="{body}">', "<inertia>", "</inertia>")
        text = text.replace(f"<mass>{mass}</mass>", "<mass>0</mass>", 1)
        text = text.replace(f"<inertia>{inertia}</inertia>", "<inertia>0 0 0 0 0 0</inertia>", 1)
    tag = '<Body name="b1">'
    return Case(text, UnsupportedElementError, [tag, f"line {line_of(text, tag)}", "no mass", "OpenSim"])


def _second_transform_axis(base: str, tmp_path: Path) -> Case:
    """The knee's rotation1 TransformAxis twice (a crash inside the builder once)."""
    root = etree.fromstring(base.encode())
    (ta,) = root.xpath("//CustomJoint[@name='knee']/SpatialTransform/TransformAxis[@name='rotation1']")
    ta.addnext(copy.deepcopy(ta))
    text = '<?xml version="1.0" encoding="UTF-8" ?>\n' + etree.tostring(root, encoding="unicode")
    second = etree.fromstring(text.encode()).xpath("//TransformAxis[@name='rotation1']")[1].sourceline
    return Case(text, UnsupportedElementError, ['<TransformAxis name="rotation1">', f"line {second}", "second"])


def _quadrant_word(base: str, tmp_path: Path) -> Case:
    text = _build_base(tmp_path / "quadrant_src.osim", muscle=True).replace("<quadrant>all</quadrant>",
                                                                            "<quadrant>up</quadrant>")
    tag = '<WrapCylinder name="cyl">'
    return Case(text, UnsupportedElementError, [tag, f"line {line_of(text, tag)}", "quadrant", "'up'"])


def _path_wrap_case(tmp_path: Path, prop: str, value: str) -> Case:
    """The muscle model with its PathWrap's ``prop`` (method or range) made ``value``."""
    text = _build_base(tmp_path / "pathwrap_src.osim", muscle=True)
    start = text.index("<PathWrap ")
    end = text.index(">", start) + 1
    tag = text[start:end]
    body = text[end:text.index("</PathWrap>", start)]
    new = re.sub(rf"<{prop}>.*?</{prop}>", "", body) + f"<{prop}>{value}</{prop}>"
    text = text[:end] + new + text[end + len(body):]
    return Case(text, UnsupportedElementError, [tag, f"line {line_of(text, tag)}", prop])


def _plugin_classes(base: str, tmp_path: Path) -> Case:
    """Two classes of a plugin (a body and a joint): one error names the first by line and both."""
    text = base
    for set_tag, element in (("JointSet", '<FooJoint name="x" />'), ("BodySet", '<BarBody name="y" />')):
        marker = re.search(rf"<{set_tag} name=\"[^\"]*\">\s*<objects>\s*", text)
        assert marker is not None, set_tag
        text = text[:marker.end()] + element + "\n" + text[marker.end():]
    return Case(text, UnsupportedElementError, ['<BarBody name="y">', f"line {line_of(text, '<BarBody')}",
                                                "unknown classes in this model: BarBody (1), FooJoint (1)"])


MORE_CASES = {
    "plugin-classes": _plugin_classes,
    "mesh-one-color": lambda base, tmp: _mesh_case(tmp, "<Appearance><color>0.5</color></Appearance>", "color"),
    "mesh-scale-text": lambda base, tmp: _mesh_case(tmp, "<scale_factors>a b c</scale_factors>", "scale_factors"),
    "muscle-negative-force": lambda base, tmp: _muscle_case(tmp, "max_isometric_force", "-1000"),
    "muscle-nan-fiber-length": lambda base, tmp: _muscle_case(tmp, "optimal_fiber_length", "NaN"),
    "muscle-nan-pennation": lambda base, tmp: _muscle_case(tmp, "pennation_angle_at_optimal", "nan"),
    "wrap-zero-radius": _zero_radius_wrap,
    "spline-huge-value": _huge_spline,
    "path-point-far-out": _huge_location,
    "massless-bodies": _massless,
    "second-transform-axis": _second_transform_axis,
    "wrap-quadrant-word": _quadrant_word,
    "path-wrap-method": lambda base, tmp: _path_wrap_case(tmp, "method", "o2m"),
    "path-wrap-range": lambda base, tmp: _path_wrap_case(tmp, "range", "1 o2m"),
}


def text_between(text: str, after: str, start: str, end: str) -> str:
    i = text.index(start, text.index(after)) + len(start)
    return text[i:text.index(end, i)]


CASES = ["missing-file", "truncated", "empty", "not-opensim", "unknown-joint", "ellipsoid-joint",
         "scapulothoracic-joint", "unknown-function", "bad-joint-socket", "bad-frame-socket", "mass-text",
         "inertia-text", *MORE_CASES]


def _write(case: Case, tmp_path: Path, name: str) -> Path:
    path = tmp_path / f"{name}.osim"
    if case.text is not None:
        path.write_text(case.text)
    return path


def _assert_no_output(tmp_path: Path, out: Path) -> None:
    """Nothing written: no output folder content (no .xml, no report, no mesh)."""
    if out.exists():
        assert not list(out.rglob("*.xml"))
        assert not any(out.iterdir()), list(out.iterdir())
    assert not list(tmp_path.glob(".o2m-*")), "staging folder left behind"


@pytest.mark.parametrize("name", CASES)
def test_bad_input_raises(name, base, tmp_path):
    case = _case(name, base, tmp_path)
    path = _write(case, tmp_path, name)
    out = tmp_path / "out"
    with pytest.raises(case.error) as info:
        convert(path, out, convert_options())
    msg = str(info.value)
    assert isinstance(info.value, O2MError)
    for s in case.expect:
        assert s in msg, f"{s!r} not in {msg!r}"
    _assert_no_output(tmp_path, out)


@pytest.mark.parametrize("name", list(CASES))
def test_error_names_the_file(name, base, tmp_path):
    """Every message starts with the file the user gave."""
    case = _case(name, base, tmp_path)
    path = _write(case, tmp_path, name)
    with pytest.raises(O2MError) as info:
        convert(path, tmp_path / "out", convert_options())
    assert str(info.value).startswith(str(path)), str(info.value)


@pytest.mark.parametrize("name", ["truncated", "unknown-joint", "mass-text", "missing-file"])
def test_bad_input_cli(name, base, tmp_path):
    case = _case(name, base, tmp_path)
    path = _write(case, tmp_path, name)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "o2m", "convert", str(path), "-o", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1, (proc.stdout, proc.stderr)
    assert proc.stderr.startswith("o2m: error:"), proc.stderr
    assert "Traceback" not in proc.stderr
    for s in case.expect:
        assert s in proc.stderr, f"{s!r} not in {proc.stderr!r}"
    _assert_no_output(tmp_path, out)


def test_failure_keeps_existing_output(base, tmp_path):
    """A failed conversion into a folder holding an earlier good conversion leaves it as it was."""
    good = tmp_path / "model.osim"
    good.write_text(base)
    out = tmp_path / "out"
    first = convert(good, out, convert_options())
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    good.write_text(base.replace("<mass>2</mass>", "<mass>heavy</mass>"))
    with pytest.raises(UnsupportedElementError):
        convert(good, out, convert_options())
    after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert after == before and first.xml.exists()
    assert not list(tmp_path.glob(".o2m-*"))


def test_missing_mesh_is_not_an_error(tmp_path):
    """A mesh file that cannot be found: the model converts, the report lists the mesh."""
    path = tmp_path / "meshy.osim"
    _build_base(path, mesh="no_such_bone.vtp")
    conv = convert(path, tmp_path / "out", convert_options())
    assert conv.xml.exists()
    skipped = [s for s in conv.report.skipped if s.element == "Mesh"]
    assert len(skipped) == 1 and "no_such_bone.vtp" in skipped[0].reason
    assert any("no_such_bone.vtp" in w for w in conv.report.warnings)
    assert "no_such_bone.vtp" in (tmp_path / "out" / "meshy.report.txt").read_text()
    # The CLI succeeds too.
    proc = subprocess.run([sys.executable, "-m", "o2m", "convert", str(path), "-o", str(tmp_path / "cli")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "cli" / "meshy.xml").exists()


FAST = {"fit_mechanics": False, "fit_wraps": False}


@pytest.mark.parametrize("clamped", [False, True])
def test_zero_width_range_converts(clamped, base, tmp_path):
    """A coordinate whose range has no width (knee in [0.1, 0.1]) converts, its joint the coordinate's;
    clamped and converted with ``clamped_limits``, its joint is unlimited (MuJoCo's limits need two
    ends; once a compile error), with a note."""
    path = tmp_path / "still.osim"
    rng = "<range>0.1 0.1</range>" + ("<clamped>true</clamped>" if clamped else "")
    path.write_text(base.replace("<range>-2 0.5</range>", rng))
    conv = convert(path, tmp_path / "out", convert_options(**FAST, clamped_limits=True))
    assert any(j.coordinate == "knee" and j.name == "knee" for j in conv.report.joints)
    assert any("'knee' is clamped to a range of no width" in n for n in conv.report.notes) == clamped


def test_massless_leaf_that_opensim_accepts_converts_with_a_warning(base, tmp_path):
    """b2 massless (OpenSim loads the model): converted, the report's warnings name b2."""
    mass = text_between(base, '<Body name="b2">', "<mass>", "</mass>")
    path = tmp_path / "light.osim"
    path.write_text(base.replace(f"<mass>{mass}</mass>", "<mass>0</mass>"))
    conv = convert(path, tmp_path / "out", convert_options(**FAST))
    assert any(w.startswith("Body b2:") and "no mass" in w for w in conv.report.warnings), conv.report.warnings


def _unreadable_mesh(path: Path, how: str, monkeypatch) -> None:
    if how == "corrupt":
        (path.parent / "bone.vtp").write_text("<VTKFile garbage")
    else:  # a file the user may not read (root reads every file: refuse it as the OS would)
        (path.parent / "bone.vtp").write_text("<VTKFile/>")
        real = Path.read_bytes

        def read_bytes(self):
            if self.name == "bone.vtp":
                raise PermissionError(13, "Permission denied", str(self))
            return real(self)

        monkeypatch.setattr(Path, "read_bytes", read_bytes)


@pytest.mark.parametrize("how", ["corrupt", "no-permission"])
def test_unreadable_mesh_is_skipped(how, tmp_path, monkeypatch):
    """A mesh file that exists but cannot be read is skipped, as a missing one: the report says why."""
    path = tmp_path / "meshy.osim"
    _build_base(path, mesh="bone.vtp")
    _unreadable_mesh(path, how, monkeypatch)
    conv = convert(path, tmp_path / "out", convert_options(**FAST))
    (skipped,) = [s for s in conv.report.skipped if s.element == "Mesh"]
    assert "bone.vtp" in skipped.reason and "cannot be read" in skipped.reason
    assert ("Permission denied" if how == "no-permission" else "malformed XML") in skipped.reason
    assert any("cannot be read" in w for w in conv.report.warnings)
    assert not list((tmp_path / "out" / "meshes").glob("*.stl"))


def test_a_non_finite_number_in_the_output_is_an_error(tmp_path):
    """The last check before writing: a NaN in the MJCF (which MuJoCo would load) stops the conversion."""
    xml = '<mujoco><equality><joint name="e" joint1="a" polycoef="nan inf 0 0 0"/></equality></mujoco>'
    with pytest.raises(O2MError, match=r'<joint name="e"> polycoef="nan inf 0 0 0"'):
        converter._check_finite(xml, tmp_path / "model.osim")
    converter._check_finite(xml.replace("nan inf", "0 1"), tmp_path / "model.osim")


def test_a_model_far_out_of_scale_converts_with_a_warning(base, tmp_path):
    """A number far out of scale but below the 1e10 o2m refuses (b1's centre of mass 1e8 m out)
    gives a model that diverges at its first step: the report says so."""
    com = text_between(base, '<Body name="b1">', "<mass_center>", "</mass_center>")
    path = tmp_path / "far.osim"
    path.write_text(base.replace(f"<mass_center>{com}</mass_center>", "<mass_center>0 -1e8 0</mass_center>", 1))
    conv = convert(path, tmp_path / "out", convert_options(**FAST))
    assert any("diverges in MuJoCo" in w for w in conv.report.warnings), conv.report.warnings


def test_a_negative_principal_inertia_is_raised_by_what_it_takes(base, tmp_path):
    """b2's inertia with a negative principal moment (OpenSim loads it): converted, the report giving
    the raise it took (not the 1e-12 it once said) and MuJoCo's triangle inequality kept (the
    largest moment never below the middle one: once a compile error)."""
    old = text_between(base, '<Body name="b2">', "<inertia>", "</inertia>")
    path = tmp_path / "odd.osim"
    path.write_text(base.replace(f"<inertia>{old}</inertia>", "<inertia>0 0.009 0.021 -0.001 0.0012 0</inertia>"))
    conv = convert(path, tmp_path / "out", convert_options(**FAST))
    raised = [a for a in conv.report.approximations if a.name == "b2" and "raised" in a.what]
    assert len(raised) == 1 and raised[0].max_error == pytest.approx(1.7697e-4, rel=1e-3), raised


@pytest.mark.parametrize("prop, value, expect", [("min_control", "-0.01", "makes OpenSim refuse the model"),
                                                 ("optimal_fiber_length", "1e-300", "cannot load")])
def test_muscle_fit_refusals_name_the_muscle(prop, value, expect, tmp_path):
    """OpenSim refusing the model in the muscle fit (once 'OpenSim could not load the model' without
    element or line), and a muscle fitted to parameters MuJoCo cannot load (an optimal fiber length
    of 1e-300 m: vmax 2e-299; the written model once did not load): errors naming the muscle."""
    case = _muscle_case(tmp_path, prop, value)
    path = _write(case, tmp_path, "fit")
    out = tmp_path / "out"
    with pytest.raises(UnsupportedElementError) as info:
        convert(path, out, convert_options(fit_wraps=False))
    msg = str(info.value)
    assert all(s in msg for s in case.expect) and expect in msg and msg.startswith(str(path)), msg
    _assert_no_output(tmp_path, out)


def test_a_muscle_opensim_cannot_balance_converts_with_a_warning(tmp_path):
    """A muscle on a slider with OpenSim's default ±10 m range, its path of length 0 at rest (as
    a public test model has it): OpenSim finds its static equilibrium at a few of the lengths
    only, so the fitted MuJoCo muscle is no model of OpenSim's: the conversion warns, naming it."""
    m, b = _slider(tmp_path, 10.0)
    muscle = osim.DeGrooteFregly2016Muscle()
    muscle.setName("hanging")
    muscle.addNewPathPoint("origin", m.getGround(), osim.Vec3(0))
    muscle.addNewPathPoint("insertion", b, osim.Vec3(0))
    muscle.set_optimal_fiber_length(0.2)
    muscle.set_tendon_slack_length(0.01)
    m.addForce(muscle)
    path = tmp_path / "hanging.osim"
    m.finalizeConnections()
    m.printToXML(str(path))
    conv = convert(path, tmp_path / "out", convert_options(fit_wraps=False))
    warned = [w for w in conv.report.warnings if "hanging" in w]
    assert len(warned) == 1 and "lengths fitted" in warned[0], conv.report.warnings


def test_a_wrap_object_no_path_uses_is_a_skip(tmp_path):
    """A wrap object that no path lists changes nothing; the report says it was left out."""
    m, _ = _slider(tmp_path, 0.05)
    sphere = osim.WrapSphere()
    sphere.setName("unused")
    sphere.set_radius(0.02)
    m.updGround().addWrapObject(sphere)
    path = tmp_path / "unused.osim"
    m.finalizeConnections()
    m.printToXML(str(path))
    conv = convert(path, tmp_path / "out", convert_options(fit_wraps=False))
    assert [(s.element, s.name) for s in conv.report.skipped] == [("WrapSphere", "unused")], conv.report.skipped
    assert "nothing changes" in conv.report.skipped[0].reason


def _slider(tmp_path, half_range: float):
    from tests.helpers import slider_model

    m, b = slider_model(tmp_path.name)
    m.updJointSet().get(0).upd_coordinates(0).setRangeMin(-half_range)
    m.updJointSet().get(0).upd_coordinates(0).setRangeMax(half_range)
    return m, b
