"""Visual geometry: mesh files (VTK .vtp, .stl, .obj), STL export for MuJoCo, and OpenSim's
analytic shapes mapped to MuJoCo primitives.

Lengths are in metres throughout. OpenSim keeps bone meshes as VTK XML PolyData (.vtp); MuJoCo
reads only STL, OBJ and MSH, so the converter reads each mesh with :func:`read_mesh` and writes
it with :func:`write_stl`, applying the OpenSim ``scale_factors`` on the way.

MuJoCo 4.0 and visual meshes: the real bone meshes tested compile with MuJoCo's defaults,
but open or flat meshes (the floor/plane .vtp files) do not: a colliding mesh geom needs a convex hull
("mesh has coplanar vertices, cannot compute convex hull"), and the default
``inertia="convex"`` needs a non-zero volume ("mesh volume is too small ... Try setting inertia
to shell"). A visual-only mesh geom therefore gets ``<mesh inertia="shell">`` (inertia of the
surface, needs only a non-zero area) and ``<geom contype="0" conaffinity="0">`` (no collision, so
no hull); both are needed for the flat ones. Mass properties come from OpenSim's <mass>/<inertia>
through an explicit <inertial>, which makes MuJoCo ignore geom masses. See
:data:`MUJOCO_VISUAL_MESH_ATTRS`.
"""

from __future__ import annotations

import binascii
import lzma
import re
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from lxml import etree

from o2m.errors import ModelFileError, UnsupportedElementError

__all__ = [
    "Mesh",
    "GeomSpec",
    "MUJOCO_VISUAL_MESH_ATTRS",
    "read_mesh",
    "read_vtp",
    "read_stl",
    "read_obj",
    "write_stl",
    "geometry_search_dirs",
    "find_geometry_file",
    "analytic_geom",
    "geometry_appearance",
    "geometry_scale_factors",
]

#: Attributes that let MuJoCo 4.0 compile open or flat meshes used as visual-only geoms:
#: the "mesh" ones go on ``<mesh>``, the "geom" ones on the ``<geom>`` using it.
MUJOCO_VISUAL_MESH_ATTRS: dict[str, dict[str, str]] = {
    "mesh": {"inertia": "shell"},
    "geom": {"contype": "0", "conaffinity": "0"},
}


# --------------------------------------------------------------------------------------------
# Mesh container
# --------------------------------------------------------------------------------------------


@dataclass
class Mesh:
    """A triangle mesh: ``vertices`` (n, 3) float64 in metres, ``faces`` (m, 3) int32 indices."""

    vertices: np.ndarray
    faces: np.ndarray

    def __post_init__(self) -> None:
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int32).reshape(-1, 3)


