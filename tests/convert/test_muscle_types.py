"""OpenSim muscle types (o2m.convert.muscle_types): Schutte's activation dynamics mapped to MuJoCo's."""

from __future__ import annotations

from o2m.convert.muscle_types import _schutte_time_constants


def test_schutte_activation_mapping_follows_schutte_better_than_step_matching():
    t_act, t_deact, rms, rms_step = _schutte_time_constants(0.1, 7.667, 1.459854)  # MoBL-ARMS' values
    assert rms < 0.75 * rms_step  # measured 0.024 against 0.037
    # Schutte rises with time constant ts / (a1 u + a2): 11 ms at u = 1, 27 ms at u = 0.3; falls with 68 ms
    assert 0.01 < t_act < 0.03 and 0.05 < t_deact < 0.09
