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


def test_the_default_pose_keyframe_starts_each_muscle_at_opensims_default_activation(tmp_path):
    """Tug_of_War's two Thelen muscles start at activations 1 and 0.05 in OpenSim's default state
    (their default_activation); the 'default-pose' keyframe's act has the same, and the report says so."""
    import mujoco
    import numpy as np

    from o2m.convert import convert
    from tests.helpers import model_file

    osim = model_file("opensim-models/Models/Tug_of_War/Tug_of_War.osim")
    out = convert(osim, tmp_path, ConvertOptions(quick=True))
    m = mujoco.MjModel.from_xml_path(str(out.xml))
    act = m.key("default-pose").act
    starts = {m.actuator(a).name: act[m.actuator_actadr[a]] for a in range(m.nu) if m.actuator_actadr[a] >= 0}
    np.testing.assert_allclose([starts["muscle1"], starts["muscle2"]], [1.0, 0.05])
    assert any("keyframe's act" in n for n in out.report.notes)


def test_a_muscle_opensim_disables_applies_no_force(tmp_path):
    """Tug_of_War's muscle1 with appliesForce false: its actuator is in the group the model
    disables, so at full activation it pulls with nothing, as in OpenSim; muscle2 still pulls."""
    import mujoco

    from o2m.convert import convert
    from o2m.convert.tendons import DISABLED_MUSCLE_GROUP
    from tests.helpers import model_file

    text = model_file("opensim-models/Models/Tug_of_War/Tug_of_War.osim").read_text()
    start = text.index('<Thelen2003Muscle name="muscle1">') + len('<Thelen2003Muscle name="muscle1">')
    osim = tmp_path / "tug.osim"
    osim.write_text(text[:start] + "<appliesForce>false</appliesForce>" + text[start:])
    out = convert(osim, tmp_path / "out", ConvertOptions(quick=True))
    m = mujoco.MjModel.from_xml_path(str(out.xml))
    assert m.actuator("muscle1").group == DISABLED_MUSCLE_GROUP and m.opt.disableactuator & (1 << DISABLED_MUSCLE_GROUP)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("default-pose").id)
    d.act[:] = 1.0
    mujoco.mj_forward(m, d)
    assert d.actuator_force[m.actuator("muscle1").id] == 0.0
    assert d.actuator_force[m.actuator("muscle2").id] < -1.0
    assert any("muscle1" in n and "appliesForce false" in n for n in out.report.notes)
