"""Tests of o2m.validate.dynamics on a small model built here and converted by o2m.

The OpenSim model (built with the API, Y up): ground -> link (PinJoint "swing" about z at the
origin; 1 kg, 0.4 m, centre of mass at its middle), hanging down from the pivot. Two
Thelen2003Muscles, "lift" (ground above and beside the pivot -> the link's tip, pulls the link
up and out) and "hold" (the other side), so random excitations swing it both ways.
"""

from __future__ import annotations

import numpy as np
import opensim as osim
import pytest

from o2m.cli import main
from o2m.convert.converter import convert
from o2m.osim.simulate import IntegratorSettings
from o2m.osim.storage import write_sto
from o2m.validate.dynamics import DynamicsReport, compare_dynamics
from tests.helpers import convert_options

osim.Logger.setLevelString("error")

#: Two muscles on the pendulum: name -> (ground point, link point), m, OpenSim frames.
MUSCLES = {"lift": ((0.25, 0.1, 0.0), (0.0, -0.4, 0.0)), "hold": ((-0.25, 0.1, 0.0), (0.0, -0.4, 0.0))}


def _pendulum(path) -> str:
    model = osim.Model()
    model.setName("pendulum")
    link = osim.Body("link", 1.0, osim.Vec3(0, -0.2, 0), osim.Inertia(0.015, 0.001, 0.015))
    model.addBody(link)
    pin = osim.PinJoint("swing", model.getGround(), osim.Vec3(0), osim.Vec3(0), link, osim.Vec3(0), osim.Vec3(0))
    pin.upd_coordinates(0).setName("swing")
    pin.upd_coordinates(0).setRangeMin(-1.5)
    pin.upd_coordinates(0).setRangeMax(1.5)
    model.addJoint(pin)
    for name, (origin, insertion) in MUSCLES.items():
        # 100 N, optimal fibre 0.3 m, tendon slack 0.2 m: paths are about 0.5 m at rest
        muscle = osim.Thelen2003Muscle(name, 100.0, 0.3, 0.2, 0.0)
        muscle.addNewPathPoint(f"{name}_origin", model.getGround(), osim.Vec3(*origin))
        muscle.addNewPathPoint(f"{name}_insertion", link, osim.Vec3(*insertion))
        model.addForce(muscle)
    model.finalizeConnections()
    out = str(path / "pendulum.osim")
    model.printToXML(out)
    return out


