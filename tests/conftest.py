"""Shared test set-up: the local model mirror, a per-session cache, and the bundled models
converted once per session (helpers in tests/helpers.py)."""

from __future__ import annotations

import os

import pytest

from tests.helpers import QUICK, convert_options, local_mirror, require_models

#: Bundled models converted at full size in quick runs too: Arm26's full wrap fit takes a few
#: seconds more, and its quick one (40 poses) lands on either side of BIClong's kink (OpenSim's
#: BIClonghh takes the path on with its moment arm stepping 32 mm) depending on the processor's
#: floating point: within 1 % and 2.90 mm p95 on an AMD EPYC, 1.34 % and 4.52 mm on an Intel Xeon.
#: At full size it meets every target on both (0.30 %; 1.40 / 1.91 mm).
FULL_SIZE = {"arm26"}


@pytest.fixture(autouse=True, scope="session")
def _model_mirror_and_cache(tmp_path_factory):
    """Point o2m at a local mirror when there is one (else the models are downloaded) and, unless
    set, at a cache private to this test session."""
    m = local_mirror()
    saved = {k: os.environ.get(k) for k in ("O2M_MODEL_MIRROR", "O2M_CACHE")}
    if m is not None:
        os.environ["O2M_MODEL_MIRROR"] = str(m)
    if not os.environ.get("O2M_CACHE"):
        os.environ["O2M_CACHE"] = str(tmp_path_factory.mktemp("o2m-cache"))
    yield
    for k, v in saved.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


@pytest.fixture(scope="session")
def bundled_conversion(tmp_path_factory):
    """``get(name)`` -> (FetchedModel, Conversion) of the bundled model ``name`` converted with
    this run's default options (:func:`tests.helpers.convert_options`; 2 workers, which do not
    change the result; full size for :data:`FULL_SIZE`), once per session: the integration tests
    of skeletons and of muscle paths, and the 3.x-document test, read the same conversion instead
    of each making their own (the wrapped MoBL-ARMS takes minutes). Tests must not write into its
    folder."""
    from o2m import models
    from o2m.convert.converter import convert

    done: dict[str, tuple] = {}

    def get(name: str) -> tuple:
        if name not in done:
            require_models()
            fetched = models.fetch_model_with_geometry(name, progress=False)
            options = convert_options(workers=2, quick=QUICK and name not in FULL_SIZE)
            conv = convert(fetched.osim, tmp_path_factory.mktemp(name), options, geometry_dirs=[fetched.geometry_dir])
            done[name] = (fetched, conv)
        return done[name]

    return get
