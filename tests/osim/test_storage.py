"""OpenSim .sto/.mot reading and writing."""

from __future__ import annotations

import numpy as np
import pytest

from o2m.errors import ModelFileError
from o2m.osim.storage import read_sto, write_sto
from tests.helpers import require_models


def test_round_trip(tmp_path):
    t = np.linspace(0, 1, 11)
    data = np.column_stack([np.sin(t), np.cos(t) * 1e-9])
    p = write_sto(tmp_path / "x.sto", t, ["a", "b"], data, in_degrees=True)
    st = read_sto(p)
    assert st.columns == ("a", "b") and st.in_degrees
    assert np.array_equal(st.times, t) and np.array_equal(st.data, data)
    assert st.first_row() == {"a": 0.0, "b": 1e-9}
    with pytest.raises(KeyError, match="did you mean"):
        st.column("aa")


def test_mobl_initial_states():
    require_models()
    from o2m import models

    st = read_sto(models.fetch("mobl-arms/initial_states.sto"))
    assert st.columns[0] == "r_z" and "DELT1.fiber_length" in st.columns and len(st.columns) == 142
    assert st.first_row()["elbow_flexion"] == pytest.approx(1.796872379)


@pytest.mark.parametrize("text, match", [("no header\n1 2\n", "endheader"),
                                         ("x\nendheader\nfoo\tbar\n1 2\n", "starting with 'time'"),
                                         ("x\nendheader\ntime\ta\n1 2 3\n", "3 values for 2 columns"),
                                         ("x\nendheader\ntime\ta\n", "no data")])
def test_bad_files_raise(tmp_path, text, match):
    p = tmp_path / "bad.sto"
    p.write_text(text)
    with pytest.raises(ModelFileError, match=match):
        read_sto(p)
