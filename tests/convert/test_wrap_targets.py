"""The wrap fit's targets (:mod:`o2m.convert.wrap_targets`): which samples OpenSim's own failures
leave out. On the poses that get moment arms every sample the converted model misses by over
:data:`~o2m.osim.spikes.SPIKE_TOL` is tested; on the lengths-only (validation) poses only those it
misses by over :data:`~o2m.osim.spikes.BAND_GATE` of the length, and a flagged sample is no target."""
from __future__ import annotations

import numpy as np
import pytest
from lxml import etree

from o2m.convert.converter import convert
from o2m.convert.wrap_targets import fit_targets
from tests.helpers import arm_path_actuator, convert_options, pin_pendulum


@pytest.fixture(scope="module")
def pendulum(tmp_path_factory):
    """A pin pendulum with one straight PathActuator "m" (about 0.5 m long), converted; and the
    same MJCF with the tendon's first site moved 5 mm (``near``: every pose off by more than
    SPIKE_TOL, under 5 %) and 10 cm (``far``: every pose over 5 % off)."""
    folder = tmp_path_factory.mktemp("targets")
    osim_path = folder / "pendulum.osim"
    m, arm = pin_pendulum("pendulum", (-1.0, 1.5))
    m.addForce(arm_path_actuator(m, arm, "P3"))
    m.finalizeConnections()
    m.initSystem()
    m.printToXML(str(osim_path))
    conv = convert(osim_path, folder / "out", convert_options(fit_wraps=False, fit_mechanics=False))
    moved = {}
    for name, shift in (("near", 0.005), ("far", 0.1)):
        root = etree.fromstring(conv.xml.read_bytes())
        first = root.find(".//spatial[@name='m']/site").get("site")
        site = root.find(f".//site[@name='{first}']")
        pos = np.array([float(v) for v in site.get("pos", "0 0 0").split()]) + [shift, 0.0, 0.0]
        site.set("pos", " ".join(repr(float(v)) for v in pos))
        moved[name] = folder / f"{name}.xml"
        moved[name].write_text(etree.tostring(root, encoding="unicode"))
    return osim_path, moved["near"], moved["far"]


def _recorder(monkeypatch, flag_first: int):
    """Replace OpenSim's failure tests by one that records what it is asked and flags every muscle
    it is given at the first ``flag_first`` calls."""
    calls: list[tuple[list[int], list[int]]] = []

    def fake(pair, values, muscles, lengths=None, banded=()):
        calls.append(([int(i) for i in muscles], [int(i) for i in banded]))
        return {int(i): {"test": "fake"} for i in muscles} if len(calls) <= flag_first else {}

    monkeypatch.setattr("o2m.osim.spikes.opensim_failures", fake)
    return calls


def test_lengths_only_poses_test_the_far_off_samples_and_leave_out_the_failures(pendulum, monkeypatch):
    osim_path, _, far = pendulum
    calls = _recorder(monkeypatch, flag_first=2)
    _, targets = fit_targets(str(osim_path), str(far), ["m"], 6, 0, n_arms=0)
    assert len(calls) == 6
    assert all(muscles == banded == [0] for muscles, banded in calls), calls  # the one path, far off at every pose
    assert targets["m"]["spikes"] == 2 and len(targets["m"]["qpos"]) == 4
    assert np.all(np.isnan(targets["m"]["arm"]))  # lengths only


def test_lengths_only_poses_leave_a_near_sample_untested(pendulum, monkeypatch):
    osim_path, near, _ = pendulum
    calls = _recorder(monkeypatch, flag_first=6)
    _, targets = fit_targets(str(osim_path), str(near), ["m"], 6, 0, n_arms=0)
    assert all(muscles == [] for muscles, _ in calls), calls
    assert targets["m"]["spikes"] == 0 and len(targets["m"]["qpos"]) == 6


def test_poses_with_moment_arms_test_every_sample_off_by_over_the_spike_tolerance(pendulum, monkeypatch):
    osim_path, near, _ = pendulum
    calls = _recorder(monkeypatch, flag_first=1)
    _, targets = fit_targets(str(osim_path), str(near), ["m"], 3, 0)
    assert [muscles for muscles, _ in calls] == [[0]] * 3  # near: over SPIKE_TOL, not banded
    assert [banded for _, banded in calls] == [[]] * 3
    assert targets["m"]["spikes"] == 1 and np.isfinite(targets["m"]["arm"]).all()
