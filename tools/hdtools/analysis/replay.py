"""Replay cleaned data through the C pipeline with a given model, and the
residuals the analysis works on.

Residuals (per piece, after a warm-up):
  innovation  e = y - C x_prior  (hd_kf_output_t.innovation_nm): what the
              model could not predict one step ahead;
  model residual r = torque_filtered - torque_expected: what is left of the
              measured torque once the estimated ripple and the expected
              torque are removed.  Un-modelled lines, friction, inertia
              errors and drift all end up here (and so does real load
              torque, which is why detection looks for *structure*).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import cfilter
from .loading import Data
from .model import Model


@dataclass
class PieceRun:
    t_s: np.ndarray
    motor_angle_rad: np.ndarray
    output_angle_rad: np.ndarray
    torque_nm: np.ndarray
    torque_true_nm: np.ndarray | None
    out: dict
    warm: int

    @property
    def filtered(self):
        return self.out["torque_filtered_nm"].astype(float)

    @property
    def residual(self):
        return (self.out["torque_filtered_nm"] - self.out["torque_expected_nm"]).astype(float)


def angles(piece, gear_ratio, has_motor, has_output):
    if has_motor:
        th_m = piece.motor_angle_rad
        th_o = piece.output_angle_rad if has_output else th_m / gear_ratio
    else:
        th_o = piece.output_angle_rad
        th_m = th_o * gear_ratio
    return th_m.astype(float), th_o.astype(float)


def warmup_samples(n, ts_s):
    # The filter starts from zero state: skip its convergence (and the
    # start-up at low speed) in every metric and spectrum.
    return int(min(n // 4, max(2.0 / ts_s, 50)))


def replay(data: Data, model: Model, feedforward=None) -> list[PieceRun]:
    cfg = model.kf_config(data.ts_s)
    cfilter.check(cfg)
    exp = model.expected_config()
    runs = []
    for k, p in enumerate(data.pieces):
        th_m, th_o = angles(p, model.gear_ratio, data.has_motor, data.has_output)
        dm = np.diff(th_m, prepend=th_m[0])
        do = np.diff(th_o, prepend=th_o[0])
        ff = None if feedforward is None else feedforward[k]
        out = cfilter.run(cfg, exp, p.torque_nm, dm, do, ff,
                          track_bandwidth_hz=model.track_bandwidth_hz)
        runs.append(PieceRun(p.t_s, th_m, th_o, p.torque_nm, p.torque_true_nm, out,
                             warmup_samples(len(p), data.ts_s)))
    return runs


def _cat(runs, fn):
    parts = [fn(r)[r.warm:] for r in runs]
    return np.concatenate(parts) if parts else np.zeros(0)


def metrics(runs: list[PieceRun]) -> dict:
    e = _cat(runs, lambda r: r.out["innovation_nm"].astype(float))
    s = _cat(runs, lambda r: r.out["innovation_var_nm2"].astype(float))
    res = _cat(runs, lambda r: r.residual)
    m = {"innovation_rms_nm": float(np.sqrt(np.mean(e ** 2))),
         "innovation_nll": float(0.5 * np.mean(np.log(s) + e ** 2 / s)),
         "model_residual_rms_nm": float(np.sqrt(np.mean((res - res.mean()) ** 2))),
         "samples": int(len(e)),
         "filter_resets": int(sum(r.out["reset_count"] for r in runs)),
         "frozen_fraction": float(np.mean(_cat(
             runs, lambda r: (r.out["status"] & cfilter.STATUS_FROZEN) != 0)))}
    if all(r.torque_true_nm is not None for r in runs):
        err = _cat(runs, lambda r: r.filtered - r.torque_true_nm)
        raw = _cat(runs, lambda r: r.torque_nm - r.torque_true_nm)
        m["error_rms_nm"] = float(np.sqrt(np.mean(err ** 2)))
        m["raw_error_rms_nm"] = float(np.sqrt(np.mean(raw ** 2)))
        m.update(error_bands(runs))
    return m


ERROR_SPLIT_HZ = 2.0


def error_bands(runs: list[PieceRun], split_hz: float = ERROR_SPLIT_HZ) -> dict:
    """The error against truth split at split_hz (zero-phase 4th-order
    Butterworth, per piece after its warm-up).  Above it: what the
    motor-locked (and fixed) blocks leave or inject, i.e. the ripple band
    at any useful motor speed.  Below it: output-locked lines, the offset
    and load torque the ripple blocks may take (an output-order-1 line at
    1.5 rad/s is 0.24 Hz).  A piece shorter than 2/split_hz counts as slow
    only.  Empty when the sample rate is below 4 x split_hz."""
    from scipy import signal
    ts = float(np.median(np.diff(runs[0].t_s))) if runs and len(runs[0].t_s) > 1 else 0.0
    if not ts > 0 or 1.0 / ts < 4 * split_hz:
        return {}
    sos = signal.butter(4, split_hz, "highpass", fs=1.0 / ts, output="sos")
    fast, slow = [], []
    for r in runs:
        e = (r.filtered - r.torque_true_nm)[r.warm:]
        hp = signal.sosfiltfilt(sos, e) if len(e) * ts >= 2.0 / split_hz else np.zeros_like(e)
        fast.append(hp)
        slow.append(e - hp)
    fast, slow = np.concatenate(fast), np.concatenate(slow)
    return {"error_split_hz": split_hz,
            "error_fast_rms_nm": float(np.sqrt(np.mean(fast ** 2))),
            "error_slow_rms_nm": float(np.sqrt(np.mean(slow ** 2)))}


ANALYSIS_MAX_SAMPLES = 600_000
ANALYSIS_CHUNK = 100_000


def analysis_view(runs: list[PieceRun], max_total: int = ANALYSIS_MAX_SAMPLES,
                  chunk: int = ANALYSIS_CHUNK) -> list[PieceRun]:
    """Spectra and fits need not see every sample of a long record: evenly
    spaced contiguous chunks (after each piece's warm-up) totalling at most
    max_total samples.  Deterministic in the run lengths, so views of two
    replays of the same data cover the same samples.  Metrics (RMS values)
    always use all samples."""
    spans = []
    for i, r in enumerate(runs):
        a, n = r.warm, len(r.t_s)
        while a < n:
            b = min(a + chunk, n)
            spans.append((i, a, b))
            a = b
    total = sum(b - a for _, a, b in spans)
    if total <= max_total:
        keep = spans
    else:
        k = max(1, int(max_total // chunk))
        idx = np.unique(np.linspace(0, len(spans) - 1, k).round().astype(int))
        keep = [spans[j] for j in idx]
    out = []
    for i, a, b in keep:
        r = runs[i]
        sl = slice(a, b)
        o = {k: (v[sl] if isinstance(v, np.ndarray) and len(v) == len(r.t_s) else v)
             for k, v in r.out.items()}
        out.append(PieceRun(r.t_s[sl], r.motor_angle_rad[sl], r.output_angle_rad[sl],
                            r.torque_nm[sl],
                            None if r.torque_true_nm is None else r.torque_true_nm[sl], o, 0))
    return out