@pytest.fixture(scope="module")
def pendulum(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pendulum")
    osim_path = _pendulum(folder)
    xml = convert(osim_path, folder / "mj", convert_options()).xml
    return osim_path, str(xml)


def test_opensim_and_mujoco_agree_on_random_excitations(pendulum):
    """Three random sets of 0.5 s (seed 1): OpenSim swings the pendulum 0.33 rad, not at all
    (no muscle active) and 1.1 rad; MuJoCo follows (measured: mean 0.039 rad, max 0.12 rad,
    what is left of Thelen's muscle in MuJoCo's muscle model)."""
    rep = compare_dynamics(*pendulum, n_sets=3, duration=0.5, seed=1, max_workers=2, progress=False)
    assert isinstance(rep, DynamicsReport)
    assert rep.coordinates == ["swing"] and rep.rotational.tolist() == [True]
    assert rep.status == ["ok"] * 3 and rep.compared().all() and not rep.mujoco_diverged.any()
    assert rep.opensim.shape == rep.mujoco.shape == (3, 250, 1)
    assert np.array_equal(rep.mujoco[:, 0], rep.opensim[:, 0])  # MuJoCo starts from OpenSim's first sample
    swing = np.ptp(rep.opensim, axis=1).max()
    assert swing > 0.1
    assert rep.mean_error()[0] < 0.06 and rep.max_error()[0] < 0.16, rep.summary()
    assert "swing" in rep.summary() and "OpenSim ok" in rep.summary()
    assert rep.path_flips == [] and "do not: none" in rep.summary()  # a straight path never jumps


def test_a_failed_or_timed_out_opensim_run_is_reported_not_raised(pendulum):
    failed = compare_dynamics(*pendulum, n_sets=1, duration=0.1, settings=IntegratorSettings(method="NoSuchMethod"),
                              max_workers=1, progress=False)
    assert failed.status == ["failed"] and "NoSuchMethod" in failed.reasons[0]
    assert not failed.compared().any() and np.isnan(failed.mean_error()).all()
    assert np.isfinite(failed.mujoco).all()  # MuJoCo still ran, from the default pose
    assert "OpenSim failed" in failed.summary()
    # 60 s of motion against a 1-s wall-clock limit: stopped, compared up to where it got
    slow = compare_dynamics(*pendulum, n_sets=1, duration=60.0, timeout=1.0, max_workers=1, progress=False)
    assert slow.status == ["timeout"] and "wall-clock limit" in slow.reasons[0]
    reached = np.isfinite(slow.opensim[0, :, 0])
    assert reached[0] and not reached[-1]
    assert np.isfinite(slow.final_error()).all()
    assert "OpenSim timeout" in slow.summary()


def test_a_controls_file_drives_both_and_sets_the_initial_pose(pendulum, tmp_path):
    t = np.linspace(0.0, 0.3, 31)
    controls = tmp_path / "controls.sto"
    write_sto(controls, t, ["/forceset/lift", "swing", "unrelated"],
              np.stack([np.full_like(t, 0.8), np.full_like(t, 0.3), np.zeros_like(t)], axis=1))
    rep = compare_dynamics(*pendulum, motion=controls, max_workers=1, progress=False)
    assert rep.labels == ["controls.sto"] and rep.status == ["ok"]
    assert rep.opensim[0, 0, 0] == pytest.approx(0.3)  # the coordinate column's first row
    assert rep.times[-1] == pytest.approx(0.3)
    assert rep.opensim[0, -1, 0] > 0.3 + 0.05  # lift, excited, swings the link up (positive about z)


def test_cli_validate_dynamics(pendulum, tmp_path, capsys):
    png = tmp_path / "dyn.png"
    assert main(["validate", "--dynamics", *pendulum, "--sets", "1", "--duration", "0.2", "--workers", "1",
                 "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "swing" in out and "mean abs" in out and png.stat().st_size > 1000
    bad = tmp_path / "bad.sto"
    write_sto(bad, np.array([0.0, 0.1]), ["nothing"], np.zeros((2, 1)))
    assert main(["validate", "--dynamics", *pendulum, "--motion", str(bad)]) == 1
    assert "no column names a muscle or coordinate" in capsys.readouterr().err
    degrees = tmp_path / "degrees.sto"
    write_sto(degrees, np.array([0.0]), ["swing"], np.array([[10.0]]), in_degrees=True)
    assert main(["validate", "--dynamics", *pendulum, "--initial-state", str(degrees)]) == 1
    assert "inDegrees=yes" in capsys.readouterr().err


def test_report_arithmetic_on_known_trajectories():
    """Errors, final errors and time outside the range on hand-made trajectories (no simulation)."""
    t = np.arange(4) * 0.1
    opensim = np.array([[[0.0, 0.0], [0.1, 0.5], [0.2, 1.5], [np.nan, np.nan]],  # set 0 stops after 3 samples
                        [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]])
    mujoco = opensim + np.array([0.0, 0.1, 0.2, 0.3])[None, :, None] * np.array([1.0, -2.0])
    mujoco[1] = np.array([0.0, 0.1, 0.2, 0.3])[:, None] * np.array([1.0, -2.0])
    rep = DynamicsReport("toy", t, ["a", "b"], np.array([True, False]), opensim, mujoco, ["s0", "s1"],
                         ["timeout", "ok"], ["", ""], np.array([False, False]),
                         ranges=np.array([[-1.0, 1.0], [-1.0, 1.0]]))
    np.testing.assert_allclose(rep.final_error(), [[0.2, 0.4], [0.3, 0.6]])
    np.testing.assert_allclose(rep.mean_error(), [(0.1 + 0.2 + 0.1 + 0.2 + 0.3) / 7, 2 * 0.9 / 7])
    np.testing.assert_allclose(rep.max_error(), [0.3, 0.6])
    np.testing.assert_allclose(rep.outside_range(), [0.0, 1 / 7])  # b = 1.5 at one of 7 reached samples
    assert rep.mean_rotational_error() == pytest.approx(0.9 / 7)
    assert "14.3% of samples" in rep.summary()
    rep.path_flips = [{"tendon": "t1", "trajectory": 0, "mujoco": 0.002},
                      {"tendon": "t2", "trajectory": 1, "mujoco": 0.03},
                      {"tendon": "t1", "trajectory": 1, "mujoco": 0.004}]
    assert "do not: t2 (1 set(s), up to 30.0 mm), t1 (2 set(s), up to 4.0 mm)" in rep.summary()
    rep.rotational = np.array([False, False])  # a model that only translates: its mean in metres, not NaN rad
    assert "over translational coordinates: 0.1929 m" in rep.summary() and "nan" not in rep.summary()


def test_a_model_without_muscles_is_said_to_run_passive(tmp_path):
    """The corpus's double pendulum (two CoordinateActuators, no muscle): both simulators fall
    under gravity alike, and the summary says no muscle is driven."""
    from o2m.convert import ConvertOptions, convert
    from tests.helpers import model_file

    osim = model_file("opensim-models/Models/DoublePendulum/double_pendulum.osim")
    xml = convert(osim, tmp_path, ConvertOptions(quick=True)).xml
    rep = compare_dynamics(osim, xml, n_sets=1, duration=0.5, max_workers=1, progress=False)
    assert rep.driven_muscles == [] and "no muscle is driven" in rep.summary()
    assert rep.mean_rotational_error() < 0.01, rep.summary()