def read_mesh(path: str | Path) -> Mesh:
    """Read a mesh file OpenSim can display (.vtp, .stl or .obj), chosen by its extension."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext == ".vtp":
        return read_vtp(p)
    if ext == ".stl":
        return read_stl(p)
    if ext == ".obj":
        return read_obj(p)
    raise ModelFileError(f"{p}: unsupported mesh file type {ext!r} (expected .vtp, .stl or .obj)")


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise ModelFileError(f"{path}: mesh file not found") from None
    except OSError as e:
        raise ModelFileError(f"{path}: cannot read mesh file ({e.strerror or e})") from None


# --------------------------------------------------------------------------------------------
# VTK XML PolyData (.vtp)
# --------------------------------------------------------------------------------------------

_VTK_TYPES = {
    "Int8": "i1", "UInt8": "u1", "Int16": "i2", "UInt16": "u2", "Int32": "i4", "UInt32": "u4",
    "Int64": "i8", "UInt64": "u8", "Float32": "f4", "Float64": "f8",
    # Names used by very old VTK writers.
    "Char": "i1", "UnsignedChar": "u1", "Short": "i2", "UnsignedShort": "u2", "Int": "i4",
    "UnsignedInt": "u4", "Long": "i8", "UnsignedLong": "u8", "Float": "f4", "Double": "f8",
}


class _VtpError(Exception):
    """Internal: what is wrong with a .vtp, turned into ModelFileError with the path."""


@dataclass
class _Appended:
    """The <AppendedData> section: ``data`` is raw bytes or base64 text (as bytes)."""

    encoding: str
    data: bytes
    offsets: list[int] = field(default_factory=list)  # sorted offsets of all arrays using it


def _b64decode(text: bytes) -> bytes:
    """Decode base64 that may be several independently encoded pieces glued together.

    VTK encodes the block header of compressed data separately from the blocks, so '='
    padding can appear in the middle of one DataArray.
    """
    text = re.sub(rb"\s+", b"", text)
    out = []
    for piece in re.findall(rb"[^=]+=*", text):
        if len(piece) % 4:
            raise _VtpError("truncated base64 data")
        try:
            out.append(binascii.a2b_base64(piece, strict_mode=True))
        except binascii.Error as e:
            raise _VtpError(f"invalid base64 data ({e})") from None
    return b"".join(out)


class _VtpReader:
    """Decodes the DataArrays of one parsed .vtp document."""

    def __init__(self, root: etree._Element, appended: _Appended | None):
        if root.tag != "VTKFile":
            raise _VtpError(f"root element is <{root.tag}>, expected <VTKFile>")
        if root.get("type", "PolyData") != "PolyData":
            raise _VtpError(f"VTKFile type is {root.get('type')!r}, expected 'PolyData'")
        order = root.get("byte_order", "LittleEndian")
        if order not in ("LittleEndian", "BigEndian"):
            raise _VtpError(f"unknown byte_order {order!r}")
        self.endian = "<" if order == "LittleEndian" else ">"
        header = root.get("header_type", "UInt32")
        if header not in ("UInt32", "UInt64"):
            raise _VtpError(f"unknown header_type {header!r}")
        self.header = np.dtype(self.endian + ("u4" if header == "UInt32" else "u8"))
        comp = root.get("compressor")
        if comp not in (None, "", "vtkZLibDataCompressor", "vtkLZMADataCompressor"):
            raise _VtpError(f"unsupported compressor {comp!r}")
        self.compressor = comp or None
        self.appended = appended

    def _decompress(self, blob: bytes) -> bytes:
        assert self.compressor is not None
        if self.compressor == "vtkZLibDataCompressor":
            return zlib.decompress(blob)
        return lzma.decompress(blob)

    def _decode_stream(self, raw: bytes) -> bytes:
        """Payload of one binary DataArray from its decoded bytes (header + data)."""
        hs = self.header.itemsize
        if self.compressor is None:
            if len(raw) < hs:
                raise _VtpError("binary data shorter than its header")
            n = int(np.frombuffer(raw, self.header, 1)[0])
            if len(raw) < hs + n:
                raise _VtpError(f"binary data truncated: header says {n} bytes, found {len(raw) - hs}")
            return raw[hs:hs + n]
        if len(raw) < 3 * hs:
            raise _VtpError("compressed data shorter than its header")
        nblocks = int(np.frombuffer(raw, self.header, 1)[0])
        hlen = (3 + nblocks) * hs
        if len(raw) < hlen:
            raise _VtpError("compressed data header truncated")
        head = np.frombuffer(raw, self.header, 3 + nblocks).astype(np.int64)
        sizes = head[3:]
        start, out = hlen, []
        for s in sizes:
            blob = raw[start:start + int(s)]
            if len(blob) < s:
                raise _VtpError("compressed data truncated")
            try:
                out.append(self._decompress(blob))
            except (zlib.error, lzma.LZMAError) as e:
                raise _VtpError(f"cannot decompress data block ({e})") from None
            start += int(s)
        return b"".join(out)

    def _appended_stream(self, offset: int) -> bytes:
        app = self.appended
        if app is None:
            raise _VtpError('DataArray has format="appended" but the file has no <AppendedData>')
        if offset < 0 or offset > len(app.data):
            raise _VtpError(f"appended offset {offset} outside the appended data")
        if app.encoding == "base64":
            later = [o for o in app.offsets if o > offset]
            end = later[0] if later else len(app.data)
            return self._decode_stream(_b64decode(app.data[offset:end]))
        # Raw: read the header to know the length.
        hs = self.header.itemsize
        raw = app.data[offset:]
        if self.compressor is None:
            return self._decode_stream(raw)
        if len(raw) < hs:
            raise _VtpError("appended data truncated")
        nblocks = int(np.frombuffer(raw, self.header, 1)[0])
        hlen = (3 + nblocks) * hs
        if len(raw) < hlen:
            raise _VtpError("appended data header truncated")
        total = hlen + int(np.frombuffer(raw, self.header, 3 + nblocks)[3:].astype(np.int64).sum())
        return self._decode_stream(raw[:total])

    def array(self, el: etree._Element) -> np.ndarray:
        """Values of a <DataArray> as a flat 1-D array of its own dtype."""
        name = el.get("Name", "?")
        vtype = el.get("type")
        if vtype not in _VTK_TYPES:
            raise _VtpError(f"DataArray {name!r}: unknown type {vtype!r}")
        dtype = np.dtype(self.endian + _VTK_TYPES[vtype])
        fmt = el.get("format", "ascii")
        if fmt == "ascii":
            text = (el.text or "").split()
            try:
                if dtype.kind == "f":
                    return np.array(text, dtype=np.float64)
                return np.array([int(t) for t in text], dtype=np.int64)
            except ValueError as e:
                raise _VtpError(f"DataArray {name!r}: bad ASCII value ({e})") from None
        try:
            if fmt == "binary":
                payload = self._decode_stream(_b64decode((el.text or "").encode("ascii")))
            elif fmt == "appended":
                payload = self._appended_stream(int(el.get("offset", "")))
            else:
                raise _VtpError(f"DataArray {name!r}: unknown format {fmt!r}")
        except _VtpError as e:
            raise _VtpError(f"DataArray {name!r}: {e}") from None
        except (ValueError, UnicodeEncodeError) as e:
            raise _VtpError(f"DataArray {name!r}: {e}") from None
        if len(payload) % dtype.itemsize:
            raise _VtpError(f"DataArray {name!r}: {len(payload)} bytes is not a whole number of {vtype}")
        return np.frombuffer(payload, dtype).astype(dtype.newbyteorder("="))

    def cells(self, piece: etree._Element, tag: str, count: int,
              npoints: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Cells of <Polys> or <Strips>: (connectivity, cell starts, cell ends), None if absent.

        Cell i uses the point indices ``connectivity[starts[i]:ends[i]]``.
        """
        sec = piece.find(tag)
        if count == 0 and sec is None:
            return None
        if sec is None:
            raise _VtpError(f"Piece declares {count} {tag} but has no <{tag}>")
        arrays = {a.get("Name"): a for a in sec.findall("DataArray")}
        if "connectivity" not in arrays or "offsets" not in arrays:
            raise _VtpError(f"<{tag}> needs DataArrays named 'connectivity' and 'offsets'")
        conn = self.array(arrays["connectivity"]).astype(np.int64)
        offs = self.array(arrays["offsets"]).astype(np.int64)
        if len(offs) == count + 1 and count >= 0 and len(offs) and offs[0] == 0:
            offs = offs[1:]  # VTK >= 9 in-memory layout with a leading 0
        if len(offs) != count:
            raise _VtpError(f"<{tag}>: {len(offs)} offsets for {count} cells")
        starts = np.concatenate([[0], offs[:-1]]) if count else offs
        if count and (np.any(offs < starts) or offs[-1] != len(conn)):
            raise _VtpError(f"<{tag}>: offsets do not match the {len(conn)} connectivity entries")
        if len(conn) and (conn.min() < 0 or conn.max() >= npoints):
            raise _VtpError(f"<{tag}>: point index out of range 0..{npoints - 1}")
        return conn, starts, offs


