"""The gallery's bookkeeping (o2m.gallery): the conversions themselves are the corpus benchmark."""

from __future__ import annotations

import json

import pytest


def test_a_partial_gallery_run_updates_its_rows_in_the_last_run(tmp_path):
    from o2m.gallery import GalleryRow, _merged

    earlier = tmp_path / "gallery.json"
    earlier.write_text(json.dumps({"quick": False, "poses": 50, "rows": [
        {"model": "a", "source": "A", "status": "converted", "seconds": 1.0},
        {"model": "b", "source": "B", "status": "converted", "seconds": 2.0}]}))
    rows = _merged(earlier, [GalleryRow("b", "B", "converted", 9.0)], ["a", "b", "c"], {"quick": False, "poses": 50})
    assert [(r.model, r.seconds) for r in rows] == [("a", 1.0), ("b", 9.0)]
    with pytest.raises(ValueError, match="whole gallery"):
        _merged(earlier, [], ["a"], {"quick": True, "poses": 50})
    first = _merged(tmp_path / "none.json", [GalleryRow("b", "B", "converted", 9.0)], ["a", "b"],
                    {"quick": False, "poses": 50})
    assert [r.model for r in first] == ["b"]  # no earlier run: the page lists this run's rows alone
