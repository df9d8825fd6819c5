"""The notebooks: what the builder writes, stored with the clean outputs of a full run, and
still running top to bottom on a fresh kernel in quick mode (O2M_QUICK=1)."""

from __future__ import annotations

import base64
import importlib.util
import io
import os
import re
from pathlib import Path

import nbformat
import pytest

from tests.helpers import require_models

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))

MAX_TOTAL_BYTES = 1_500_000
"""All committed notebooks together (a full run stores about 0.6 MB)."""
MAX_IMAGE_BYTES = 200_000
"""One stored PNG (the largest, a paper figure, is about 60 kB)."""
MACHINE_PATH = re.compile(r"(?<![\w.~$])(?:/(?:home|root|tmp|work|Users|usr|opt|var|mnt|srv)/|[A-Za-z]:\\\\)")
"""An absolute path of the machine that ran the notebook (outputs must use relative ones)."""


def _builder():
    spec = importlib.util.spec_from_file_location("build_notebooks", ROOT / "tools" / "build_notebooks.py")
    builder = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(builder)
    return builder


def _code_cells(nb) -> list:
    return [c for c in nb.cells if c.cell_type == "code"]


def _output_text(output) -> str:
    """The text of one output (stream text, or every text/* representation)."""
    if "text" in output:
        return "".join(output.text)
    return "".join("".join(v) for k, v in output.get("data", {}).items() if k.startswith("text/"))


def test_notebooks_are_numbered():
    assert [p.name[:2] for p in NOTEBOOKS] == [f"{i:02d}" for i in range(1, 7)]


def test_notebooks_are_what_the_builder_writes(tmp_path):
    """The committed notebooks' cells equal what tools/build_notebooks.py writes (edit the builder, not the .ipynb)."""
    built = _builder().build(tmp_path)
    assert sorted(p.name for p in built) == [p.name for p in NOTEBOOKS]
    for path in built:
        fresh, committed = (nbformat.read(p, as_version=4) for p in (path, ROOT / "notebooks" / path.name))
        assert [(c.cell_type, c.id, c.source) for c in fresh.cells] == \
            [(c.cell_type, c.id, c.source) for c in committed.cells], \
            f"{path.name}: rebuild it with python tools/build_notebooks.py --execute"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_committed_notebook_holds_the_clean_outputs_of_one_run(path):
    """Every code cell ran, in order, without error; figures and 3-D scenes are there; outputs
    name no machine path and carry no timing metadata."""
    nb = nbformat.read(path, as_version=4)
    cells = _code_cells(nb)
    assert [c.execution_count for c in cells] == list(range(1, len(cells) + 1)), \
        f"{path.name}: not one top-to-bottom run; run python tools/build_notebooks.py --execute"
    assert set(nb.metadata) == {"kernelspec"}
    for cell in cells:
        kinds = {o.output_type for o in cell.outputs}
        mimes = {m for o in cell.outputs for m in o.get("data", {})}
        assert "error" not in kinds, f"{path.name} cell {cell.id} stored an error"
        assert "execution" not in cell.metadata, f"{path.name} cell {cell.id}: timing metadata"
        if "plt.show()" in cell.source or "display(Image" in cell.source:
            assert "image/png" in mimes, f"{path.name} cell {cell.id}: the figure is missing"
        if "notebook_iframe(" in cell.source:
            html = "".join(_output_text(o) for o in cell.outputs)
            assert re.search(r'<iframe[^>]*src="(?!/)[^"]+\.html"', html), f"{path.name} cell {cell.id}: no iframe"
        for output in cell.outputs:
            found = MACHINE_PATH.search(_output_text(output))
            assert not found, f"{path.name} cell {cell.id}: machine path {_output_text(output)[found.start():][:80]!r}"
            assert str(ROOT) not in _output_text(output)


def test_committed_notebooks_are_small_enough_to_review():
    assert sum(p.stat().st_size for p in NOTEBOOKS) < MAX_TOTAL_BYTES
    for path in NOTEBOOKS:
        for cell in _code_cells(nbformat.read(path, as_version=4)):
            for output in cell.outputs:
                png = output.get("data", {}).get("image/png")
                assert png is None or len(base64.b64decode(png)) < MAX_IMAGE_BYTES, f"{path.name} cell {cell.id}"


def test_normalise_makes_a_run_reproducible():
    """Timing metadata goes, counts become 1, 2, ..., machine paths relative, PNGs small and paletted."""
    from PIL import Image

    builder = _builder()
    image = Image.new("RGBA", (2000, 500), (255, 255, 255, 0))
    image.paste((200, 30, 30, 255), (100, 100, 1900, 400))
    raw = io.BytesIO()
    image.save(raw, format="PNG")
    png = base64.b64encode(raw.getvalue()).decode()
    nb = nbformat.v4.new_notebook(metadata={"language_info": {"name": "python", "version": "3.11.7"}})
    timing = {"execution": {"iopub.status.idle": "2026-12-03T09:00:00Z"}}
    nb.cells = [nbformat.v4.new_code_cell("print(DATA)", execution_count=7, metadata=timing,
                                          outputs=[nbformat.v4.new_output("stream", text="/repo/data /c/x.osim\n")]),
                nbformat.v4.new_code_cell("plt.show()", execution_count=9,
                                          outputs=[nbformat.v4.new_output("display_data", data={"image/png": png})])]
    builder.normalise(nb, {"/repo": ".", "/c": "$O2M_CACHE"})
    assert set(nb.metadata) == {"kernelspec"}
    assert [c.execution_count for c in nb.cells] == [1, 2] and "execution" not in nb.cells[0].metadata
    assert nb.cells[0].outputs[0].text == "./data $O2M_CACHE/x.osim\n"
    small = Image.open(io.BytesIO(base64.b64decode(nb.cells[1].outputs[0].data["image/png"])))
    assert small.mode == "P" and small.width == builder.MAX_IMAGE_WIDTH
    assert small.convert("RGB").getpixel((0, 0)) == (255, 255, 255)  # transparency on white, not black
    again = nbformat.from_dict(nb)
    builder.normalise(again, {"/repo": "."})
    assert again == nb


def test_a_rebuild_keeps_the_outputs_of_unchanged_cells(tmp_path):
    builder = _builder()
    [first, *_] = builder.build(tmp_path)
    nb = nbformat.read(first, as_version=4)
    code = _code_cells(nb)
    code[0].outputs = [nbformat.v4.new_output("stream", text="kept\n")]
    code[0].execution_count = 1
    code[1].source += "\n# edited"
    code[1].outputs = [nbformat.v4.new_output("stream", text="stale\n")]
    nbformat.write(nb, first)
    builder.build(tmp_path)
    rebuilt = _code_cells(nbformat.read(first, as_version=4))
    assert rebuilt[0].outputs[0].text == "kept\n" and rebuilt[0].execution_count == 1
    assert rebuilt[1].outputs == [] and rebuilt[1].execution_count is None


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs_in_quick_mode(path, monkeypatch):
    require_models()
    if not (ROOT / "data" / "mobl_arms" / "opensim.npz").exists():
        pytest.skip("no stored dataset")
    from nbclient import NotebookClient

    monkeypatch.setenv("O2M_QUICK", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(path, as_version=4)
    NotebookClient(nb, timeout=900, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}}).execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if o.output_type == "error"]
    assert not errors
    assert os.environ["O2M_QUICK"] == "1"