def _triangles_per_cell(starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For cells of n points making n - 2 triangles each: (cell index, triangle index in its cell)."""
    ntri = np.maximum(ends - starts - 2, 0)
    cell = np.repeat(np.arange(len(starts)), ntri)
    j = np.arange(int(ntri.sum())) - np.repeat(np.cumsum(ntri) - ntri, ntri)
    return cell, j


def _fan(conn: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Fan-triangulate polygons conn[starts[i]:ends[i]]; returns (m, 3) indices."""
    cell, j = _triangles_per_cell(starts, ends)
    if cell.size == 0:
        return np.zeros((0, 3), np.int64)
    s = starts[cell]
    return np.stack([conn[s], conn[s + j + 1], conn[s + j + 2]], axis=1)


def _strips(conn: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Triangulate strips with VTK's alternating winding; returns (m, 3) indices."""
    cell, j = _triangles_per_cell(starts, ends)
    if cell.size == 0:
        return np.zeros((0, 3), np.int64)
    i0 = starts[cell] + j
    odd = (j % 2).astype(bool)
    a = np.where(odd, conn[i0 + 1], conn[i0])
    b = np.where(odd, conn[i0], conn[i0 + 1])
    return np.stack([a, b, conn[i0 + 2]], axis=1)


def _split_appended(data: bytes) -> tuple[bytes, _Appended | None]:
    """Separate the XML head from <AppendedData>, whose raw bytes are not valid XML text."""
    at = data.find(b"<AppendedData")
    if at < 0:
        return data, None
    close = data.find(b">", at)
    if close < 0:
        raise _VtpError("<AppendedData> tag is not closed")
    tag = data[at:close + 1].decode("latin-1")
    m = re.search(r'encoding\s*=\s*"([^"]*)"', tag)
    encoding = m.group(1) if m else "raw"
    if encoding not in ("raw", "base64"):
        raise _VtpError(f"unknown AppendedData encoding {encoding!r}")
    underscore = data.find(b"_", close)
    if underscore < 0:
        raise _VtpError("<AppendedData> has no '_' marker before its data")
    body = data[underscore + 1:]
    if encoding == "base64":
        end = body.find(b"<")
        body = (body[:end] if end >= 0 else body).rstrip()
    else:
        end = body.rfind(b"</AppendedData")
        if end >= 0:
            body = body[:end]
    return data[:at] + b"</VTKFile>", _Appended(encoding, body)


def read_vtp(path: str | Path) -> Mesh:
    """Read the triangles of a VTK XML PolyData file (.vtp).

    Handles ``format="ascii"``, ``"binary"`` (base64, UInt32/UInt64 block headers, optionally
    zlib- or lzma-compressed) and ``"appended"`` (raw or base64 <AppendedData>), several
    <Piece>s, <Polys> (fan-triangulated) and <Strips> (alternating winding). <Verts> and
    <Lines> are ignored. Returns vertices (n, 3) in the file's units (OpenSim: metres) and
    triangles (m, 3). Raises ModelFileError naming the file and the problem.
    """
    p = Path(path)
    data = _read_bytes(p)
    try:
        head, appended = _split_appended(data)
        try:
            root = etree.fromstring(head, etree.XMLParser(huge_tree=True, remove_comments=True))
        except etree.XMLSyntaxError as e:
            raise _VtpError(f"malformed XML ({e})") from None
        reader = _VtpReader(root, appended)
        if appended is not None:
            offs = sorted({int(o) for o in root.xpath('//DataArray[@format="appended"]/@offset')
                           if o.strip().lstrip("-").isdigit()})
            appended.offsets = offs
        pieces = root.findall("PolyData/Piece")
        if root.find("PolyData") is None:
            raise _VtpError("no <PolyData> element")
        verts, faces, base = [], [], 0
        for piece in pieces:
            try:
                npts = int(piece.get("NumberOfPoints", "0"))
                npolys = int(piece.get("NumberOfPolys", "0"))
                nstrips = int(piece.get("NumberOfStrips", "0"))
            except ValueError as e:
                raise _VtpError(f"bad <Piece> count ({e})") from None
            pts_el = piece.find("Points/DataArray")
            if pts_el is None:
                if npts:
                    raise _VtpError("<Piece> has no <Points><DataArray>")
                continue
            ncomp = int(pts_el.get("NumberOfComponents", "1"))
            pts = reader.array(pts_el)
            if ncomp != 3 or len(pts) != 3 * npts:
                raise _VtpError(f"Points: {len(pts)} values with {ncomp} components for {npts} points")
            tris = []
            poly = reader.cells(piece, "Polys", npolys, npts)
            if poly is not None:
                tris.append(_fan(*poly))
            strip = reader.cells(piece, "Strips", nstrips, npts)
            if strip is not None:
                tris.append(_strips(*strip))
            verts.append(pts.reshape(-1, 3))
            if tris:
                faces.append(np.concatenate(tris) + base)
            base += npts
    except _VtpError as e:
        raise ModelFileError(f"{p}: {e}") from None
    return Mesh(np.concatenate(verts) if verts else np.zeros((0, 3)),
                np.concatenate(faces) if faces else np.zeros((0, 3), np.int32))


# --------------------------------------------------------------------------------------------
# STL and OBJ
# --------------------------------------------------------------------------------------------

_STL_DTYPE = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def _merge_vertices(tri_vertices: np.ndarray) -> Mesh:
    """Mesh from per-triangle corners (m, 3, 3), merging identical vertices."""
    flat = tri_vertices.reshape(-1, 3).astype(np.float64)
    if len(flat) == 0:
        return Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int32))
    uniq, inv = np.unique(flat, axis=0, return_inverse=True)
    return Mesh(uniq, inv.reshape(-1, 3))


