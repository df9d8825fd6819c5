"""OpenSim's side of the muscle fit (o2m.convert.muscle_samples): the bench reproduces the full
model's static tendon forces, and an island of lengths OpenSim reaches only through a step is
told from a steep but continuous tail."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from o2m.convert.muscle_samples import ISLAND_LINE_STEPS, _Bench, _muscle_elements, length_island
from tests.helpers import model_file


@pytest.fixture(scope="module")
def arm26() -> Path:
    return model_file("opensim-models/Models/Arm26/arm26.osim")


def test_bench_equals_full_model(arm26):
    """OpenSim's static tendon force on the bench (a straight path of the same MTU length) equals
    the full model's at random poses, at activation 1 and 0."""
    import opensim

    from o2m.osim.document import load_document

    opensim.Logger.setLevelString("error")
    model = opensim.Model(str(arm26))
    state = model.initSystem()
    muscles = [model.getMuscles().get(i) for i in range(model.getMuscles().getSize())]
    names = [m.getName() for m in muscles]
    doc = load_document(arm26)
    elements = _muscle_elements(doc, names)
    bench = _Bench(doc, [elements[n] for n in names])
    cs = model.getCoordinateSet()
    coords = [cs.get(i) for i in range(cs.getSize())]
    rng = np.random.default_rng(7)
    for _ in range(4):
        st = opensim.State(state)
        for c in coords:
            c.setValue(st, float(rng.uniform(c.getRangeMin(), c.getRangeMax())), False)
            c.setSpeedValue(st, 0.0)
        model.assemble(st)
        for a in (1.0, 0.0):
            for m in muscles:
                m.setActivation(st, a)
            model.equilibrateMuscles(st)
            model.realizeDynamics(st)
            full = np.array([m.getTendonForce(st) for m in muscles])
            lengths = np.array([[m.getLength(st)] for m in muscles])
            on_bench, _ = bench.forces(lengths, a)
            np.testing.assert_allclose(on_bench[:, 0], full, rtol=1e-6, atol=1e-6)


def _delp_static_force(opensim, m, length: float, a: float) -> float:
    """Delp1990's static tendon force (N) at MTU ``length`` (m) and activation ``a``, solved from
    its curves: tendon force = (a fal + fp) x cos(pennation) at constant fiber width."""
    from scipy.optimize import brentq

    def curve(name):
        fn = opensim.Function.safeDownCast(m.getPropertyByName(name).getValueAsObject())
        return lambda x: fn.calcValue(opensim.Vector(1, float(x)))

    fal, fp, ft = curve("active_force_length_curve"), curve("passive_force_length_curve"), curve(
        "tendon_force_length_curve")
    lopt, lts = m.getOptimalFiberLength(), m.getTendonSlackLength()
    w = lopt * math.sin(m.getPennationAngleAtOptimalFiberLength())

    def tendon(lf):
        strain = (length - math.sqrt(lf * lf - w * w)) / lts - 1.0
        return ft(strain) if strain >= 0 else 0.0

    def residual(lf):
        fiber = max(a * fal(lf / lopt), 0.0) + max(fp(lf / lopt), 0.0)
        return tendon(lf) - fiber * math.sqrt(lf * lf - w * w) / lf

    return m.getMaxIsometricForce() * tendon(brentq(residual, max(1.0001 * w, 0.05 * lopt), 1.5 * length))


def test_bench_reads_delp1990_forces_opensim_cannot_give_through_its_dynamics(arm26, tmp_path):
    """Delp1990Muscle_Deprecated has no muscle dynamics in OpenSim 4.6 (getTendonForce raises
    "calcActiveForce() NOT IMPLEMENTED"); the bench reads the force its static equilibrium leaves
    in the actuation. It equals the equilibrium solved here from the muscle's own curves, to
    OpenSim's tolerance (0.01 N)."""
    import opensim

    from o2m.osim.document import load_document

    opensim.Logger.setLevelString("error")
    tag = "Delp1990Muscle_Deprecated"
    text = arm26.read_text().replace("<Thelen2003Muscle ", f"<{tag} ").replace("</Thelen2003Muscle>", f"</{tag}>")
    (tmp_path / "delp.osim").write_text(text)
    doc = load_document(tmp_path / "delp.osim")
    names = ["TRIlong", "BICshort"]  # pennated and not
    elements = _muscle_elements(doc, names)
    bench = _Bench(doc, [elements[n] for n in names])
    for m in bench.muscles:
        with pytest.raises(RuntimeError, match="NOT IMPLEMENTED"):
            m.getTendonForce(bench.state)
    lengths = np.array([[m.getTendonSlackLength() + m.getOptimalFiberLength() * x for x in np.linspace(0.5, 1.7, 7)]
                        for m in bench.muscles])
    for a in (1.0, 0.0):
        forces, _ = bench.forces(lengths, a)
        expected = [[_delp_static_force(opensim, m, x, a) for x in lengths[k]] for k, m in enumerate(bench.muscles)]
        np.testing.assert_allclose(forces, expected, atol=0.02)
        assert np.ptp(forces) > 100  # (not all slack)


