"""Tests of o2m.osim.meshes: mesh reading (.vtp in every encoding, .stl, .obj) and STL export
loaded by MuJoCo."""

from __future__ import annotations

import base64
import fnmatch
import lzma
import struct
import zlib
from pathlib import Path, PurePosixPath

import mujoco
import numpy as np
import pytest
from lxml import etree

from o2m import models
from o2m.convert.geometry import MUJOCO_VISUAL_MESH_ATTRS
from o2m.errors import ModelFileError
from o2m.osim.meshes import Mesh, read_mesh, read_obj, read_stl, read_vtp, write_stl
from tests.helpers import require_models

#: The registry folders of real OpenSim geometry the reader tests go through.
GEOMETRY_DIRS = ("mobl-arms/Geometry/", "opensim-models/Geometry/")

# --------------------------------------------------------------------------------------------
# A small VTK XML PolyData writer covering every encoding read_vtp must understand.
# --------------------------------------------------------------------------------------------

_NP = {"Float32": "f4", "Float64": "f8", "Int32": "i4", "Int64": "i8", "UInt32": "u4", "UInt64": "u8"}


def _stream(values: np.ndarray, vtype: str, *, endian: str, header: str, compressor: str | None,
            block: int) -> tuple[bytes, bytes]:
    """(header bytes, data bytes) of one binary DataArray, laid out as VTK writes them."""
    data = np.asarray(values).astype(endian + _NP[vtype]).tobytes()
    hdt = endian + ("u4" if header == "UInt32" else "u8")
    if compressor is None:
        return np.array([len(data)], hdt).tobytes(), data
    comp = zlib.compress if compressor == "vtkZLibDataCompressor" else lzma.compress
    blocks = [data[i:i + block] for i in range(0, len(data), block)]  # none for empty data
    packed = [comp(b) for b in blocks]
    head = [len(blocks), block, len(data) % block, *(len(p) for p in packed)]
    return np.array(head, hdt).tobytes(), b"".join(packed)


def make_vtp(points: np.ndarray, polys: list[list[int]] | None = None,
             strips: list[list[int]] | None = None, *, fmt: str = "ascii", compressor: str | None = None,
             header: str = "UInt32", encoding: str = "raw", big_endian: bool = False,
             float_type: str = "Float32", int_type: str = "Int32", b64_joined: bool = False,
             block: int = 40, extra_cells: bool = True, leading_zero: bool = False) -> bytes:
    """Bytes of a .vtp holding ``points`` (n, 3) and the given polygons and strips.

    fmt is "ascii", "binary" or "appended" (``encoding`` raw or base64). ``b64_joined`` encodes
    header and data as one base64 stream instead of separately. ``extra_cells`` adds Verts,
    Lines and point normals that the reader must ignore.
    """
    endian = ">" if big_endian else "<"
    appended: list[bytes] = []
    app_len = 0

    def data_array(values: np.ndarray, vtype: str, name: str, ncomp: int = 1) -> str:
        nonlocal app_len
        attrs = f'type="{vtype}" Name="{name}" NumberOfComponents="{ncomp}"'
        flat = np.asarray(values).reshape(-1)
        if fmt == "ascii":
            txt = " ".join(repr(float(v)) if vtype.startswith("Float") else str(int(v)) for v in flat)
            return f'<DataArray {attrs} format="ascii">\n{txt}\n</DataArray>'
        head, data = _stream(flat, vtype, endian=endian, header=header, compressor=compressor, block=block)
        if fmt == "binary" or encoding == "base64":
            if b64_joined:
                blob = base64.b64encode(head + data)
            else:
                blob = base64.b64encode(head) + base64.b64encode(data)
        else:
            blob = head + data
        if fmt == "binary":
            return f'<DataArray {attrs} format="binary">\n{blob.decode()}\n</DataArray>'
        offset = app_len
        appended.append(blob)
        app_len += len(blob)
        return f'<DataArray {attrs} format="appended" offset="{offset}"/>'

    def cells(tag: str, cl: list[list[int]] | None) -> str:
        cl = cl or []
        conn = np.array([i for c in cl for i in c], dtype=np.int64)
        offs = np.cumsum([len(c) for c in cl]).astype(np.int64)
        if leading_zero:
            offs = np.concatenate([[0], offs])
        return (f"<{tag}>{data_array(conn, int_type, 'connectivity')}"
                f"{data_array(offs, int_type, 'offsets')}</{tag}>")

    pts = np.asarray(points, dtype=float)
    body = []
    if extra_cells:
        normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
        normals_xml = data_array(normals, float_type, "Normals", 3)
        body.append(f'<PointData Normals="Normals">{normals_xml}</PointData>')
    body.append(f"<Points>{data_array(pts, float_type, 'Points', 3)}</Points>")
    nverts = nlines = 0
    if extra_cells and len(pts) >= 2:
        body.append(cells("Verts", [[0]]))
        body.append(cells("Lines", [[0, 1]]))
        nverts = nlines = 1
    body.append(cells("Strips", strips))
    body.append(cells("Polys", polys))
    piece = (f'<Piece NumberOfPoints="{len(pts)}" NumberOfVerts="{nverts}" NumberOfLines="{nlines}" '
             f'NumberOfStrips="{len(strips or [])}" NumberOfPolys="{len(polys or [])}">'
             + "\n".join(body) + "</Piece>")
    attrs = f'type="PolyData" version="1.0" byte_order="{"BigEndian" if big_endian else "LittleEndian"}"'
    attrs += f' header_type="{header}"'
    if compressor:
        attrs += f' compressor="{compressor}"'
    xml = f'<?xml version="1.0"?>\n<VTKFile {attrs}>\n<PolyData>\n{piece}\n</PolyData>\n'.encode()
    if fmt == "appended":
        xml += f'<AppendedData encoding="{encoding}">\n_'.encode() + b"".join(appended)
        xml += b"\n</AppendedData>\n"
    return xml + b"</VTKFile>\n"