def read_stl(path: str | Path) -> Mesh:
    """Read an ASCII or binary STL file; identical corners are merged into shared vertices."""
    p = Path(path)
    data = _read_bytes(p)
    if len(data) >= 84:
        n = struct.unpack_from("<I", data, 80)[0]
        if len(data) == 84 + 50 * n:
            tris = np.frombuffer(data, _STL_DTYPE, n, 84)
            return _merge_vertices(tris["v"])
    text = data.decode("latin-1")
    if not text.lstrip().lower().startswith("solid"):
        raise ModelFileError(f"{p}: neither a binary STL (size does not match its triangle count) "
                             "nor an ASCII STL (does not start with 'solid')")
    nums = re.findall(r"^\s*vertex\s+(\S+)\s+(\S+)\s+(\S+)", text, flags=re.M | re.I)
    try:
        v = np.array(nums, dtype=np.float64)
    except ValueError as e:
        raise ModelFileError(f"{p}: bad ASCII STL vertex ({e})") from None
    if len(v) % 3:
        raise ModelFileError(f"{p}: ASCII STL has {len(v)} vertices, not a multiple of 3")
    return _merge_vertices(v.reshape(-1, 3, 3))


def read_obj(path: str | Path) -> Mesh:
    """Read the ``v`` and ``f`` lines of a Wavefront OBJ; polygons are fan-triangulated."""
    p = Path(path)
    text = _read_bytes(p).decode("utf-8", errors="replace")
    verts: list[list[float]] = []
    tris: list[tuple[int, int, int]] = []
    for lineno, line in enumerate(text.splitlines(), 1):
        tok = line.split()
        if not tok:
            continue
        try:
            if tok[0] == "v":
                verts.append([float(t) for t in tok[1:4]])
                if len(verts[-1]) != 3:
                    raise ValueError("vertex needs 3 coordinates")
            elif tok[0] == "f":
                idx = []
                for t in tok[1:]:
                    i = int(t.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(verts) + i)
                if len(idx) < 3:
                    raise ValueError("face needs at least 3 vertices")
                if min(idx) < 0 or max(idx) >= len(verts):
                    raise ValueError("face refers to a vertex that is not defined")
                tris.extend((idx[0], idx[k], idx[k + 1]) for k in range(1, len(idx) - 1))
        except ValueError as e:
            raise ModelFileError(f"{p}: line {lineno}: {e}") from None
    return Mesh(np.array(verts, dtype=np.float64).reshape(-1, 3),
                np.array(tris, dtype=np.int64).reshape(-1, 3))


