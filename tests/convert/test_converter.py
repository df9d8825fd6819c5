"""convert()'s BLAS thread limit (ConvertOptions.blas_threads)."""

from __future__ import annotations

import pytest
from threadpoolctl import threadpool_info

from o2m.convert import ConvertOptions, converter


def _blas_threads() -> list[int]:
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_convert_runs_on_one_blas_thread_by_default_and_restores_the_count(monkeypatch, tmp_path):
    before = _blas_threads()
    seen = []
    monkeypatch.setattr(converter, "_convert", lambda *a: seen.append(_blas_threads()))
    converter.convert(tmp_path / "m.osim", tmp_path / "out")
    assert seen and seen[0] and all(n == 1 for n in seen[0])
    assert _blas_threads() == before


def test_no_limit_leaves_the_library_own(monkeypatch, tmp_path):
    before = _blas_threads()
    seen = []
    monkeypatch.setattr(converter, "_convert", lambda *a: seen.append(_blas_threads()))
    converter.convert(tmp_path / "m.osim", tmp_path / "out", ConvertOptions(blas_threads=None))
    assert seen == [before]


@pytest.mark.parametrize("bad", [0, -1])
def test_a_blas_limit_below_one_is_refused(bad):
    with pytest.raises(ValueError, match="blas_threads"):
        ConvertOptions(blas_threads=bad)
