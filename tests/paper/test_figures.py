"""The paper's figures come out of a small stored result set."""

from __future__ import annotations

import json

import numpy as np

from o2m.paper.figures import make_figures


def test_figures_from_stored_results(tmp_path):
    res = tmp_path / "results"
    res.mkdir()
    rng = np.random.default_rng(0)
    dofs, muscles = ["a", "b"], ["m1", "m2", "m3"]
    t = np.arange(50) * 0.002
    np.savez(res / "results.npz", dofs=dofs, muscles=muscles, test=[3, 5], times=t,
             err_converted=rng.random((2, 2)), err_fitted=rng.random((2, 2)) / 2, err_corrected=rng.random((2, 2)) / 4,
             correction_mae=rng.random((2, 3)) / 10, overlay_sets=[3], overlay_opensim=rng.random((1, 50, 2)),
             overlay_converted=rng.random((1, 50, 2)), overlay_fitted=rng.random((1, 50, 2)),
             overlay_corrected=rng.random((1, 50, 2)), err_paper_fitted=rng.random((2, 2)),
             err_paper_corrected=rng.random((1, 2)), paper_corrected_sets=[3],
             overlay_paper_fitted=rng.random((1, 50, 2)), overlay_paper_corrected=np.zeros((0, 50, 2)))
    (tmp_path / "speed.json").write_text(json.dumps({"opensim_median_s": 15.5, "mujoco_median_s": 0.025,
                                                     "ratio": 620.0}))
    written = make_figures(res, tmp_path / "figs")
    names = sorted(p.name for p in written)
    assert names == sorted(f"{n}.{e}" for n in ["joint_errors", "corrections_boxplot", "overlay_set003", "speed"]
                           for e in ["png", "pdf"])
    for p in written:
        assert p.stat().st_size > 1000
    # drawn again, every file is the same to the byte (no embedded dates): a rerun leaves git clean
    again = make_figures(res, tmp_path / "figs2")
    for a, b in zip(sorted(written), sorted(again), strict=True):
        assert a.read_bytes() == b.read_bytes(), a.name
        if a.suffix == ".pdf":
            assert b"/CreationDate" not in a.read_bytes(), a.name


def test_passive_forces_draws_each_force_over_the_angle():
    from o2m.paper.figures import passive_forces

    t = np.arange(100) * 0.01
    fig = passive_forces(t, np.sin(t), np.cos(t), {"a": np.cos(t) + 1, "b": np.zeros_like(t)}, title="x")
    top, bottom = fig.axes
    assert len(top.lines) == 3 and len(bottom.lines) == 1
    np.testing.assert_allclose(top.lines[1].get_ydata(), np.cos(t) + 1)