def write_stl(path: str | Path, mesh: Mesh,
              scale: tuple[float, float, float] | np.ndarray = (1.0, 1.0, 1.0)) -> int:
    """Write ``mesh`` as a binary STL with vertices multiplied by ``scale`` (3,) per axis.

    ``scale`` is the OpenSim Mesh ``scale_factors``. A mirroring scale (negative product) flips
    the winding so normals keep pointing outwards. Triangles of zero area (after scaling and
    rounding to float32, as stored in STL) are dropped: they have no normal and add nothing
    to the surface (MuJoCo 4.0 happens to tolerate them, other STL readers may not). Returns the
    number of triangles written; raises ValueError if none is left (MuJoCo cannot load an
    empty mesh, e.g. a .vtp holding only lines). Load it in MuJoCo 4.0 as a visual mesh with
    :data:`MUJOCO_VISUAL_MESH_ATTRS` (``inertia="shell"``, no collision) so that open or flat
    meshes compile.
    """
    s = np.asarray(scale, dtype=np.float64).reshape(3)
    v = (mesh.vertices * s).astype(np.float32)
    f = mesh.faces.astype(np.int64)
    if np.prod(s) < 0:
        f = f[:, ::-1]
    if len(f) and (f.min() < 0 or f.max() >= len(v)):
        raise ValueError(f"mesh faces refer to vertices outside 0..{len(v) - 1}")
    tri = v[f].astype(np.float64)  # (m, 3, 3)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area2 = np.linalg.norm(normal, axis=1)
    keep = (area2 > 0) & np.all(np.isfinite(tri.reshape(-1, 9)), axis=1)
    if not keep.any():
        raise ValueError(f"{path}: mesh has no triangle of non-zero area to write")
    out = np.zeros(int(keep.sum()), _STL_DTYPE)
    out["normal"] = normal[keep] / area2[keep, None]
    out["v"] = tri[keep]
    header = b"o2m binary STL".ljust(80, b" ")
    with open(path, "wb") as fh:
        fh.write(header)
        fh.write(struct.pack("<I", len(out)))
        fh.write(out.tobytes())
    return len(out)


