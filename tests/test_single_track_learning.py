"""Cornering-compliance learning (fusion/single_track.py): what its model-error estimate learns from."""
from __future__ import annotations

import math

from ecu_daemon.estimator.fusion.single_track import SingleTrackFusion

M, IZ, LF, LR, CF, CR = 1500.0, 2500.0, 1.2, 1.5, 100e3, 120e3


def _fusion() -> SingleTrackFusion:
    return SingleTrackFusion(M, IZ, LF, LR, CF, CR, adapt=True)


def test_a_regressor_buried_in_the_vy_noise_does_not_inflate_the_model_error():
    # nearly straight (0.005 g): a slip term of 0.005 m/s under vy noise of 0.1 m/s; residuals
    # of that noise over so small a regressor once read as a 1000 % model error
    st = _fusion()
    rel0 = st.rear.rel_var
    vx, ay = 18.0, 0.05
    r = ay / vx
    vy = LR * r + (M / CR) * st.regressor_rear(vx, ay, 0.0)
    for i in range(200):
        st.adapt_from(vx, vy + (0.1 if i % 2 else -0.1), 0.05 ** 2, r, ay, 0.0, math.nan)
    assert st.rear.rel_var <= rel0
