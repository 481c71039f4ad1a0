"""No bare numbers across the ctypes boundary: the status bits and error
codes the Python tools use are the C filter library's (hd_kf_status_name,
hd_kf_err_name / hd_kf_err_str), and the Python constants are checked
against it, and against the C header's #defines and enum."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

from hdtools.analysis import cfilter

HEADER = (ROOT / "filter" / "hd_kf.h").read_text()
ERR_HEADER = (ROOT / "filter" / "hd_filter_err.h").read_text()


def test_status_bits_match_the_c_library_and_header():
    from_lib = cfilter.status_names()
    from_header = {m.group(1): 1 << int(m.group(2)) for m in
                   re.finditer(r"#define HD_KF_STATUS_(\w+)\s+\(1u << (\d+)\)", HEADER)}
    assert from_lib == from_header == cfilter.STATUS_BITS
    for name, bit in cfilter.STATUS_BITS.items():
        assert getattr(cfilter, f"STATUS_{name}") == bit
    assert "OFFSET_JUMP" in from_lib  # the bit the old Python list stopped before


def test_every_error_has_a_name_and_text_from_c():
    enum = {m.group(1): int(m.group(2)) for m in
            re.finditer(r"\b(HD_KF_(?:OK|ERR_\w+)) = (-?\d+)", ERR_HEADER)}
    assert len(enum) >= 16 and "HD_KF_ERR_TRACK_BANDWIDTH" in enum
    for name, code in enum.items():
        assert cfilter.error_name(code) == name
        assert cfilter.error_text(code) != "unknown error"
    assert cfilter.error_name(12345) == "12345"
    assert cfilter.error_text(12345) == "unknown error"


def test_pipeline_init_errors_reach_python_by_name():
    cfg = cfilter.recommended_config(1e-3, 0.02, 0.05, 0.02)
    n = 10
    with pytest.raises(cfilter.FilterError, match="HD_KF_ERR_TRACK_BANDWIDTH") as exc:
        cfilter.run(cfg, cfilter.ExpectedConfig(), [0.0] * n, [0.0] * n, [0.0] * n,
                    track_bandwidth_hz=1000.0)
    assert exc.value.code == "HD_KF_ERR_TRACK_BANDWIDTH"
    with pytest.raises(cfilter.FilterError, match="HD_KF_ERR_EXPECTED_CONFIG"):
        cfilter.run(cfg, cfilter.ExpectedConfig(coulomb_vel_eps_rad_s=0.0), [0.0] * n, [0.0] * n,
                    [0.0] * n)
    cfg.output_learn_scale = 2.0
    with pytest.raises(cfilter.FilterError) as exc:
        cfilter.check(cfg)
    assert exc.value.code == "HD_KF_ERR_LEARN_SCALE"


def test_status_reaches_python_with_the_c_bits():
    """A non-finite sample is flagged BAD_INPUT; an over-Nyquist block FROZEN."""
    cfg = cfilter.recommended_config(1e-3, 0.02, 0.05, 0.02)
    torque = [1.0, float("nan"), 1.0, 1.0]
    d_motor = [0.1, 0.1, 3.0, 0.1]  # order 2 and 4 over 0.9 pi at the third sample
    out = cfilter.run(cfg, cfilter.ExpectedConfig(), torque, d_motor, [0.001] * 4)
    st = [int(s) for s in out["status"]]
    assert st[1] & cfilter.STATUS_BAD_INPUT and not st[0] & cfilter.STATUS_BAD_INPUT
    assert st[2] & cfilter.STATUS_FROZEN and not st[3] & cfilter.STATUS_FROZEN
    # and nothing else: each of those steps raises its one bit
    assert st == [0, cfilter.STATUS_BAD_INPUT, cfilter.STATUS_FROZEN, 0]


def test_profile_import_errors_reach_python_by_name():
    """cfilter.run's profile import: a line of order 0 is refused by the C
    library (HD_KF_ERR_PROFILE), an angle outside [0, 2 pi) too
    (HD_KF_ERR_ANGLE); both by name."""
    cfg = cfilter.recommended_config(1e-3, 0.02, 0.05, 0.02)
    n = 4
    motor = cfilter.LOCK_BY_NAME["motor"]
    with pytest.raises(cfilter.FilterError, match="HD_KF_ERR_PROFILE") as exc:
        cfilter.run(cfg, cfilter.ExpectedConfig(), [0.0] * n, [0.0] * n, [0.0] * n,
                    profile=([(motor, 0, 0.5, 0.1)], 1.0, 1.0, 0.0))
    assert exc.value.code == "HD_KF_ERR_PROFILE"
    with pytest.raises(cfilter.FilterError, match="HD_KF_ERR_ANGLE") as exc:
        cfilter.run(cfg, cfilter.ExpectedConfig(), [0.0] * n, [0.0] * n, [0.0] * n,
                    profile=([(motor, 2, 0.5, 0.1)], float("nan"), 1.0, 0.0))
    assert exc.value.code == "HD_KF_ERR_ANGLE"