# --------------------------------------------------------------------------------------------
# Locating mesh files
# --------------------------------------------------------------------------------------------


def geometry_search_dirs(model_path: str | Path, extra_dirs: list[str | Path] | tuple = ()) -> list[Path]:
    """OpenSim's mesh search folders, in order: the model file's folder, its ``Geometry/``
    subfolder, then ``extra_dirs`` (the user's geometry paths) in the order given."""
    folder = Path(model_path).resolve().parent
    return [folder, folder / "Geometry", *(Path(d) for d in extra_dirs)]


def find_geometry_file(name: str, search_dirs: list[str | Path] | tuple) -> Path | None:
    """Locate the ``mesh_file`` ``name`` as OpenSim does: an absolute path is taken as is,
    otherwise the first of ``search_dirs`` (see :func:`geometry_search_dirs`) holding it wins.

    Windows separators in ``name`` are accepted. Returns None when no folder has the file.
    """
    name = name.strip().replace("\\", "/")
    if not name:
        return None
    p = Path(name)
    if p.is_absolute():
        return p if p.is_file() else None
    for d in search_dirs:
        cand = Path(d) / p
        if cand.is_file():
            return cand
    return None


# --------------------------------------------------------------------------------------------
# Analytic geometry
# --------------------------------------------------------------------------------------------

