"""meshcat scenes of converted models: drawing, animation, OpenSim side by side, HTML export.

The browser test opens an exported page in headless Chromium (Debian's ``chromium``, which
``.ci/run`` installs) and checks that geometry was drawn; it skips when no Chromium is found.
"""

from __future__ import annotations

import base64
import os
import re
import shutil
import signal
import subprocess
from pathlib import Path

import mujoco
import numpy as np
import pytest

pytest.importorskip("meshcat")

from o2m.viz import scene as V  # noqa: E402
from tests.viz.helpers import arm_motion  # noqa: E402

MB = 1e6


def _commands(html: str) -> list[dict]:
    """The meshcat commands embedded in an exported page, decoded."""
    import umsgpack

    return [umsgpack.unpackb(base64.b64decode(b64)) for b64 in re.findall(r"base64,([A-Za-z0-9+/=]+)\"", html)]


def _self_contained(html: str) -> bool:
    return not re.search(r"<script[^>]*\bsrc\s*=", html, re.I) and not re.search(r"fetch\(\s*[\"']https?:", html)


# --------------------------------------------------------------------------------------------
# Scenes and export
# --------------------------------------------------------------------------------------------


def test_scene_contents_and_html(arm26, tmp_path):
    _, _, m = arm26
    v = V.Viewer()
    scene = v.add_model(m)
    scene.show_qpos(arm_motion(m, 2)[0][-1], np.linspace(0, 1, m.nu))
    v.frame_camera()
    path = v.export_html(tmp_path / "arm26.html")
    html = path.read_text()
    assert html.startswith("<!DOCTYPE html>") and "MeshCat.Viewer" in html
    assert _self_contained(html)
    objects = {c["path"]: c["object"] for c in _commands(html) if c["type"] == "set_object"}
    mesh_geoms = [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH]
    mesh_paths = [p for p, o in objects.items() if "/bodies/" in p and o["geometries"][0]["type"] == "BufferGeometry"]
    assert len(mesh_paths) >= len(mesh_geoms)
    wraps = [p for p, o in objects.items() if "/g" in p and "wrap_" in p]
    assert wraps and all(objects[p]["materials"][0]["transparent"] for p in wraps)
    site_meshes = [o["geometries"][0] for p, o in objects.items() if p.endswith("/sites")]
    shown = np.isin(m.site_group, [0, 1, 2, 3, 4])
    assert len(site_meshes) == len(set(m.site_bodyid[shown]))  # one mesh per body with sites
    n_vertices = sum(len(g["data"]["attributes"]["position"]["array"].data) // 12 for g in site_meshes)
    assert n_vertices == 12 * int(shown.sum())  # an icosahedron per site
    assert "/meshcat/o2m/mujoco/tendons/pose" in objects
    size = path.stat().st_size
    assert 1 * MB < size < 6 * MB, size
    small = V.show_pose(m, decimate=0.004).export_html(tmp_path / "arm26-small.html")
    print(f"arm26 scene: {size / MB:.2f} MB, decimate=0.004: {small.stat().st_size / MB:.2f} MB")
    assert small.stat().st_size < 0.6 * size


def test_animation_export(arm26, tmp_path):
    _, _, m = arm26
    q, act = arm_motion(m, 12)
    v = V.animate_qpos(m, q, fps=24, activations=act, tendon_stride=2, html=tmp_path / "anim.html")
    html = (tmp_path / "anim.html").read_text()
    assert _self_contained(html)
    cmds = _commands(html)
    assert cmds[-1]["type"] == "set_animation"
    clips = {a["path"]: a["clip"] for a in cmds[-1]["animations"]}
    elbow = clips["/meshcat/o2m/mujoco/bodies/r_ulna_radius_hand"]
    assert elbow["fps"] == 24
    quat_track = next(t for t in elbow["tracks"] if t["name"] == ".quaternion")
    assert len(quat_track["keys"]) == 12
    flipbook = [p for p in clips if "/tendons/f" in p]
    assert len(flipbook) == 6  # every second frame
    assert sum(c["type"] == "set_object" and "/tendons/f" in c["path"] for c in cmds) == 6
    with pytest.raises(V.ViewerError, match="qpos"):
        V.animate_qpos(m, np.zeros((3, m.nq + 1)))
    v.close()


def test_side_by_side(arm26, tmp_path):
    osim, _, m = arm26
    q, act = arm_motion(m, 5)
    names = ["r_shoulder_elev", "r_elbow_flex"]
    values = q[:, [m.joint(n).qposadr[0] for n in names]]
    v = V.side_by_side(m, osim, names, values, q, fps=10, activations=act, html=tmp_path / "sbs.html",
                       decimate=0.004)
    html = (tmp_path / "sbs.html").read_text()
    cmds = _commands(html)
    clips = {a["path"] for a in cmds[-1]["animations"]}
    assert "/meshcat/o2m/opensim/bodies/r_humerus" in clips and "/meshcat/o2m/mujoco/bodies/r_humerus" in clips
    offsets = {c["path"]: c["matrix"][12:15] for c in cmds if c["type"] == "set_transform"}
    np.testing.assert_allclose(offsets["/meshcat/o2m/opensim"], [0, 0.6, 0], atol=1e-6)
    assert [s.name for s in v.scenes] == ["opensim", "mujoco"]


def test_server_starts_only_when_asked_and_stops(arm26):
    _, _, m = arm26
    with V.Viewer() as v:
        v.add_model(m, decimate=0.01, show_sites=False)
        assert not v.server_running
        url = v.url()
        assert url.startswith("http://127.0.0.1:") and v.server_running
        proc = v._window.server_proc
    assert proc.poll() is not None and not v.server_running


def test_notebook_iframe(tmp_path):
    frame = V.notebook_iframe(tmp_path / "figs" / "a.html", start=tmp_path, height=300)
    assert frame.src == "figs/a.html" and frame.height == 300
    assert len(frame._repr_html_()) < 1000


def test_mobl_arms_sizes(mobl, tmp_path):
    """Measured sizes of MoBL-ARMS pages (reported in o2m.viz.scene's docstring)."""
    _, _, m = mobl
    sizes = {}
    for dec in (None, 0.003):
        sizes["pose", dec] = V.show_pose(m, decimate=dec).export_html(tmp_path / f"pose{dec}.html").stat().st_size
    q = np.tile(m.qpos0, (50, 1))
    for name, amp in (("elbow_flexion", 1.2), ("shoulder_elv", 0.8)):
        q[:, m.joint(name).qposadr[0]] += amp * np.sin(np.linspace(0, np.pi, 50))
    act = np.tile(np.linspace(0, 1, 50)[:, None], (1, m.nu))
    v = V.animate_qpos(m, q, 30, act, decimate=0.003)
    sizes["anim50", 0.003] = v.export_html(tmp_path / "anim.html").stat().st_size
    print({k: f"{s / MB:.2f} MB" for k, s in sizes.items()})
    assert sizes["pose", 0.003] < 0.7 * sizes["pose", None] < 0.7 * 5 * MB
    assert sizes["anim50", 0.003] < 3.5 * MB


# --------------------------------------------------------------------------------------------
# In a browser
# --------------------------------------------------------------------------------------------

CHROMIUM = next((p for p in (shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")) if p), None)


def _screenshot(html: Path, png: Path, profile: Path) -> None:
    """Headless Chromium screenshot (800 x 600) of ``html`` after 3 s of virtual time."""
    cmd = [CHROMIUM, "--headless", "--disable-gpu", "--no-sandbox", "--hide-scrollbars", "--mute-audio",
           f"--user-data-dir={profile}", f"--screenshot={png}", "--window-size=800,600",
           "--virtual-time-budget=3000", html.resolve().as_uri()]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        proc.wait(timeout=150)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # the group this test started: Chromium and its helpers
        proc.wait()
        pytest.fail(f"Chromium did not finish a screenshot of {html.name} in 150 s")


def _pixels(png: Path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(png).convert("RGB"), dtype=int).reshape(-1, 3)


def _drawn_fraction(rgb: np.ndarray) -> float:
    """Fraction of pixels (N, 3) that differ from the most common colour (the background)."""
    colours, counts = np.unique(rgb, axis=0, return_counts=True)
    background = colours[np.argmax(counts)]
    return float(np.mean(np.abs(rgb - background).max(axis=1) > 24))


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium (apt-get install chromium) to render the exported HTML")
def test_exported_html_draws_in_a_browser(arm26, tmp_path):
    pytest.importorskip("PIL")
    _, _, m = arm26
    q, act = arm_motion(m, 4)
    background = (0.1, 0.1, 0.15)
    page = V.animate_qpos(m, q, fps=30, activations=act, background=background, decimate=0.004,
                          html=tmp_path / "arm26.html")
    page.close()
    empty = V.Viewer(background=background).export_html(tmp_path / "empty.html")
    _screenshot(tmp_path / "arm26.html", tmp_path / "arm26.png", tmp_path / "profile1")
    _screenshot(empty, tmp_path / "empty.png", tmp_path / "profile2")
    shot, blank = _pixels(tmp_path / "arm26.png"), _pixels(tmp_path / "empty.png")
    drawn, control = _drawn_fraction(shot), _drawn_fraction(blank)
    r, g, b = shot.T
    red, blue = int(np.sum((r > 150) & (g < 90) & (b < 90))), int(np.sum((b > 150) & (r < 90) & (g < 90)))
    print(f"pixels not background: model {drawn:.4f}, empty scene {control:.4f}; red {red}, blue {blue}")
    assert control < 0.02  # only meshcat's "Open Controls" bar
    assert drawn > control + 0.01, "the exported page drew (almost) nothing"  # > 4800 pixels of bones
    # The animation ran to its last frame: tendons fully activated (red), frame 0's blue lines hidden.
    assert red > 30 and blue < red / 4