def _island_of(length, n=400, seed=0):
    """length_island over ``n`` uniform poses of the unit square for a length function ``length(q)``
    (q (k, 2) -> (k,) m)."""
    poses = np.random.default_rng(seed).uniform(0.0, 1.0, size=(n, 2))

    def along(a, b):
        t = np.linspace(0.0, 1.0, ISLAND_LINE_STEPS + 1)[:, None]
        return length(a + t * (b - a))

    return poses, length(poses), length_island(poses, length(poses), along)


def test_an_island_reached_through_a_step_is_found():
    """A length that steps up by 0.15 m in a thin corner of the poses (as OpenSim's wrap taking a
    path the long way round for a moment) leaves a gap in the sorted lengths: those samples are
    an island, and the rest keeps its own range."""
    def length(q):
        return 0.1 + 0.05 * q[:, 0] + 0.15 * (q[:, 1] > 0.995)

    poses, lengths, island = _island_of(length)
    corner = np.flatnonzero(poses[:, 1] > 0.995)
    assert 1 <= len(corner) <= 8, len(corner)
    assert island is not None
    assert sorted(island["index"]) == sorted(corner)
    assert island["step"] == pytest.approx(0.15, abs=0.01)
    assert island["rest"][1] < 0.151


def test_a_steep_continuous_tail_is_no_island(monkeypatch):
    """The same corner reached by a steep ramp instead of a step leaves a like gap in the sorted
    lengths, but OpenSim's length takes every value in between along the lines: kept."""
    import o2m.convert.muscle_samples as samples

    def length(q):
        return 0.1 + 0.05 * q[:, 0] + 0.15 * np.clip((q[:, 1] - 0.99) / 0.005, 0.0, 1.0)

    assert _island_of(length)[2] is None
    monkeypatch.setattr(samples, "ISLAND_STEP", 0.0)  # the gap alone would make it one
    island = _island_of(length)[2]
    assert island is not None and island["gap"] > 0.05 and island["step"] < 0.01, island


def test_an_island_at_the_short_end_and_too_few_samples():
    def length(q):
        return 0.3 + 0.05 * q[:, 0] - 0.2 * (q[:, 1] < 0.004)

    poses, _, island = _island_of(length)
    assert island is not None and set(island["index"]) == set(np.flatnonzero(poses[:, 1] < 0.004))
    assert _island_of(length, n=40)[2] is None  # 2 % of 40 samples is under one


def test_lengthranges_leave_out_path_failures_and_name_them():
    """A sample whose OpenSim path fails as a path (here a loop and a length not of its drawn
    path) is left out of the lengthrange; the note counts each kind."""
    from o2m.convert.muscle_samples import FAILURE_TESTS, LengthSamples, _lengthranges

    lengths = np.array([[0.10], [0.12], [0.30], [0.11], [0.25]])
    failures = np.zeros((5, 1), dtype=np.int8)
    failures[2, 0], failures[4, 0] = FAILURE_TESTS["loop"], FAILURE_TESTS["inconsistent"]
    lr, notes = _lengthranges(LengthSamples(np.zeros((5, 1)), lengths, failures, 0), [0], ["m"])
    assert tuple(lr[0]) == (0.10, 0.12)
    assert notes["m"] == ["2 sampled pose(s) left out of the lengthrange where OpenSim's path fails as a path "
                          "(1 loop, 1 length not of its drawn path; o2m.osim.spikes)"]
    # a path that fails at every pose keeps its lengths (the fit needs some), and says so
    lr, notes = _lengthranges(LengthSamples(np.zeros((5, 1)), lengths, np.full((5, 1), 4, np.int8), 0), [0], ["m"])
    assert tuple(lr[0]) == (0.10, 0.30) and "at every sampled pose" in notes["m"][0], notes
