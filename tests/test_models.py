"""Tests of o2m.models: fetching registry files from a mirror or URL into a verified cache."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from o2m import models
from o2m.errors import FetchError
from tests.helpers import local_mirror, require_models

SMALL = ["mobl-arms/license.txt", "opensim-models/Models/Arm26/arm26.osim"]


@pytest.fixture(scope="session")
def real_copy(tmp_path_factory) -> Path:
    """A folder laid out like the registry holding real files: the local mirror when there is one,
    else a cache filled from the registry's URLs (a cache is laid out like a mirror)."""
    local = local_mirror()
    if local is not None and (local / models.BUNDLED["arm26"]).is_file():
        return local
    require_models()
    folder = tmp_path_factory.mktemp("downloaded")
    for p in SMALL:
        models.fetch(p, cache=folder)
    for name in ("arm26", "mobl_arms"):
        models.fetch_model_with_geometry(name, cache=folder, progress=False)
    return folder


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    """An empty cache folder, set through O2M_CACHE; no mirror from the environment."""
    folder = tmp_path / "cache"
    monkeypatch.setenv(models.CACHE_ENV, str(folder))
    monkeypatch.delenv(models.MIRROR_ENV, raising=False)
    return folder


@pytest.fixture
def mirror(tmp_path, real_copy) -> Path:
    """A temporary mirror holding a couple of real registry files."""
    folder = tmp_path / "mirror"
    for p in SMALL:
        (folder / p).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(real_copy / p, folder / p)
    return folder


def _files(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if p.is_file()] if folder.exists() else []


def test_registry_loads_and_lists_bundled_models():
    reg = models.get_registry()
    assert len(reg) == len(reg.paths) > 600
    assert all(len(e.sha256) == 64 and e.url.startswith("https://") for e in reg)
    for name, osim in models.BUNDLED.items():
        assert osim in reg, name
        model = models.bundled_model(name)
        assert model.osim == osim
        assert reg.under(model.geometry), model.geometry
    assert models.bundled_model("mobl_arms").geometry == "mobl-arms/Geometry"
    assert models.bundled_model("gait2392").geometry == "opensim-models/Geometry"
    assert set(models.bundled_model("mobl_arms").extras()) >= {
        "mobl-arms/initial_states.sto", "mobl-arms/setup_fd.xml", "mobl-arms/license.txt"}


def test_cache_dir_from_env(cache):
    assert models.cache_dir() == cache
    assert models.cache_dir(cache / "x") == cache / "x"


def test_fetch_from_mirror_verifies_hash(cache, mirror, monkeypatch):
    monkeypatch.setenv(models.MIRROR_ENV, str(mirror))
    for p in SMALL:
        got = models.fetch(p)
        assert got == cache / p
        assert models.sha256_of(got) == models.get_registry().lookup(p).sha256
    # the mirror argument wins over the environment variable
    monkeypatch.setenv(models.MIRROR_ENV, str(mirror / "nowhere"))
    other = cache.parent / "cache2"
    assert models.fetch(SMALL[0], mirror=mirror, cache=other) == other / SMALL[0]


def test_corrupted_mirror_file_is_rejected_and_not_cached(cache, mirror):
    bad = mirror / SMALL[0]
    bad.write_bytes(bad.read_bytes() + b"tampered")
    with pytest.raises(FetchError, match="sha256") as info:
        models.fetch(SMALL[0], mirror=mirror)
    msg = str(info.value)
    assert models.get_registry().lookup(SMALL[0]).sha256 in msg
    assert models.sha256_of(bad) in msg and str(bad) in msg
    assert _files(cache) == []


def test_corrupted_cache_file_is_replaced(cache, mirror):
    target = models.fetch(SMALL[0], mirror=mirror)
    target.write_bytes(b"garbage")
    assert models.fetch(SMALL[0], mirror=mirror) == target
    assert models.sha256_of(target) == models.get_registry().lookup(SMALL[0]).sha256


def test_missing_mirror_file(cache, mirror):
    path = "opensim-models/Models/Leg6Dof9Musc/leg6dof9musc.osim"
    with pytest.raises(FetchError) as info:
        models.fetch(path, mirror=mirror)
    msg = str(info.value)
    assert str(mirror / path) in msg and models.MIRROR_ENV in msg
    assert _files(cache) == []


def test_unknown_path_suggests_close_matches(cache):
    with pytest.raises(FetchError, match="not in o2m's model registry") as info:
        models.fetch("opensim-models/Models/Arm26/arm25.osim")
    assert "opensim-models/Models/Arm26/arm26.osim" in str(info.value)
    with pytest.raises(FetchError, match="mobl-arms/Geometry/hand_2distph.vtp"):
        models.fetch("hand_2distph.vtp")
    with pytest.raises(FetchError, match="arm26"):
        models.fetch_model("arm27")


