"""``path_forces``: a MovingPathPoint next to a point of its own body, on a hand-built pendulum.

ground -> arm (PinJoint q, range [-1, 1.5] rad); two PathActuators from P1 on ground to P3 on the
arm (0.3, 0, 0) through a MovingPathPoint P2 on the arm whose x follows q by a quadratic
(exact in MuJoCo, whose slide equalities are quartics):

* "big": x = 0.1 + 0.03 q + 0.01 q^2 (the same-body segment P2-P3 varies by 24 % of the path),
* "small": x = 0.1 + 0.002 q (it varies by 1.3 %).

OpenSim 4.6 applies the tension only along P1-P2 (P2-P3 is on one body), so its
``computeMomentArm`` is ``-d|P1 P2|/dq`` while ``getLength`` is ``|P1 P2| + |P2 P3|``. Expected:
``path_forces="opensim"`` gives a tendon whose ``-dL/dq`` is ``computeMomentArm`` and whose length
is OpenSim's up to half the variation of ``|P2 P3|``; ``"kinematic"`` gives OpenSim's length and
``-dL/dq``; ``"auto"`` takes "opensim" for "small" and "kinematic" for "big".
"""

from __future__ import annotations

import mujoco
import numpy as np
import opensim as osim
import pytest

from o2m.convert.converter import convert
from o2m.mj.tendons import mujoco_moment_arms
from o2m.osim.pair import ModelPair
from o2m.validate.muscles import compare_muscles
from tests.helpers import add_three_point_paths, convert_options, pin_pendulum, with_moving_point

osim.Logger.setLevelString("error")

MOVING = {"big": "0.01 0.03 0.1", "small": "0.002 0.1"}  # PolynomialFunction coefficients, highest first


def _model(path) -> None:
    m, arm = pin_pendulum("moving_pendulum")
    add_three_point_paths(m, arm, MOVING)
    m.finalizeConnections()
    m.initSystem()
    m.printToXML(str(path))
    text = path.read_text()
    for name, coefs in MOVING.items():  # P2 made a MovingPathPoint along x
        text = with_moving_point(text, f"{name}-P2", "arm", (
            f"<PolynomialFunction><coefficients>{coefs}</coefficients></PolynomialFunction>",
            "<Constant><value>0.03</value></Constant>", "<Constant><value>0</value></Constant>"))
    path.write_text(text)


@pytest.fixture(scope="module")
def pendulum(tmp_path_factory):
    folder = tmp_path_factory.mktemp("moving")
    osim_path = folder / "moving.osim"
    _model(osim_path)
    convs = {mode: convert(osim_path, folder / mode,
                           convert_options(path_forces=mode, fit_wraps=False, fit_mechanics=False))
             for mode in ("opensim", "kinematic", "auto")}
    return osim_path, convs


def _sweep(osim_path, xml):
    """Per path over q: OpenSim getLength, computeMomentArm, -dL/dq; MuJoCo length and -dL/dq."""
    pair = ModelPair(osim_path, xml)
    names = [n for n, _, _ in pair.matched]
    qs = np.linspace(-0.95, 1.45, 25)
    out = {n: {k: [] for k in ("L_os", "cma", "dldq", "L_mj", "ma_mj")} for n in names}
    h = 1e-6
    for q in qs:
        st = pair.os_state({"q": q})
        up, dn = pair.os_lengths(pair.os_state({"q": q + h})), pair.os_lengths(pair.os_state({"q": q - h}))
        st = pair.os_state({"q": q})
        l_os = pair.os_lengths(st)
        l_mj = pair.mj_lengths({"q": q})[pair.tendon_ids]
        ma = mujoco_moment_arms(pair.mj_model, pair.mj_data, {"q": q}, ["q"], plan=pair.plan)[pair.tendon_ids, 0]
        for i, (n, _, obj) in enumerate(pair.matched):
            row = out[n]
            row["L_os"].append(l_os[i])
            row["cma"].append(obj.computeMomentArm(st, pair.coord("q")))
            row["dldq"].append(-(up[i] - dn[i]) / (2 * h))
            row["L_mj"].append(l_mj[i])
            row["ma_mj"].append(ma[i])
    return {n: {k: np.array(v) for k, v in row.items()} for n, row in out.items()}


