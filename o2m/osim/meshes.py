"""Mesh files OpenSim displays: VTK XML PolyData (.vtp), STL and OBJ, read into a :class:`Mesh`;
and binary STL export, since MuJoCo reads only STL, OBJ and MSH.

Lengths are in the files' units (OpenSim: metres). :func:`read_mesh` reads any of the three;
:func:`write_stl` writes a mesh scaled by OpenSim's ``scale_factors``. Problems with a file raise
:class:`o2m.errors.ModelFileError` naming it.
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

from o2m.errors import ModelFileError

__all__ = ["Mesh", "read_mesh", "read_obj", "read_stl", "read_vtp", "write_stl"]


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
    :data:`o2m.convert.geometry.MUJOCO_VISUAL_MESH_ATTRS` (``inertia="shell"``, no collision) so that open or flat
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

