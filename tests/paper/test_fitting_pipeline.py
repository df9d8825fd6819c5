"""The pipeline's CMA-ES fit takes its step size from the settings (o2m's column and the paper's apart)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

from o2m.paper.fitting import load_fit
from o2m.paper.pipeline import QUICK, fit_parameters
from tests.paper.test_fitting import _setup


def test_fit_parameters_uses_the_settings_step_size(tmp_path):
    model, init, ctrl, ref = _setup(0.5, 0.05, n=2, steps=60)
    exp = SimpleNamespace(dofs=["swing"], muscles=["lifter"], init=init, controls=ctrl, reference=ref,
                          xml=Path("pendulum.xml"))
    for sigma0 in (0.02, 0.3):
        fit_file = tmp_path / f"fit{sigma0}.json"
        _, fit = fit_parameters(exp, model, [0], [1], fit_file, settings=replace(QUICK, generations=1, popsize=4,
                                                                               sigma0=sigma0), progress=False)
        assert fit.settings["sigma0"] == sigma0 and load_fit(fit_file).settings["sigma0"] == sigma0


def test_a_stored_fit_of_another_model_is_refused(tmp_path):
    """A fit stored for one model (o2m's column fits the model with its passive fibres) is not
    loaded for another with the same parameter names."""
    import pytest

    model, init, ctrl, ref = _setup(0.5, 0.05, n=2, steps=60)
    exp = SimpleNamespace(dofs=["swing"], muscles=["lifter"], init=init, controls=ctrl, reference=ref,
                          xml=Path("pendulum.xml"))
    fit_file = tmp_path / "fit.json"
    settings = replace(QUICK, generations=1, popsize=4)
    fit_parameters(exp, model, [0], [1], fit_file, settings=settings, progress=False)
    fit_parameters(exp, model, [0], [1], fit_file, settings=settings, progress=False)  # loads it
    other = SimpleNamespace(**{**vars(exp), "xml": Path("pendulum_fibres.xml")})
    with pytest.raises(ValueError, match="fitted on another model"):
        fit_parameters(other, model, [0], [1], fit_file, settings=settings, progress=False)