#: Rotation (w, x, y, z) of -90 degrees about x: takes MuJoCo's cylinder axis (local z) onto
#: OpenSim's cylinder axis (the frame's y).
_CYLINDER_QUAT = np.array([np.sqrt(0.5), -np.sqrt(0.5), 0.0, 0.0])

#: Geometry OpenSim draws that has no MuJoCo counterpart, with the reason reported when skipped.
_SKIPPED = {
    "Cone": "MuJoCo has no cone primitive",
    "Torus": "MuJoCo has no torus primitive",
    "FrameGeometry": "frame axes are a visual decoration, not body geometry",
    "Arrow": "arrows are a visual decoration, not body geometry",
    "Line": "lines are a visual decoration, not body geometry",
    "LineGeometry": "lines are a visual decoration, not body geometry",
    "Mesh": "Mesh is not analytic; convert it with read_mesh/write_stl",
}

#: OpenSim 4.6 default property values, used when the element omits them.
_DEFAULTS = {
    ("Sphere", "radius"): [1.0],
    ("Cylinder", "radius"): [0.5],
    ("Cylinder", "half_height"): [0.5],
    ("Brick", "half_lengths"): [0.1, 0.2, 0.3],
    ("Ellipsoid", "radii"): [0.5, 1.0, 2.0],
}


@dataclass
class GeomSpec:
    """A MuJoCo primitive standing in for an OpenSim analytic geometry.

    ``type`` is the MuJoCo geom type name, ``size`` (3,) MuJoCo's size in metres, ``pos`` (3,)
    and ``quat`` (4, w-x-y-z) place it in the OpenSim frame holding the geometry (``frame`` is
    that element's socket_frame path, e.g. ".."), ``rgba`` (4,) comes from <Appearance> (None
    when absent), ``visible`` from <Appearance><visible>.
    """

    type: str
    size: np.ndarray
    pos: np.ndarray = field(default_factory=lambda: np.zeros(3))
    quat: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    rgba: np.ndarray | None = None
    name: str | None = None
    frame: str | None = None
    visible: bool = True


def _err(el: etree._Element, msg: str) -> UnsupportedElementError:
    return UnsupportedElementError(msg, element=str(el.tag), name=el.get("name"), line=el.sourceline)


def _vector(el: etree._Element, prop: str, n: int, default: list[float] | None = None) -> np.ndarray:
    """Property ``prop`` of ``el`` as a float array (n,), or ``default`` when absent."""
    child = el.find(prop)
    if child is None or not (child.text or "").strip():
        if default is None:
            raise _err(el, f"has no <{prop}>")
        return np.array(default, dtype=np.float64)
    text = re.sub(r"[(),~\[\]]", " ", child.text)
    try:
        vals = np.array([float(t) for t in text.split()], dtype=np.float64)
    except ValueError:
        raise _err(el, f"<{prop}> is not numeric: {child.text.strip()!r}") from None
    if len(vals) != n or not np.all(np.isfinite(vals)):
        raise _err(el, f"<{prop}> needs {n} finite number(s), got {child.text.strip()!r}")
    return vals


def geometry_scale_factors(element: etree._Element) -> np.ndarray:
    """The ``scale_factors`` (3,) of any OpenSim Geometry element (default 1 1 1)."""
    default = [0.2, 0.2, 0.2] if element.tag == "FrameGeometry" else [1.0, 1.0, 1.0]
    return _vector(element, "scale_factors", 3, default)