# A unit-ish cube (quads) with values exact in float32, plus its fan triangulation.
CUBE_PTS = np.array([[x, y, z] for z in (0.0, 0.25) for y in (0.0, 0.5) for x in (-0.125, 0.375)])
CUBE_QUADS = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
CUBE_TRIS = np.array([[q[0], q[k], q[k + 1]] for q in CUBE_QUADS for k in (1, 2)])

ENCODINGS = {
    "ascii": {},
    "binary": {"fmt": "binary"},
    "binary_joined_b64": {"fmt": "binary", "b64_joined": True},
    "binary_zlib": {"fmt": "binary", "compressor": "vtkZLibDataCompressor"},
    "binary_zlib_joined_b64": {"fmt": "binary", "compressor": "vtkZLibDataCompressor", "b64_joined": True},
    "binary_uint64": {"fmt": "binary", "header": "UInt64"},
    "binary_zlib_uint64": {"fmt": "binary", "compressor": "vtkZLibDataCompressor", "header": "UInt64"},
    "binary_lzma": {"fmt": "binary", "compressor": "vtkLZMADataCompressor"},
    "binary_bigendian_float64_int64": {"fmt": "binary", "big_endian": True, "float_type": "Float64",
                                       "int_type": "Int64"},
    "appended_raw": {"fmt": "appended"},
    "appended_raw_zlib": {"fmt": "appended", "compressor": "vtkZLibDataCompressor"},
    "appended_raw_uint64": {"fmt": "appended", "header": "UInt64"},
    "appended_raw_zlib_uint64": {"fmt": "appended", "compressor": "vtkZLibDataCompressor",
                                 "header": "UInt64"},
    "appended_base64": {"fmt": "appended", "encoding": "base64"},
    "appended_base64_joined": {"fmt": "appended", "encoding": "base64", "b64_joined": True},
    "appended_base64_zlib": {"fmt": "appended", "encoding": "base64", "compressor": "vtkZLibDataCompressor"},
    "appended_base64_uint64": {"fmt": "appended", "encoding": "base64", "header": "UInt64"},
    "ascii_leading_zero_offsets": {"leading_zero": True},
}


def _write(tmp_path: Path, data: bytes, name: str = "m.vtp") -> Path:
    p = tmp_path / name
    p.write_bytes(data)
    return p


@pytest.mark.parametrize("enc", list(ENCODINGS))
def test_vtp_encodings_roundtrip(tmp_path, enc):
    p = _write(tmp_path, make_vtp(CUBE_PTS, CUBE_QUADS, **ENCODINGS[enc]))
    mesh = read_vtp(p)
    assert mesh.vertices.dtype == np.float64 and mesh.vertices.shape == (8, 3)
    assert mesh.faces.dtype == np.int32 and mesh.faces.shape == (12, 3)
    np.testing.assert_array_equal(mesh.vertices, CUBE_PTS)
    np.testing.assert_array_equal(mesh.faces, CUBE_TRIS)