def test_download_failure_is_a_clean_fetch_error(cache, monkeypatch):
    real = models.get_registry().lookup(SMALL[0])
    fake = models.Registry([models.Entry(real.path, real.sha256, "http://127.0.0.1:9/o2m/license.txt")])
    monkeypatch.setattr(models, "get_registry", lambda: fake)
    with pytest.raises(FetchError) as info:
        models.fetch(SMALL[0])
    msg = str(info.value)
    assert "http://127.0.0.1:9/o2m/license.txt" in msg and models.MIRROR_ENV in msg
    assert _files(cache) == []


def test_valid_cached_file_is_reused_without_the_mirror(cache, mirror):
    first = models.fetch(SMALL[1], mirror=mirror)
    mtime = first.stat().st_mtime_ns
    shutil.rmtree(mirror)
    assert models.fetch(SMALL[1], mirror=mirror) == first
    assert first.stat().st_mtime_ns == mtime


def test_fetch_model_arm26(cache, real_copy):
    res = models.fetch_model_with_geometry("arm26", mirror=real_copy, progress=False)
    assert res.osim == cache / models.BUNDLED["arm26"] and res.osim.is_file()
    assert res.geometry_dir == cache / "opensim-models" / "Geometry"
    meshes = models.referenced_meshes(res.osim)
    assert meshes and all((res.geometry_dir / m).is_file() for m in meshes)
    # only what the model needs, not the whole geometry folder
    assert len(_files(res.geometry_dir)) == len(meshes)
    assert models.fetch_model("arm26", mirror=real_copy, geometry=False) == res.osim


def test_fetch_model_mobl_arms(cache, real_copy):
    res = models.fetch_model_with_geometry("mobl_arms", mirror=real_copy, progress=False)
    assert res.osim.parent / "Geometry" == res.geometry_dir  # OpenSim's own search finds the meshes
    meshes = models.referenced_meshes(res.osim)
    assert len(meshes) > 20 and all((res.geometry_dir / m).is_file() for m in meshes)
    for extra in ("initial_states.sto", "setup_fd.xml", "license.txt"):
        assert (res.osim.parent / extra).is_file()


def test_every_registry_row_matches_the_mirror():
    """The local mirror (when there is one: it is what this test checks) holds every registry file."""
    local = local_mirror()
    if local is None:
        pytest.skip("no local mirror to check (O2M_MODEL_MIRROR or shared/models beside the clone)")
    bad = []
    for entry in models.get_registry():
        f = local / entry.path
        if not f.is_file():
            bad.append(f"{entry.path}: missing")
        elif models.sha256_of(f) != entry.sha256:
            bad.append(f"{entry.path}: sha256 differs")
    assert not bad, bad


@pytest.fixture
def http_server(tmp_path):
    """A local HTTP server (127.0.0.1, free port) serving tmp_path/www; yields (folder, base url)."""
    import functools
    import http.server
    import threading

    root = tmp_path / "www"
    root.mkdir()

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=root))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield root, f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


def test_download_from_local_server(cache, mirror, http_server, monkeypatch):
    root, base = http_server
    real = models.get_registry().lookup(SMALL[0])
    shutil.copyfile(mirror / SMALL[0], root / "good.txt")
    (root / "bad.txt").write_bytes(b"not the license")
    fake = models.Registry([
        models.Entry(SMALL[0], real.sha256, f"{base}/good.txt"),
        models.Entry("x/bad.txt", real.sha256, f"{base}/bad.txt"),
        models.Entry("x/gone.txt", real.sha256, f"{base}/gone.txt"),
    ])
    monkeypatch.setattr(models, "get_registry", lambda: fake)
    assert models.sha256_of(models.fetch(SMALL[0])) == real.sha256
    with pytest.raises(FetchError, match="sha256 mismatch"):
        models.fetch("x/bad.txt")
    with pytest.raises(FetchError, match="404"):
        models.fetch("x/gone.txt")
    assert _files(cache) == [cache / SMALL[0]]


def test_mirror_can_be_a_server(cache, mirror, http_server, monkeypatch):
    """O2M_MODEL_MIRROR may be a URL laid out like the registry: files come from <url>/<path>, hash-checked."""
    root, base = http_server
    for p in SMALL:
        (root / p).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(mirror / p, root / p)
    monkeypatch.setenv(models.MIRROR_ENV, base + "/")
    assert models.mirror_dir() == base
    got = models.fetch(SMALL[0])
    assert models.sha256_of(got) == models.get_registry().lookup(SMALL[0]).sha256
    (root / SMALL[1]).write_bytes(b"tampered")
    with pytest.raises(FetchError, match="sha256 mismatch"):
        models.fetch(SMALL[1])
