"""The ctypes mirror of the filter structs matches the C compiler's layout,
and the binding runs the C pipeline correctly on a closed-form case."""
from __future__ import annotations

import ctypes
import math
import shutil
import subprocess

import numpy as np
import pytest

from conftest import ROOT
from hdtools.analysis import cfilter

C_PROGRAM = r"""
#include <stddef.h>
#include <stdio.h>
#include "hd_pipeline.h"
#define P(T) printf(#T " %zu\n", sizeof(T))
#define O(T, F) printf(#T "." #F " %zu\n", offsetof(T, F))
int main(void) {
    P(hd_kf_block_config_t); P(hd_kf_config_t); P(hd_kf_t); P(hd_track_t);
    P(hd_expected_config_t); P(hd_pipeline_t); P(hd_pipeline_io_t);
    O(hd_kf_config_t, block_count); O(hd_kf_config_t, offset_q_nm2);
    O(hd_kf_config_t, nyquist_fraction); O(hd_kf_t, x); O(hd_kf_t, p);
    O(hd_kf_t, reset_count); O(hd_pipeline_t, output_track); O(hd_pipeline_t, expected);
    O(hd_pipeline_t, torque_expected_nm); O(hd_pipeline_io_t, status);
    O(hd_pipeline_io_t, amplitude_nm);
    P(hd_kf_profile_line_t); P(hd_kf_profile_t); O(hd_kf_profile_line_t, a_nm);
    O(hd_kf_profile_t, lines);
    P(hd_expected_current_config_t); P(hd_slow_current_config_t); P(hd_slow_current_t);
    O(hd_slow_current_config_t, alpha); O(hd_slow_current_config_t, ts_s);
    O(hd_slow_current_t, primed); O(hd_pipeline_io_t, motor_current_a);
    O(hd_pipeline_io_t, torque_expected_var_nm2);
    return 0;
}
"""

MIRROR = {
    "hd_kf_block_config_t": cfilter.BlockConfig, "hd_kf_config_t": cfilter.KfConfig,
    "hd_kf_t": cfilter.KfState, "hd_track_t": cfilter.Track,
    "hd_expected_config_t": cfilter.ExpectedConfig, "hd_pipeline_t": cfilter.Pipeline,
    "hd_pipeline_io_t": cfilter.PipelineIO, "hd_kf_profile_line_t": cfilter.ProfileLine,
    "hd_kf_profile_t": cfilter.Profile, "hd_expected_current_config_t": cfilter.CurrentTerm,
    "hd_slow_current_config_t": cfilter.CurrentConfig, "hd_slow_current_t": cfilter.CurrentState,
}


def test_struct_layout_matches_c(tmp_path):
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if not cc:
        pytest.skip("no C compiler")
    src = tmp_path / "layout.c"
    src.write_text(C_PROGRAM)
    exe = tmp_path / "layout"
    subprocess.run([cc, "-std=c11", "-I", str(ROOT / "filter"), str(src), "-o", str(exe)],
                   check=True)
    lines = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split("\n")
    checked = 0
    for line in filter(None, lines):
        name, value = line.rsplit(" ", 1)
        if "." in name:
            t, f = name.split(".")
            got = getattr(MIRROR[t], f).offset
        else:
            got = ctypes.sizeof(MIRROR[name])
        assert got == int(value), f"{name}: ctypes {got} != C {value}"
        checked += 1
    assert checked == 30


def test_single_block_removes_a_sinusoid():
    """Closed form: a motor-order-2 line of 0.5 N m on a constant 3 N m at
    constant speed; after convergence the filtered torque is the constant
    (to within the noise) and the innovation is white noise."""
    ts, n, w = 1e-3, 20000, 150.0
    rng = np.random.default_rng(1)
    theta = w * ts * np.arange(n)
    noise = 0.01 * rng.standard_normal(n)
    torque = 3.0 + 0.5 * np.sin(2 * theta + 0.3) + noise
    cfg = cfilter.default_config(ts)
    cfg.r_nm2 = 1e-4
    cfg.offset_enabled, cfg.offset_q_nm2 = 1, 1e-4 * (ts / 0.05) ** 2
    cfg.add_block(cfilter.LOCK_MOTOR, 2.0, 1e-4 * (ts / 0.05) ** 2)
    out = cfilter.run(cfg, cfilter.ExpectedConfig(), torque, np.full(n, w * ts),
                      np.full(n, w * ts / 100))
    tail = slice(n // 2, n)
    err = out["torque_filtered_nm"][tail] - 3.0
    assert math.sqrt(np.mean(err ** 2)) < 0.03
    assert np.std(out["innovation_nm"][tail]) == pytest.approx(0.01, rel=0.3)


def test_bad_configuration_is_a_clear_error():
    cfg = cfilter.default_config(1e-3)
    cfg.r_nm2 = 0.0
    with pytest.raises(cfilter.FilterError, match="filter configuration rejected"):
        cfilter.check(cfg)


def test_imported_profile_removes_its_line_from_the_first_sample():
    """Closed form: an output-order-1 line a cos(theta) + b sin(theta) on a
    load that steps; an output block that never learns (output_learn_scale
    0), its state imported from the exact (a, b) at the first sample's
    absolute angle (which does not start at zero): the filtered torque is
    the load from the first sample on, the step included (nothing of it is
    taken by the block)."""
    ts, n = 1e-3, 8000
    rng = np.random.default_rng(2)
    w_out = 1.5
    theta = 2.3 + w_out * ts * np.arange(n)
    a, b = 0.3, -0.4
    load = np.where(np.arange(n) < n // 2, 2.0, 5.0)
    torque = load + a * np.cos(theta) + b * np.sin(theta) + 0.005 * rng.standard_normal(n)
    cfg = cfilter.default_config(ts)
    cfg.r_nm2 = 2.5e-5
    cfg.p0_nm2 = cfg.output_p0_nm2 = 0.1
    cfg.offset_enabled, cfg.offset_q_nm2 = 1, 2.5e-5 * (ts / 0.02) ** 2
    cfg.add_block(cfilter.LOCK_OUTPUT, 1.0, 1e-6)
    cfg.output_learn_scale = 0.0
    d_out = np.diff(theta, prepend=theta[0])
    out = cfilter.run(cfg, cfilter.ExpectedConfig(), torque, 100 * d_out, d_out,
                      profile=([(cfilter.LOCK_OUTPUT, 1, a, b)], 100 * theta[0], theta[0], 0.0))
    ripple = out["ripple_nm"].astype(float)
    # The prediction for a sample is turned by the previous sample's
    # increment (the filter cannot see the next one): at most one step of
    # phase behind, amplitude x increment.
    lag_bound = math.hypot(a, b) * w_out * ts
    assert np.max(np.abs(ripple - (a * np.cos(theta) + b * np.sin(theta)))) < 1.05 * lag_bound
    err = out["torque_filtered_nm"] - load
    assert np.sqrt(np.mean(err ** 2)) < 0.01