def test_appended_raw_holds_bytes_that_are_not_xml(tmp_path):
    # Coordinates whose float32 bytes contain '<', '&' and NUL: lxml must never see them.
    pts = CUBE_PTS.copy()
    pts[0] = np.frombuffer(b"<&\x00\x3f" + b"\x00\x00<\x3e" + b"&&\x00\x3f", "<f4")
    data = make_vtp(pts, CUBE_QUADS, fmt="appended")
    assert b"\x00" in data and b"_" in data
    mesh = read_vtp(_write(tmp_path, data))
    np.testing.assert_array_equal(mesh.vertices, pts.astype(np.float32))


def test_multiblock_compression_is_used():
    """The helper really splits compressed data into several blocks (block=40 bytes)."""
    data = make_vtp(CUBE_PTS, CUBE_QUADS, fmt="binary", compressor="vtkZLibDataCompressor",
                    extra_cells=False)
    root = etree.fromstring(data)
    text = root.find("PolyData/Piece/Points/DataArray").text.strip()
    nblocks = struct.unpack("<I", base64.b64decode(text[:8])[:4])[0]
    assert nblocks == 3  # 8 points * 3 * 4 bytes = 96 bytes -> blocks of 40, 40, 16


def test_polygons_of_any_size_fan_triangulated(tmp_path):
    ang = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    pts = np.c_[np.cos(ang), np.sin(ang), np.zeros(6)]
    polys = [[0, 1, 2, 3, 4, 5], [0, 2, 4], [1, 3]]  # hexagon, triangle, a 2-gon giving nothing
    for fmt in ("ascii", "binary"):
        mesh = read_vtp(_write(tmp_path, make_vtp(pts, polys, fmt=fmt, float_type="Float64")))
        np.testing.assert_array_equal(
            mesh.faces, [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5], [0, 2, 4]])


