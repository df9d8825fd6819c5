"""Tests of o2m.convert.geometry: mesh file lookup and OpenSim analytic geometry."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from lxml import etree

from o2m.convert.geometry import (
    GeomSpec,
    analytic_geom,
    find_geometry_file,
    geometry_appearance,
    geometry_scale_factors,
    geometry_search_dirs,
)
from o2m.errors import UnsupportedElementError

# --------------------------------------------------------------------------------------------
# Locating mesh files
# --------------------------------------------------------------------------------------------


def test_find_geometry_file_search_order(tmp_path):
    model = tmp_path / "model" / "arm.osim"
    (tmp_path / "model" / "Geometry").mkdir(parents=True)
    extra1, extra2 = tmp_path / "extra1", tmp_path / "extra2"
    extra1.mkdir()
    extra2.mkdir()
    model.write_text("<OpenSimDocument/>")
    dirs = geometry_search_dirs(model, [extra1, extra2])
    assert dirs == [model.parent.resolve(), model.parent.resolve() / "Geometry", extra1, extra2]

    for d in (extra2, extra1, model.parent / "Geometry", model.parent):
        (d / "bone.vtp").write_text("x")
        assert find_geometry_file("bone.vtp", dirs).resolve() == (d / "bone.vtp").resolve()
    (extra2 / "only2.vtp").write_text("x")
    assert find_geometry_file("only2.vtp", dirs) == extra2 / "only2.vtp"
    assert find_geometry_file("absent.vtp", dirs) is None
    assert find_geometry_file("", dirs) is None
    (model.parent / "Geometry" / "sub").mkdir()
    (model.parent / "Geometry" / "sub" / "s.vtp").write_text("x")
    assert find_geometry_file("sub\\s.vtp", dirs) == model.parent.resolve() / "Geometry" / "sub" / "s.vtp"
    absolute = extra1 / "bone.vtp"
    assert find_geometry_file(str(absolute), []) == absolute
    assert find_geometry_file(str(tmp_path / "gone.vtp"), dirs) is None


# --------------------------------------------------------------------------------------------
# Analytic geometry
# --------------------------------------------------------------------------------------------


def _el(xml: str) -> etree._Element:
    return etree.fromstring(xml)


def _rotate(quat: np.ndarray, v: np.ndarray) -> np.ndarray:
    out = np.zeros(3)
    mujoco.mju_rotVecQuat(out, np.asarray(v, float), np.asarray(quat, float))
    return out


def test_analytic_geometry_from_opensim_api(tmp_path):
    """Property names and defaults as OpenSim 4.6 itself writes them."""
    osim = pytest.importorskip("opensim")
    model = osim.Model()
    body = osim.Body("b", 1.0, osim.Vec3(0), osim.Inertia(1))
    model.addBody(body)
    cyl = osim.Cylinder(0.1, 0.2)
    cyl.setName("cyl")
    cyl.setColor(osim.Vec3(0.1, 0.2, 0.3))
    cyl.setOpacity(0.5)
    geoms = [osim.Sphere(0.1), cyl, osim.Brick(osim.Vec3(0.1, 0.2, 0.3)), osim.Ellipsoid(0.1, 0.2, 0.3),
             osim.Cone(osim.Vec3(0), osim.UnitVec3(0, 1, 0), 0.4, 0.5), osim.FrameGeometry(0.2), osim.Arrow(),
             osim.LineGeometry(), osim.Torus()]
    for g in geoms:
        body.attachGeometry(g)
    model.finalizeConnections()
    model.printToXML(str(tmp_path / "g.osim"))
    root = etree.parse(str(tmp_path / "g.osim")).getroot()
    attached = root.find(".//Body[@name='b']/attached_geometry")
    skipped: list[str] = []
    specs = {el.tag: analytic_geom(el, skipped) for el in attached}
    assert specs["Sphere"].type == "sphere" and np.allclose(specs["Sphere"].size, [0.1, 0, 0])
    c = specs["Cylinder"]
    assert c.type == "cylinder" and np.allclose(c.size, [0.1, 0.2, 0]) and c.name == "cyl"
    np.testing.assert_allclose(c.rgba, [0.1, 0.2, 0.3, 0.5])
    np.testing.assert_allclose(np.abs(_rotate(c.quat, [0, 0, 1])), [0, 1, 0], atol=1e-12)
    assert specs["Brick"].type == "box" and np.allclose(specs["Brick"].size, [0.1, 0.2, 0.3])
    assert specs["Ellipsoid"].type == "ellipsoid" and np.allclose(specs["Ellipsoid"].size, [0.1, 0.2, 0.3])
    for tag in ("Cone", "FrameGeometry", "Arrow", "LineGeometry", "Torus"):
        assert specs[tag] is None
        assert any(s.startswith(f"<{tag}") for s in skipped), skipped
    assert all(s.frame == ".." for s in specs.values() if s is not None)


def test_analytic_geometry_hand_written():
    s = analytic_geom(_el("<Sphere name='s'><radius>0.05</radius></Sphere>"))
    assert isinstance(s, GeomSpec) and s.type == "sphere" and s.name == "s" and s.rgba is None
    np.testing.assert_array_equal(s.pos, [0, 0, 0])
    np.testing.assert_array_equal(s.quat, [1, 0, 0, 0])
    assert s.visible
    # Defaults of OpenSim 4.6 when the size property is omitted.
    assert np.allclose(analytic_geom(_el("<Sphere/>")).size, [1, 0, 0])
    assert np.allclose(analytic_geom(_el("<Cylinder/>")).size, [0.5, 0.5, 0])
    assert np.allclose(analytic_geom(_el("<Brick/>")).size, [0.1, 0.2, 0.3])
    assert np.allclose(analytic_geom(_el("<Ellipsoid/>")).size, [0.5, 1, 2])
    # scale_factors, as OpenSim applies them when drawing.
    e = analytic_geom(_el("<Sphere><scale_factors>1 2 3</scale_factors><radius>0.1</radius></Sphere>"))
    assert e.type == "ellipsoid" and np.allclose(e.size, [0.1, 0.2, 0.3])
    e = analytic_geom(_el("<Sphere><scale_factors>2 2 2</scale_factors><radius>0.1</radius></Sphere>"))
    assert e.type == "sphere" and np.allclose(e.size, [0.2, 0, 0])
    c = analytic_geom(_el("<Cylinder><scale_factors>2 3 2</scale_factors><radius>0.1</radius>"
                          "<half_height>0.2</half_height></Cylinder>"))
    assert np.allclose(c.size, [0.2, 0.6, 0])
    b = analytic_geom(_el("<Brick><scale_factors>-1 2 1</scale_factors>"
                          "<half_lengths>0.1 0.1 0.1</half_lengths></Brick>"))
    assert np.allclose(b.size, [0.1, 0.2, 0.1])
    skipped: list[str] = []
    elliptic = _el("<Cylinder name='e'><scale_factors>1 1 2</scale_factors></Cylinder>")
    assert analytic_geom(elliptic, skipped) is None
    assert "elliptic" in skipped[0] and 'name="e"' in skipped[0]
    assert analytic_geom(_el("<Sphere><radius>0</radius></Sphere>"), skipped) is None
    assert analytic_geom(_el("<Line/>"), skipped) is None
    assert analytic_geom(_el("<Cone><base_radius>1</base_radius></Cone>"), skipped) is None
    assert "cone" in skipped[-1]
    assert len(skipped) == 4
    assert analytic_geom(_el("<Mesh><mesh_file>a.vtp</mesh_file></Mesh>")) is None  # no list: fine
    assert analytic_geom(etree.Comment("a comment inside attached_geometry")) is None


def test_appearance_and_scale_helpers():
    el = _el("<Brick><Appearance><visible>false</visible><color>1 0.5 0</color></Appearance></Brick>")
    rgba, visible = geometry_appearance(el)
    np.testing.assert_allclose(rgba, [1, 0.5, 0, 1])
    assert not visible and not analytic_geom(el).visible
    el = _el("<Brick><Appearance><opacity>0.25</opacity></Appearance></Brick>")
    rgba, visible = geometry_appearance(el)
    np.testing.assert_allclose(rgba, [1, 1, 1, 0.25])
    assert geometry_appearance(_el("<Brick/>")) == (None, True)
    np.testing.assert_allclose(geometry_scale_factors(_el("<Mesh/>")), [1, 1, 1])
    np.testing.assert_allclose(geometry_scale_factors(_el("<FrameGeometry/>")), [0.2, 0.2, 0.2])


def test_analytic_geometry_in_mujoco():
    specs = [analytic_geom(_el(x)) for x in (
        "<Sphere><radius>0.1</radius></Sphere>",
        "<Cylinder><radius>0.1</radius><half_height>0.3</half_height></Cylinder>",
        "<Brick><half_lengths>0.1 0.2 0.3</half_lengths></Brick>",
        "<Ellipsoid><radii>0.1 0.2 0.3</radii></Ellipsoid>")]
    spec = mujoco.MjSpec()
    for g in specs:
        spec.worldbody.add_geom(type=getattr(mujoco.mjtGeom, f"mjGEOM_{g.type.upper()}"),
                                size=g.size, pos=g.pos, quat=g.quat)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    # The cylinder's long axis lies along the OpenSim frame's y.
    axis = data.geom_xmat[1].reshape(3, 3)[:, 2]
    np.testing.assert_allclose(np.abs(axis), [0, 1, 0], atol=1e-12)


def test_unknown_geometry_tag_raises():
    root = etree.fromstring(b"<attached_geometry>\n\n<Teapot name='tea'/></attached_geometry>")
    with pytest.raises(UnsupportedElementError) as info:
        analytic_geom(root[0])
    err = info.value
    assert err.element == "Teapot" and err.name == "tea" and err.line == 3
    with pytest.raises(UnsupportedElementError, match="radius"):
        analytic_geom(_el("<Sphere><radius>big</radius></Sphere>"))
    with pytest.raises(UnsupportedElementError, match="half_lengths"):
        analytic_geom(_el("<Brick><half_lengths>1 2</half_lengths></Brick>"))


def test_sizes_out_of_mujocos_scale():
    """A size below 1e-15 m (which MuJoCo's XML writer leaves out, so the written model did not load)
    is skipped with the reason; a number beyond 1e10 is an error naming the element."""
    why: list[str] = []
    assert analytic_geom(_el('<Sphere name="dot"><radius>1e-300</radius></Sphere>'), why) is None
    assert "below 1e-15" in why[0] and "dot" in why[0]
    with pytest.raises(UnsupportedElementError, match="beyond 1e"):
        analytic_geom(_el('<Brick name="huge"><half_lengths>0.02 1e300 0.04</half_lengths></Brick>'))
    with pytest.raises(UnsupportedElementError, match=r"<Appearance/color> holds 1e\+300"):
        geometry_appearance(_el("<Sphere><Appearance><color>1 1 1e300</color></Appearance></Sphere>"))