def test_opensim_computes_its_moment_arm_from_the_cross_body_segment_only(pendulum):
    osim_path, convs = pendulum
    s = _sweep(osim_path, convs["kinematic"].xml)
    for n in MOVING:
        assert np.max(np.abs(s[n]["cma"] - s[n]["dldq"])) > (5e-3 if n == "big" else 1e-4), n  # they differ


def test_opensim_mode_matches_compute_moment_arm(pendulum):
    osim_path, convs = pendulum
    s = _sweep(osim_path, convs["opensim"].xml)
    recs = {r["path"]: r for r in convs["opensim"].report.path_forces}
    for n in MOVING:
        assert recs[n]["mode"] == "opensim"
        assert np.max(np.abs(s[n]["ma_mj"] - s[n]["cma"])) < 1e-6, n
        # length: OpenSim's up to half the variation of the held segment (the record says how much)
        err = np.max(np.abs(s[n]["L_mj"] - s[n]["L_os"]))
        assert err <= recs[n]["length_error_mm"] * 1e-3 + 1e-9, (n, err)
        assert err > 0.4 * recs[n]["length_error_mm"] * 1e-3  # and the record is not a loose bound
    m = mujoco.MjModel.from_xml_path(str(convs["opensim"].xml))
    assert int(mujoco.mjtWrap.mjWRAP_PULLEY) in {int(t) for t in m.wrap_type}


def test_kinematic_mode_matches_the_length_and_its_derivative(pendulum):
    osim_path, convs = pendulum
    s = _sweep(osim_path, convs["kinematic"].xml)
    recs = {r["path"]: r for r in convs["kinematic"].report.path_forces}
    for n in MOVING:
        assert recs[n]["mode"] == "kinematic"
        assert np.max(np.abs(s[n]["L_mj"] - s[n]["L_os"])) < 1e-9, n
        assert np.max(np.abs(s[n]["ma_mj"] - s[n]["dldq"])) < 1e-6, n
        # the recorded moment-arm difference is the one OpenSim shows
        gap = np.max(np.abs(s[n]["cma"] - s[n]["dldq"]))
        assert abs(recs[n]["moment_arm_mm"]["q"] * 1e-3 - gap) < 0.05 * gap + 1e-6, n


def test_auto_holds_only_the_segment_that_varies_little(pendulum):
    osim_path, convs = pendulum
    recs = {r["path"]: r for r in convs["auto"].report.path_forces}
    assert recs["small"]["mode"] == "opensim" and recs["small"]["variation_pct"] <= 2.0
    assert recs["big"]["mode"] == "kinematic" and recs["big"]["variation_pct"] > 2.0
    approx = {a.name: a for a in convs["auto"].report.approximations}
    assert "computeMomentArm" in approx["big"].what and "pulley" in approx["small"].what
    rep = compare_muscles(osim_path, convs["auto"].xml, n_poses=40, seed=0, ma_poses=20)
    assert rep.muscles["small"].max_len_pct <= 1.0  # held: within the length target
    assert rep.muscles["small"].moment_arms["q"].rms < 1e-6  # vs computeMomentArm
    assert rep.muscles["big"].moment_arms["q"].rms_vs_dldq < 1e-6  # kept: vs -dL/dq
    assert "Path forces (auto" in convs["auto"].report.summary()
    full, steady = convs["auto"].report.summary().splitlines(), convs["auto"].report.summary(timing=False).splitlines()
    assert [line for line in full if not line.startswith("  time ")] == steady and len(full) == len(steady) + 1


def test_cli_accepts_the_option(tmp_path, pendulum):
    from o2m.cli import main

    osim_path, _ = pendulum
    assert main(["convert", str(osim_path), "-o", str(tmp_path / "cli"), "--path-forces", "opensim"]) == 0
    text = (tmp_path / "cli" / "moving.xml").read_text()
    assert "pulley" in text