def test_strips_alternate_winding(tmp_path):
    # A zig-zag strip in the z=0 plane: every triangle must face +z.
    pts = np.array([[0, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [2, 0, 0], [2, 1, 0]], dtype=float)
    mesh = read_vtp(_write(tmp_path, make_vtp(pts, None, [[1, 0, 3, 2, 5, 4]], fmt="appended")))
    np.testing.assert_array_equal(mesh.faces, [[1, 0, 3], [3, 0, 2], [3, 2, 5], [5, 2, 4]])
    v = mesh.vertices[mesh.faces]
    normals = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    assert np.all(normals[:, 2] > 0)


def test_strips_and_polys_together_and_several_pieces(tmp_path):
    one = make_vtp(CUBE_PTS, CUBE_QUADS[:2], [[0, 1, 2, 3]], extra_cells=False)
    root = etree.fromstring(one)
    polydata = root.find("PolyData")
    polydata.append(etree.fromstring(etree.tostring(polydata.find("Piece"))))
    mesh = read_vtp(_write(tmp_path, etree.tostring(root)))
    assert mesh.vertices.shape == (16, 3)
    first = [[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 2], [2, 1, 3]]
    np.testing.assert_array_equal(mesh.faces, np.r_[first, np.array(first) + 8])


def test_lines_only_vtp_gives_empty_mesh(tmp_path):
    mesh = read_vtp(_write(tmp_path, make_vtp(CUBE_PTS, None)))
    assert mesh.faces.shape == (0, 3) and mesh.vertices.shape == (8, 3)
    with pytest.raises(ValueError, match="no triangle"):
        write_stl(tmp_path / "empty.stl", mesh)


def _real_files(pattern: str) -> list[Path]:
    """The real geometry files of the registry whose names match ``pattern``, fetched (cached)."""
    require_models()
    paths = [p for p in models.get_registry().paths if p.startswith(GEOMETRY_DIRS)]
    return sorted((models.fetch(p) for p in paths if fnmatch.fnmatch(PurePosixPath(p).name, pattern)),
                  key=lambda f: f.name)


def test_real_vtp_sample_matches_declared_counts():
    names = ["humerus.vtp", "superquadric.vtp", "ConePendulum.vtp", "r_pelvis.vtp"]
    checked = 0
    for f in _real_files("*.vtp"):
        if f.name not in names:
            continue
        piece = etree.parse(str(f)).find("PolyData/Piece")
        mesh = read_vtp(f)
        assert len(mesh.vertices) == int(piece.get("NumberOfPoints"))
        assert mesh.faces.min() >= 0 and mesh.faces.max() < len(mesh.vertices)
        if int(piece.get("NumberOfStrips")) == 0:
            conn = np.array(piece.find("Polys/DataArray[@Name='connectivity']").text.split(), int)
            offs = np.array(piece.find("Polys/DataArray[@Name='offsets']").text.split(), int)
            assert len(mesh.faces) == (np.diff(np.r_[0, offs]) - 2).sum()
            assert conn[0] == mesh.faces[0, 0]
        else:
            assert len(mesh.faces) > 0
        checked += 1
    assert checked >= 2


# --------------------------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------------------------


def _bad(tmp_path: Path, data: bytes, match: str) -> None:
    p = _write(tmp_path, data, "bad.vtp")
    with pytest.raises(ModelFileError, match=match) as info:
        read_vtp(p)
    assert str(p) in str(info.value)


def test_missing_file(tmp_path):
    p = tmp_path / "nope.vtp"
    for reader in (read_vtp, read_stl, read_obj, read_mesh):
        with pytest.raises(ModelFileError, match="not found") as info:
            reader(p)
        assert str(p) in str(info.value)


def test_malformed_xml(tmp_path):
    _bad(tmp_path, make_vtp(CUBE_PTS, CUBE_QUADS)[:-30], "malformed XML")
    _bad(tmp_path, b"<VTKFile><PolyData><Piece></VTKFile>", "malformed XML")
    _bad(tmp_path, b"<NotVTK/>", "expected <VTKFile>")
    _bad(tmp_path, b'<VTKFile type="UnstructuredGrid"/>', "PolyData")


@pytest.mark.parametrize("kw", [{}, {"compressor": "vtkZLibDataCompressor"}], ids=["plain", "zlib"])
@pytest.mark.parametrize("cut", [1, 4, 12])
def test_truncated_base64(tmp_path, kw, cut):
    data = make_vtp(CUBE_PTS, CUBE_QUADS, fmt="binary", extra_cells=False, **kw)
    root = etree.fromstring(data)
    arr = root.find("PolyData/Piece/Points/DataArray")
    arr.text = arr.text.strip()[:-cut]
    _bad(tmp_path, etree.tostring(root), "Points.*(truncated|base64|decompress)")


def test_truncated_appended_raw(tmp_path):
    data = make_vtp(CUBE_PTS, CUBE_QUADS, fmt="appended", extra_cells=False)
    cut = data.index(b"\n</AppendedData>") - 20
    _bad(tmp_path, data[:cut], "truncated")


def test_inconsistent_arrays(tmp_path):
    good = make_vtp(CUBE_PTS, CUBE_QUADS, extra_cells=False).decode()
    _bad(tmp_path, good.replace('NumberOfPoints="8"', 'NumberOfPoints="9"').encode(), "Points")
    _bad(tmp_path, good.replace('NumberOfPolys="6"', 'NumberOfPolys="5"').encode(), "offsets")
    bad_index = make_vtp(CUBE_PTS, [[0, 1, 8]], extra_cells=False)
    _bad(tmp_path, bad_index, "out of range")
    bad_offsets = good.replace(">\n4 8 12 16 20 24\n<", ">\n4 8 12 16 20 25\n<")
    assert bad_offsets != good
    _bad(tmp_path, bad_offsets.encode(), "offsets")
    _bad(tmp_path, good.replace('format="ascii"', 'format="weird"', 1).encode(), "unknown format")
    _bad(tmp_path, good.replace('type="Float32"', 'type="Float128"', 1).encode(), "unknown type")
    _bad(tmp_path, good.replace(">\n-0.125 0.0 0.0", ">\n-0.125 zero 0.0", 1).encode(), "bad ASCII")
    comp = make_vtp(CUBE_PTS, CUBE_QUADS, fmt="binary", compressor="vtkZLibDataCompressor").decode()
    _bad(tmp_path, comp.replace("vtkZLibDataCompressor", "vtkLZ4DataCompressor").encode(), "compressor")
    app = make_vtp(CUBE_PTS, CUBE_QUADS, fmt="appended")
    _bad(tmp_path, app.replace(b'encoding="raw"', b'encoding="zip"'), "encoding")
    _bad(tmp_path, app[:app.index(b"<AppendedData")] + b"</VTKFile>", "no <AppendedData>")


def test_bad_stl_and_obj(tmp_path):
    p = tmp_path / "bad.stl"
    p.write_bytes(b"\x00" * 100)
    with pytest.raises(ModelFileError, match="bad.stl"):
        read_stl(p)
    q = tmp_path / "bad.obj"
    q.write_text("v 0 0 0\nv 1 0 0\nf 1 2 3\n")
    with pytest.raises(ModelFileError, match=r"bad.obj: line 3"):
        read_obj(q)
    with pytest.raises(ModelFileError, match="unsupported mesh file type"):
        read_mesh(tmp_path / "x.ply")


# --------------------------------------------------------------------------------------------
# STL / OBJ reading and STL writing
# --------------------------------------------------------------------------------------------


def _canonical(mesh: Mesh) -> np.ndarray:
    """Sorted (m, 9) array of triangle corner coordinates, each triangle rotated so that its
    smallest corner comes first (winding kept): compares meshes independent of vertex order."""
    tri = mesh.vertices[mesh.faces]
    out = []
    for t in tri:
        k = min(range(3), key=lambda i: tuple(t[i]))
        out.append(np.roll(t, -k, axis=0).reshape(9))
    out = np.array(out)
    return out[np.lexsort(out.T[::-1])]


def _outward(mesh: Mesh) -> bool:
    """True when every triangle of a convex mesh faces away from the vertex centroid."""
    v = mesh.vertices[mesh.faces]
    normals = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return bool(np.all(np.einsum("ij,ij->i", normals, v.mean(axis=1) - mesh.vertices.mean(axis=0)) > 0))


def test_write_stl_roundtrip_scale_and_degenerate(tmp_path):
    # Extra vertex 8 lies on the edge 0-1: (0, 8, 1) is collinear, (0, 0, 1) repeats an index.
    pts = np.r_[CUBE_PTS, [[0.125, 0.0, 0.0]]]
    mesh = Mesh(pts, np.r_[CUBE_TRIS, [[0, 0, 1], [0, 8, 1]]])
    scale = (2.0, 0.5, 4.0)
    assert write_stl(tmp_path / "c.stl", mesh, scale) == 12
    data = (tmp_path / "c.stl").read_bytes()
    assert len(data) == 84 + 50 * 12
    back = read_stl(tmp_path / "c.stl")
    np.testing.assert_allclose(_canonical(back), _canonical(Mesh(CUBE_PTS * scale, CUBE_TRIS)))
    rec = np.frombuffer(data[84:], np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]))
    np.testing.assert_allclose(np.linalg.norm(rec["n"], axis=1), 1.0, atol=1e-6)
    assert _outward(back)


