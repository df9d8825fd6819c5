"""The wrap fit leaves out an ellipsoid stand-in's side site whose leaving out makes no length or
moment arm at its poses worse (``wrapfit._Evaluator.unneeded_side_sites``), and drop_from_spec then
keeps the geom without it."""

from __future__ import annotations

import mujoco
import numpy as np

from o2m.convert.wrap_choice import drop_from_spec
from o2m.convert.wrapfit import _Evaluator, _Task

#: A tendon from a ground site over a ground sphere (radius 0.05 m, at the origin) to a site on
#: an arm hinged at (0.6, 0, 0); the side site {side} (ground frame, m). Over q in [-0.1, 0.1]
#: rad the straight path crosses the sphere above its centre (2.3 to 3.8 cm up).
_XML = """
<mujoco>
  <worldbody>
    <site name="origin" pos="-0.3 0 0.03"/>
    <geom name="ball" type="sphere" size="0.05" pos="0 0 0" contype="0" conaffinity="0"/>
    <site name="ball_side" pos="{side}"/>
    <body name="arm" pos="0.6 0 0">
      <joint name="q" type="hinge" axis="0 1 0"/>
      <inertial pos="0.15 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>
      <site name="insertion" pos="0.3 0 0.03"/>
    </body>
  </worldbody>
  <tendon>
    <spatial name="m">
      <site site="origin"/>
      <geom geom="ball" sidesite="ball_side"/>
      <site site="insertion"/>
    </spatial>
  </tendon>
</mujoco>
"""


def _evaluator(side: str, kind: str = "WrapEllipsoid",
               targets: tuple[np.ndarray, np.ndarray] | None = None) -> _Evaluator:
    """The wrap fit's evaluator of the tendon, its sphere standing for an OpenSim ``kind`` whose
    lengths (m, (9,)) and moment arms (m, (9, 1)) at the 9 poses are ``targets`` (zeros when None)."""
    qpos = np.linspace(-0.1, 0.1, 9)[:, None]
    n = len(qpos)
    length, arm = (np.zeros(n), np.zeros((n, 1))) if targets is None else targets
    task = _Task("m", _XML.format(side=side), ["ball"], ["ball_side"], [kind], qpos,
                 np.ones((n, 1, 1)), length, arm, n, ["q"], 0, 0)
    return _Evaluator(task)


def _lengths(side: str) -> tuple[np.ndarray, np.ndarray]:
    """The tendon's lengths (m, (9,)) and moment arms (m, (9, 1)) at the 9 poses with the side
    site at ``side``."""
    ev = _evaluator(side)
    return ev.errors(np.zeros(ev.n_params), slice(0, 9))


def test_a_side_site_on_the_short_way_is_left_out_and_one_on_opensims_long_way_kept():
    over = _evaluator("0 0 0.1", targets=_lengths("0 0 0.1"))  # the short way, over the top, everywhere
    assert over.unneeded_side_sites(np.zeros(over.n_params), slice(0, 9)) == ["ball_side"]
    # MuJoCo goes under, the long way, at these poses, as OpenSim does
    under = _evaluator("0 0 -0.1", targets=_lengths("0 0 -0.1"))
    assert under.unneeded_side_sites(np.zeros(under.n_params), slice(0, 9)) == []


def test_a_side_site_taking_a_long_way_opensim_does_not_take_is_left_out():
    # OpenSim goes the short way; the side site would send MuJoCo the long way
    assert np.all(_lengths("0 0 -0.1")[0] > _lengths("0 0 0.1")[0] + 1e-3)
    under = _evaluator("0 0 -0.1", targets=_lengths("0 0 0.1"))
    assert under.unneeded_side_sites(np.zeros(under.n_params), slice(0, 9)) == ["ball_side"]


def test_a_wrap_spheres_side_site_stays_it_is_opensims_switch():
    sphere = _evaluator("0 0 0.1", kind="WrapSphere")
    assert sphere.unneeded_side_sites(np.zeros(sphere.n_params), slice(0, 9)) == []


def test_a_dropped_side_site_leaves_the_geom_in_the_path():
    spec = mujoco.MjSpec.from_string(_XML.format(side="0 0 0.1"))
    drop_from_spec(spec, {"m": ["ball_side"]})
    m = spec.compile()
    assert m.nsite == 2 and m.ngeom == 1
    w = m.tendon_adr[0] + 1
    assert int(m.wrap_type[w]) == int(mujoco.mjtWrap.mjWRAP_SPHERE) and m.wrap_prm[w] == -1


def test_a_tendon_already_at_opensims_lengths_is_not_fitted():
    """Targets the converted geoms meet (OpenSim's noise at most): CMA-ES is not run and the
    geoms keep their places; a start 2 mm off is fitted."""
    from dataclasses import replace

    from o2m.convert.wrapfit import _fit_one

    length, arm = _lengths("0 0 0.1")
    exact = replace(_evaluator("0 0 0.1", targets=(length + 1e-6, arm)).t, evals=200, n_fit=5)
    fit = _fit_one(exact)
    assert fit.exact and not fit.accepted and fit.evaluations < 10
    assert fit.values["ball"]["pos"] == [0.0, 0.0, 0.0]
    off = replace(_evaluator("0 0 0.1", targets=(length + 2e-3, arm)).t, evals=200, n_fit=5)
    assert not _fit_one(off).exact
