"""OpenSim's log: silent on the terminal by default, and into a file inside ``opensim_log``; the
intervals coordinates are sampled over."""

from __future__ import annotations

import re

from o2m.convert import convert
from o2m.osim import runtime
from o2m.validate import compare_kinematics
from tests.helpers import convert_options, model_file

#: A line of OpenSim's console log ("[info] Loaded model ...", "[warning] ..."); ANSI colours allowed.
OPENSIM_LINE = re.compile(r"^\W*\[(?:\x1b\[[0-9;]*m)?(trace|debug|info|warning|error|critical)", re.M)

ARM26 = "opensim-models/Models/Arm26/arm26.osim"


def test_a_conversion_and_a_comparison_print_nothing_from_opensim(tmp_path, capfd):
    osim = model_file(ARM26)
    result = convert(osim, tmp_path / "arm26", convert_options())
    compare_kinematics(osim, result.xml, n_poses=3, seed=0, progress=False)
    out, err = capfd.readouterr()
    assert not OPENSIM_LINE.search(out + err), (out + err)[:2000]


def test_opensim_log_sends_opensims_lines_to_the_file_and_python_still_prints(tmp_path, capfd):
    osim = model_file(ARM26)
    log_file = tmp_path / "logs" / "opensim.log"
    with runtime.opensim_log(log_file) as path:
        runtime.load_model(osim)
        print("python prints reach the terminal")
    out, err = capfd.readouterr()
    assert path == log_file
    assert "python prints reach the terminal" in out
    assert not OPENSIM_LINE.search(out + err), (out + err)[:2000]
    text = log_file.read_text()
    assert "Loaded model" in text and "arm26" in text
    assert runtime.opensim().Logger.getLevelString() == "Error"  # restored after the block


def test_a_nested_opensim_log_gives_the_outer_block_its_level_back(tmp_path, capfd):
    osim = model_file(ARM26)
    outer, inner = tmp_path / "outer.log", tmp_path / "inner.log"
    with runtime.opensim_log(outer):
        with runtime.opensim_log(inner):
            runtime.load_model(osim)
        runtime.load_model(osim)  # still at the outer block's info level, into the outer file
    assert "Loaded model" in inner.read_text() and "Loaded model" in outer.read_text()
    assert runtime.opensim().Logger.getLevelString() == "Error"
    out, err = capfd.readouterr()
    assert not OPENSIM_LINE.search(out + err)


def test_opensim_log_restores_the_terminal_after_an_error(tmp_path, capfd):
    osim = model_file(ARM26)
    try:
        with runtime.opensim_log(tmp_path / "opensim.log"):
            raise KeyError("inside")
    except KeyError:
        pass
    runtime.load_model(osim)  # at error level again: nothing to print
    print("after the block")
    out, err = capfd.readouterr()
    assert "after the block" in out and not OPENSIM_LINE.search(out + err)


def test_a_simulation_worker_appends_opensims_log_to_the_named_file(tmp_path, capfd):
    import numpy as np

    from o2m.osim.simulate import run_isolated

    muscles = ["TRIlong", "BIClong"]
    times = np.linspace(0.0, 0.004, 3)
    log_file = tmp_path / "opensim.log"
    run = run_isolated(model_file(ARM26), times, np.full((3, 2), 0.1), muscles, opensim_log=log_file, timeout=120)
    out, err = capfd.readouterr()
    assert run.ok, run.reason
    assert "Loaded model" in log_file.read_text()
    assert not OPENSIM_LINE.search(out + err)


def test_a_rotation_wider_than_a_turn_is_sampled_over_the_turn_round_its_default():
    """OpenSim's "unbounded" ±99999.9 on a pin (a public ball-joint test model's, sampled at
    -402607 rad once): one turn round the default value; a translation's range is kept, an
    infinite one becomes ±1 m, a range within a turn is kept."""
    import math

    from tests.helpers import pin_pendulum, slider_model

    m, _ = pin_pendulum("wide", q_range=(-99999.9, 99999.9))
    c = m.updCoordinateSet().get(0)
    c.setDefaultValue(0.5)
    lo, hi = runtime.sample_bounds(c)
    assert (lo, hi) == (0.5 - math.pi, 0.5 + math.pi)
    c.setRangeMin(-1.0)
    c.setRangeMax(1.5)
    assert runtime.sample_bounds(c) == (-1.0, 1.5)
    m, _ = slider_model("far")
    c = m.updCoordinateSet().get(0)
    c.setRangeMin(-99999.9)
    c.setRangeMax(99999.9)
    assert runtime.sample_bounds(c) == (-99999.9, 99999.9)
    c.setRangeMin(-math.inf)
    assert runtime.sample_bounds(c) == (-1.0, 99999.9)