def test_write_stl_mirror_scale_keeps_outward_normals(tmp_path):
    assert _outward(Mesh(CUBE_PTS, CUBE_TRIS))
    write_stl(tmp_path / "m.stl", Mesh(CUBE_PTS, CUBE_TRIS), (-1.0, 1.0, 1.0))
    back = read_stl(tmp_path / "m.stl")
    assert _outward(back)
    np.testing.assert_allclose(back.vertices.min(axis=0), [-0.375, 0, 0])


def test_read_ascii_stl(tmp_path):
    p = tmp_path / "a.stl"
    p.write_text("solid test\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n"
                 "   vertex 0 1 0\n  endloop\n endfacet\n facet normal 0 0 1\n  outer loop\n"
                 "   vertex 1 0 0\n   vertex 1 1 0\n   vertex 0 1 0\n  endloop\n endfacet\nendsolid test\n")
    mesh = read_stl(p)
    assert mesh.vertices.shape == (4, 3) and mesh.faces.shape == (2, 3)
    np.testing.assert_array_equal(mesh.vertices[mesh.faces[0]], [[0, 0, 0], [1, 0, 0], [0, 1, 0]])


def test_read_binary_stl_with_solid_header(tmp_path):
    # Binary STLs may start with "solid" too (the size decides).
    write_stl(tmp_path / "b.stl", Mesh(CUBE_PTS, CUBE_TRIS))
    data = bytearray((tmp_path / "b.stl").read_bytes())
    data[:10] = b"solid junk"
    (tmp_path / "b.stl").write_bytes(bytes(data))
    mesh = read_mesh(tmp_path / "b.stl")
    np.testing.assert_allclose(_canonical(mesh), _canonical(Mesh(CUBE_PTS, CUBE_TRIS)))


