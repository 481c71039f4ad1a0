"""cfilter.run's profile import against the contract of hd_kf.h ("Which
angle"): given the ABSOLUTE angles of a log's first sample, the replay's
prediction of every sample is the profile at that sample's angles, also when
the log starts in motion (its first increment is not 0: the filter is given
the angles of the sample before the first, and turns by the first
increment itself).  Expected values: the profile evaluated in closed form
with numpy at the log's angles."""
from __future__ import annotations


import numpy as np

from hdtools.analysis import cfilter

TS_S = 1e-3
GEAR = 100.0
LINES = [("motor", 2, 0.7, -0.4), ("motor", 4, 0.1, 0.25), ("output", 1, 0.3, 0.2)]


def profile_nm(th_m, th_o):
    r = np.zeros(len(th_m))
    for lock, order, a, b in LINES:
        ph = order * (th_m if lock == "motor" else th_o)
        r += a * np.cos(ph) + b * np.sin(ph)
    return r


def replay(first_increment_rad: float, motor_start_rad: float = 5.0):
    """Motor speed from first_increment / ts, changing every 40 samples;
    the blocks neither learn (q 0, prior variance 0) nor see a correction
    they could use: their predictions are the imported profile turned."""
    cfg = cfilter.default_config(TS_S)
    for i, (lock, order, _, _) in enumerate(LINES):
        cfg.blocks[i].lock = cfilter.LOCK_BY_NAME[lock]
        cfg.blocks[i].enabled = 1
        cfg.blocks[i].order = order
        cfg.blocks[i].q_nm2 = 0.0
    cfg.block_count = len(LINES)
    cfilter.check(cfg)
    n = 200
    d_m = np.full(n, first_increment_rad)
    d_m[40:] = 0.21
    d_m[80:] = -0.05
    d_m[120:] = 0.33
    d_m = d_m.astype(np.float32)
    d_o = (d_m / GEAR).astype(np.float32)
    th_m = motor_start_rad + np.cumsum(d_m.astype(float))   # absolute angles of the samples
    th_o = 2.0 + np.cumsum(d_o.astype(float))
    torque = profile_nm(th_m, th_o) + 3.0
    lines = [(cfilter.LOCK_BY_NAME[lock], order, a, b) for lock, order, a, b in LINES]
    out = cfilter.run(cfg, cfilter.ExpectedConfig(), torque, d_m, d_o,
                      profile=(lines, th_m[0], th_o[0], 0.0))
    return out["ripple_nm"].astype(float), profile_nm(th_m, th_o)


def test_a_log_starting_in_motion_is_predicted_at_its_own_angles():
    ripple, truth = replay(0.12)
    assert np.max(np.abs(ripple - truth)) < 2e-5
    # imported at the first sample's angles instead (the increment turned
    # once too often) the first prediction is 2 x 0.12 rad off on 0.8 N m
    lagged = profile_nm(np.array([5.0 + 0.24]), np.array([2.0 + 0.0024]))[0]
    assert abs(lagged - truth[0]) > 0.05


def test_a_log_starting_at_rest_is_predicted_at_its_own_angles():
    ripple, truth = replay(0.0)
    assert np.max(np.abs(ripple - truth)) < 2e-5


def test_an_angle_just_below_two_pi_is_angle_zero():
    # 2 pi - 1e-8 rounds to float32 2 pi, outside the filter's [0, 2 pi):
    # the import must take it as 0, not be refused (HD_KF_ERR_ANGLE).
    ripple, truth = replay(0.0, motor_start_rad=2.0 * np.pi - 1e-8)
    assert np.max(np.abs(ripple - truth)) < 2e-5
