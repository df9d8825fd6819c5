"""meshcat geometry: mesh decimation keeps the shape."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("meshcat")

from o2m.viz.geometry import decimate_mesh  # noqa: E402


def test_decimate_mesh_keeps_the_shape():
    # A unit-radius UV sphere, 4k triangles.
    th, ph = np.meshgrid(np.linspace(0, np.pi, 33), np.linspace(0, 2 * np.pi, 65)[:-1], indexing="ij")
    v = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(32), np.arange(64), indexing="ij")
    a, b = i * 64 + j, i * 64 + (j + 1) % 64
    f = np.concatenate([np.stack([a, b, b + 64], -1).reshape(-1, 3), np.stack([a, b + 64, a + 64], -1).reshape(-1, 3)])
    v2, f2 = decimate_mesh(v, f, 0.2)
    assert len(f2) < len(f) / 4 and len(v2) < len(v) / 4
    assert f2.min() >= 0 and f2.max() < len(v2)
    assert np.all(np.abs(np.linalg.norm(v2, axis=1) - 1.0) < 0.2)  # vertices stay near the surface
    v3, f3 = decimate_mesh(v, f, None)
    assert np.array_equal(v3, v) and np.array_equal(f3, f)
