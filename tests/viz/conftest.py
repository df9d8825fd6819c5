"""Models the viz tests draw, converted once per session."""

from __future__ import annotations

import pytest

from tests.viz.helpers import convert_model


@pytest.fixture(scope="session")
def arm26(tmp_path_factory):
    """(osim path, MJCF path, MjModel) of arm26, converted once per session."""
    return convert_model("arm26", tmp_path_factory.mktemp("viewer-arm26"))


@pytest.fixture(scope="session")
def mobl(tmp_path_factory):
    """(osim path, MJCF path, MjModel) of MoBL-ARMS without wrapping (the paper's model)."""
    return convert_model("mobl_arms_no_wrap", tmp_path_factory.mktemp("viewer-mobl"))