def test_read_obj(tmp_path):
    p = tmp_path / "q.obj"
    p.write_text("# quad and pentagon\nvn 0 0 1\nv 0 0 0\nv 1 0 0\nv 1 1 0 1.0\nv 0 1 0\nv -1 0.5 0\n"
                 "vt 0 0\ng grp\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -5//1 -1//1 -2//1\n"
                 "l 1 2\nf 1 2 3 4 5\n")
    mesh = read_obj(p)
    assert mesh.vertices.shape == (5, 3)
    np.testing.assert_array_equal(
        mesh.faces, [[0, 1, 2], [0, 2, 3], [0, 4, 3], [0, 1, 2], [0, 2, 3], [0, 3, 4]])


def test_real_obj_and_stl():
    for f in _real_files("*.obj") + _real_files("*.stl"):
        mesh = read_mesh(f)
        assert len(mesh.faces) > 0 and mesh.faces.max() < len(mesh.vertices), f


# --------------------------------------------------------------------------------------------
# MuJoCo loading
# --------------------------------------------------------------------------------------------


def _attrs(kind: str) -> str:
    return " ".join(f'{k}="{v}"' for k, v in MUJOCO_VISUAL_MESH_ATTRS[kind].items())


def _mj_model(meshdir: Path, files: list[str]) -> mujoco.MjModel:
    assets = "".join(f'<mesh name="m{i}" file="{f}" {_attrs("mesh")}/>' for i, f in enumerate(files))
    geoms = "".join(f'<geom type="mesh" mesh="m{i}" {_attrs("geom")}/>' for i in range(len(files)))
    xml = (f'<mujoco><compiler meshdir="{meshdir}"/><asset>{assets}</asset><worldbody>'
           f'<body><freejoint/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>{geoms}</body>'
           "</worldbody></mujoco>")
    return mujoco.MjModel.from_xml_string(xml)


def test_mujoco_loads_scaled_stl_from_xml(tmp_path):
    mesh = read_vtp(_write(tmp_path, make_vtp(CUBE_PTS, CUBE_QUADS, fmt="binary")))
    scale = np.array([2.0, 3.0, 0.5])
    write_stl(tmp_path / "cube.stl", mesh, scale)
    model = _mj_model(tmp_path, ["cube.stl"])
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    vert = model.mesh_vert[: model.mesh_vertnum[0]]
    world = data.geom_xpos[0] + vert @ data.geom_xmat[0].reshape(3, 3).T
    np.testing.assert_allclose(world.min(axis=0), CUBE_PTS.min(axis=0) * scale, atol=1e-6)
    np.testing.assert_allclose(world.max(axis=0), CUBE_PTS.max(axis=0) * scale, atol=1e-6)


def test_mujoco_loads_open_flat_mesh_with_mjspec(tmp_path):
    """A single open, flat square: the worst case for MuJoCo's inertia and hull computation."""
    square = Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    write_stl(tmp_path / "flat.stl", square)
    spec = mujoco.MjSpec()
    spec.meshdir = str(tmp_path)
    m = spec.add_mesh()
    m.name, m.file, m.inertia = "flat", "flat.stl", mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
    body = spec.worldbody.add_body()
    body.add_freejoint()
    body.explicitinertial = True
    body.mass, body.inertia = 1.0, [1.0, 1.0, 1.0]
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="flat", contype=0, conaffinity=0)
    model = spec.compile()
    assert model.nmesh == 1 and model.mesh_facenum[0] == 2
    with pytest.raises(ValueError, match="coplanar|volume"):  # why the attributes are needed
        mujoco.MjModel.from_xml_string(
            f'<mujoco><compiler meshdir="{tmp_path}"/><asset><mesh name="f" file="flat.stl"/></asset>'
            '<worldbody><body><freejoint/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>'
            '<geom type="mesh" mesh="f"/></body></worldbody></mujoco>')


def test_every_real_mesh_converts_and_loads(tmp_path):
    """Every real .vtp/.stl/.obj converts to STL and compiles in MuJoCo, except files holding no
    surface at all (axes.vtp, line.vtp, outline.vtp: only <Lines>), which write_stl refuses."""
    files = _real_files("*.vtp") + _real_files("*.stl") + _real_files("*.obj")
    failures, no_surface = [], []
    for i, f in enumerate(files):
        mesh = read_mesh(f)
        out = tmp_path / f"{i}.stl"
        try:
            write_stl(out, mesh, (1.0, 1.0, 1.0))
        except ValueError:
            no_surface.append(f.name)
            assert len(mesh.faces) == 0, f
            continue
        try:
            _mj_model(tmp_path, [out.name])
        except ValueError as e:
            failures.append(f"{f}: {e}")
    assert not failures, "\n".join(failures)
    assert set(no_surface) <= {"axes.vtp", "line.vtp", "outline.vtp"}