def geometry_appearance(element: etree._Element) -> tuple[np.ndarray | None, bool]:
    """``(rgba (4,) or None, visible)`` from a Geometry's <Appearance>.

    rgba is None when there is no <Appearance>; missing <color>/<opacity> take OpenSim's
    defaults (white, opaque).
    """
    app = element.find("Appearance")
    if app is None:
        return None, True
    color = _vector(app, "color", 3, [1.0, 1.0, 1.0])
    opacity = _vector(app, "opacity", 1, [1.0])
    vis = app.find("visible")
    visible = vis is None or (vis.text or "true").strip().lower() not in ("false", "0")
    return np.clip(np.concatenate([color, opacity]), 0.0, 1.0), visible


def analytic_geom(element: etree._Element, skipped: list[str] | None = None) -> GeomSpec | None:
    """MuJoCo primitive for an OpenSim 4.x geometry element from <attached_geometry>.

    Sphere -> sphere (ellipsoid if scaled non-uniformly), Cylinder -> cylinder (OpenSim's axis
    is the frame's y, so ``quat`` turns MuJoCo's z onto it), Brick -> box, Ellipsoid ->
    ellipsoid; ``scale_factors`` are applied as OpenSim does when drawing. Cone, Torus,
    FrameGeometry, Arrow, Line, LineGeometry and Mesh give None, and the reason
    ('<Tag name="n">: why') is appended to ``skipped`` when given; so do a Cylinder scaled
    differently in x and z and a shape of zero size. XML comments give None without a reason.
    Unknown tags raise UnsupportedElementError.
    """
    if not isinstance(element.tag, str):  # an XML comment or processing instruction
        return None
    tag = element.tag
    name = element.get("name")

    def skip(reason: str) -> None:
        if skipped is not None:
            label = f'<{tag} name="{name}">' if name else f"<{tag}>"
            skipped.append(f"{label}: {reason}")

    if tag in _SKIPPED:
        skip(_SKIPPED[tag])
        return None
    if tag not in ("Sphere", "Cylinder", "Brick", "Ellipsoid"):
        raise _err(element, "is not a geometry type o2m knows")
    scale = np.abs(geometry_scale_factors(element))
    quat = np.array([1.0, 0.0, 0.0, 0.0])
    if tag == "Sphere":
        r = _vector(element, "radius", 1, _DEFAULTS[tag, "radius"])[0] * scale
        if np.allclose(r, r[0], rtol=1e-12, atol=0.0):
            gtype, size = "sphere", np.array([r[0], 0.0, 0.0])
        else:
            gtype, size = "ellipsoid", r
    elif tag == "Cylinder":
        r = _vector(element, "radius", 1, _DEFAULTS[tag, "radius"])[0]
        hh = _vector(element, "half_height", 1, _DEFAULTS[tag, "half_height"])[0]
        if not np.isclose(scale[0], scale[2], rtol=1e-12, atol=0.0):
            skip(f"scale_factors {scale.tolist()} make an elliptic cylinder, which MuJoCo lacks")
            return None
        gtype, size, quat = "cylinder", np.array([r * scale[0], hh * scale[1], 0.0]), _CYLINDER_QUAT.copy()
    elif tag == "Brick":
        gtype, size = "box", _vector(element, "half_lengths", 3, _DEFAULTS[tag, "half_lengths"]) * scale
    else:
        gtype, size = "ellipsoid", _vector(element, "radii", 3, _DEFAULTS[tag, "radii"]) * scale
    used = size[:1] if gtype == "sphere" else size[:2] if gtype == "cylinder" else size
    if np.any(used <= 0):
        skip(f"non-positive size {used.tolist()}")
        return None
    rgba, visible = geometry_appearance(element)
    frame = element.findtext("socket_frame")
    return GeomSpec(type=gtype, size=size, quat=quat, rgba=rgba, name=name,
                    frame=frame.strip() if frame is not None else None, visible=visible)
