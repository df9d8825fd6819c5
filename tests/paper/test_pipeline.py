"""Pieces of the paper's pipeline that need no dataset: the corrections' cache key and cache."""

from __future__ import annotations

import copy
from dataclasses import replace
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

from o2m.mj.simulate import initial_state
from o2m.paper.model_key import model_values, same_values
from o2m.paper.pipeline import FULL, QUICK, correct_sets, correction_key, load_fresh_experiment
from tests.helpers import MUSCLE_PENDULUM

MODEL = """
<mujoco><worldbody><body><joint name="j" type="hinge" damping="{d}"/><geom size="0.1" mass="1"/></body></worldbody>
</mujoco>"""


def test_correction_key_changes_with_the_model_structure_sets_or_budget():
    m = mujoco.MjModel.from_xml_string(MODEL.format(d=0.5))
    key = correction_key(m, [1, 2], FULL, True)
    assert correction_key(copy.copy(m), [1, 2], FULL, True) == key
    other = copy.copy(m)
    other.jnt_limited[0] = 1  # the structure: not a float value (those are compared within rounding)
    assert correction_key(other, [1, 2], FULL, True) != key
    assert correction_key(m, [1, 3], FULL, True) != key
    assert correction_key(m, [1, 2], QUICK, True) != key
    assert correction_key(m, [1, 2], FULL, False) != key
    assert correction_key(m, [1, 2], FULL, True, method="lm") != key


def test_correction_key_does_not_depend_on_the_folder_of_the_model(tmp_path):
    """MuJoCo keeps a mesh's file path, absolute: the same model in another folder (another
    clone's out/) has the same key and values; a mesh changed is another model."""
    xml = ('<mujoco><asset><mesh name="m" file="box.obj"/></asset><worldbody><body><joint type="hinge"/>'
           '<geom type="mesh" mesh="m" mass="1"/></body></worldbody></mujoco>')
    keys = []
    for folder, size in (("a", 0.1), ("b", 0.1), ("c", 0.2)):
        (tmp_path / folder).mkdir()
        corners = [(x, y, z) for x in (0, size) for y in (0, size) for z in (0, size)]
        faces = ["1 2 4 3", "5 7 8 6", "1 5 6 2", "3 4 8 7", "1 3 7 5", "2 6 8 4"]
        (tmp_path / folder / "box.obj").write_text("".join(f"v {x} {y} {z}\n" for x, y, z in corners)
                                                   + "".join(f"f {f}\n" for f in faces))
        (tmp_path / folder / "model.xml").write_text(xml)
        m = mujoco.MjModel.from_xml_path(str(tmp_path / folder / "model.xml"))
        assert str(tmp_path / folder) in m.paths.decode(errors="replace")
        keys.append((correction_key(m, [1, 2], FULL, True), model_values(m)))
    assert keys[0][0] == keys[1][0] and same_values(keys[0][1], keys[1][1])
    assert keys[2][0] != keys[0][0] or not same_values(keys[0][1], keys[2][1])




def test_corrections_computed_equal_corrections_loaded_from_the_cache(tmp_path):
    model = mujoco.MjModel.from_xml_string(MUSCLE_PENDULUM)
    n_t = 60
    excitation = 0.3 + 0.2 * np.sin(np.linspace(0, 6, n_t))[None, :, None]  # (1, T, 1)
    reference = np.linspace(0.3, 0.1, n_t)[None, :, None]
    exp = SimpleNamespace(init=initial_state(model, {"swing": 0.3})[None], muscles=["lifter"], dofs=["swing"],
                          dataset=SimpleNamespace(activations=SimpleNamespace(values=excitation)), reference=reference)
    settings = replace(QUICK, correction_generations=2, correction_sweeps=1)
    cache = tmp_path / "corrections.npz"
    computed = correct_sets(exp, model, [0], settings=settings, force_start=False, progress=False, cache=cache)
    loaded = correct_sets(exp, model, [0], settings=settings, force_start=False, progress=False, cache=cache)
    for a, b in zip(computed, loaded, strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    # another method is another key: the cache is recomputed, then reused
    with pytest.warns(UserWarning, match="budget"):
        lm = correct_sets(exp, model, [0], settings=settings, force_start=False, progress=False, cache=cache,
                          method="lm")
    assert not np.array_equal(lm[0], computed[0])
    lm_loaded = correct_sets(exp, model, [0], settings=settings, force_start=False, progress=False, cache=cache,
                             method="lm")
    for a, b in zip(lm, lm_loaded, strict=True):
        assert np.array_equal(a, b)


def test_corrections_cache_holds_for_the_model_rounded_otherwise_not(tmp_path, monkeypatch):
    """The same model up to rounding (a value 1e-12 off, as another machine's conversion) finds
    the cached corrections; a value 1e-3 off computes them again."""
    from o2m.paper import corrections

    calls = []
    real = corrections.fit_corrections
    monkeypatch.setattr(corrections, "fit_corrections", lambda *a, **k: calls.append(1) or real(*a, **k))
    model = mujoco.MjModel.from_xml_string(MUSCLE_PENDULUM)
    n_t = 40
    exp = SimpleNamespace(init=initial_state(model, {"swing": 0.3})[None], muscles=["lifter"], dofs=["swing"],
                          dataset=SimpleNamespace(activations=SimpleNamespace(values=np.full((1, n_t, 1), 0.4))),
                          reference=np.linspace(0.3, 0.1, n_t)[None, :, None])
    settings = replace(QUICK, correction_generations=1, correction_sweeps=1)
    cache = tmp_path / "corrections.npz"
    first = correct_sets(exp, model, [0], settings=settings, force_start=False, progress=False, cache=cache)
    assert len(calls) == 1
    rounded = copy.copy(model)
    rounded.body_mass[1] *= 1 + 1e-12
    again = correct_sets(exp, rounded, [0], settings=settings, force_start=False, progress=False, cache=cache)
    assert len(calls) == 1 and np.array_equal(first[0], again[0])
    edited = copy.copy(model)
    edited.body_mass[1] *= 1 + 1e-3
    with pytest.warns(UserWarning, match="body_mass"):  # says why it takes minutes again
        correct_sets(exp, edited, [0], settings=settings, force_start=False, progress=False, cache=cache)
    assert len(calls) == 2


def test_no_fresh_experiment_without_the_fresh_dataset(tmp_path):
    assert load_fresh_experiment(tmp_path, tmp_path) is None
