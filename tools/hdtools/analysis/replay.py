"""Replay cleaned data through the C pipeline with a given model, the
residuals the analysis works on, and the split of the log into a part that
detects and fits (fold A) and a held-out part that judges (fold B).

Residuals (per piece, after a warm-up):
  innovation  e = y - C x_prior  (hd_kf_output_t.innovation_nm): what the
              model could not predict one step ahead;
  model residual r = torque_filtered - torque_expected: what is left of the
              measured torque once the estimated ripple and the expected
              torque are removed.  Un-modelled lines, friction, inertia
              errors and drift all end up here (and so does real load
              torque, which is why detection looks for *structure*).

Feed-forward: the log's `torque_feedforward_nm` column (the robot
controller's expected torque) goes into hd_pipeline_run's feedforward_nm,
which adds it to T_exp exactly as the firmware adds the CAN feed-forward.

Fixed angle profile (model.profile, docs/analyze.md "Profile"): output-locked
lines the geometry fit found run as output blocks with output_learn_scale 0
(they predict and turn with the output angle but never learn), their state
imported into the C filter at each piece's first sample
(hd_kf_profile_import), as the firmware does from a stored profile record.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import cfilter
from .loading import Data
from .model import Model

TRAIN, HELD_OUT, WARMUP = 0, 1, -1
FOLD_NAMES = {TRAIN: "in_sample", HELD_OUT: "out_of_sample"}
# Blocks of the timeline alternate A, B, A, B...: at least MIN_BLOCK_S long,
# at most MAX_BLOCKS of them.
MIN_BLOCK_S = 8.0
MAX_BLOCKS = 8


@dataclass
class PieceRun:
    t_s: np.ndarray
    motor_angle_rad: np.ndarray
    output_angle_rad: np.ndarray
    torque_nm: np.ndarray
    torque_true_nm: np.ndarray | None
    out: dict
    warm: int
    fold: np.ndarray | None = None      # TRAIN / HELD_OUT / WARMUP per sample
    feedforward_nm: np.ndarray | None = None
    segment: str = ""                   # pieces of one segment share a time base

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


def folds(data: Data) -> list[np.ndarray]:
    """Per piece, each sample's fold: the usable samples (after each piece's
    warm-up), laid end to end, are cut into 2 m blocks of equal length
    (m = the most that keeps a block >= MIN_BLOCK_S, at least 1, at most
    MAX_BLOCKS / 2) that alternate TRAIN, HELD_OUT.  Deterministic in the
    piece lengths."""
    warm = [warmup_samples(len(p), data.ts_s) for p in data.pieces]
    usable = sum(len(p) - w for p, w in zip(data.pieces, warm))
    m = int(np.clip(usable * data.ts_s // (2 * MIN_BLOCK_S), 1, MAX_BLOCKS // 2))
    edges = np.linspace(0, usable, 2 * m + 1)
    out, pos = [], 0
    for p, w in zip(data.pieces, warm):
        f = np.full(len(p), WARMUP, np.int8)
        k = np.arange(len(p) - w) + pos
        f[w:] = (np.searchsorted(edges, k, side="right") - 1) % 2
        pos += len(p) - w
        out.append(f)
    return out


def profile_torque(model: Model, th_m, th_o):
    """The model's fixed angle profile at these angles [N m]."""
    x = np.zeros(len(th_o))
    for ln in model.profile:
        ph = ln.order * (th_o if ln.lock == "output" else th_m)
        x += ln.a_nm * np.cos(ph) + ln.b_nm * np.sin(ph)
    return x


def replay(data: Data, model: Model, fold=None) -> list[PieceRun]:
    cfg = model.kf_config(data.ts_s)
    cfilter.check(cfg)
    exp = model.expected_config()
    fold = folds(data) if fold is None else fold
    runs = []
    for k, p in enumerate(data.pieces):
        th_m, th_o = angles(p, model.gear_ratio, data.has_motor, data.has_output)
        dm = np.diff(th_m, prepend=th_m[0])
        do = np.diff(th_o, prepend=th_o[0])
        ff = p.feedforward_nm
        imp = None
        if model.profile:
            lines = [(cfilter.LOCK_BY_NAME[ln.lock], int(round(ln.order)), ln.a_nm, ln.b_nm)
                     for ln in model.profile]
            imp = (lines, th_m[0], th_o[0], 0.0)
        out = cfilter.run(cfg, exp, p.torque_nm, dm, do, ff,
                          track_bandwidth_hz=model.track_bandwidth_hz, profile=imp)
        runs.append(PieceRun(p.t_s, th_m, th_o, p.torque_nm, p.torque_true_nm, out,
                             warmup_samples(len(p), data.ts_s), fold[k], ff, p.segment))
    return runs


def _rms(x):
    return float(np.sqrt(np.mean(x ** 2))) if len(x) else float("nan")


def _summary(e, s, res, err, raw):
    m = {"innovation_rms_nm": _rms(e),
         "innovation_nll": float(0.5 * np.mean(np.log(s) + e ** 2 / s)) if len(e) else float("nan"),
         "model_residual_rms_nm": _rms(res - res.mean()) if len(res) else float("nan"),
         "samples": int(len(e))}
    if err is not None:
        m["error_rms_nm"] = _rms(err)
        m["raw_error_rms_nm"] = _rms(raw)
    return m


def metrics(runs: list[PieceRun], which=None, bands: bool = False) -> dict:
    """RMS metrics over every sample after the warm-up, and per fold as
    in_sample_* (fold A) and out_of_sample_* (fold B); with `which`, the
    plain keys are those of that fold.  bands: also the error against truth
    split into frequency bands (error_bands; slower)."""
    def cat(fn):
        return np.concatenate([np.asarray(fn(r), float)[r.warm:] for r in runs])
    fold = np.concatenate([r.fold[r.warm:] for r in runs])
    e = cat(lambda r: r.out["innovation_nm"])
    s = cat(lambda r: r.out["innovation_var_nm2"])
    res = cat(lambda r: r.out["torque_filtered_nm"] - r.out["torque_expected_nm"])
    truth = all(r.torque_true_nm is not None for r in runs)
    err = cat(lambda r: r.filtered - r.torque_true_nm) if truth else None
    raw = cat(lambda r: r.torque_nm - r.torque_true_nm) if truth else None

    def part(mask):
        pick = (lambda x: None if x is None else x[mask]) if mask is not None else (lambda x: x)
        return _summary(pick(e), pick(s), pick(res), pick(err), pick(raw))
    m = part(None if which is None else fold == which)
    m["filter_resets"] = int(sum(r.out["reset_count"] for r in runs))
    m["frozen_fraction"] = float(np.mean(np.concatenate(
        [(r.out["status"][r.warm:] & cfilter.STATUS_FROZEN) != 0 for r in runs])))
    for f, name in FOLD_NAMES.items():
        for k, v in part(fold == f).items():
            m[f"{name}_{k}"] = v
    if bands and truth:
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


def _slice_run(r: PieceRun, a: int, b: int) -> PieceRun:
    sl = slice(a, b)
    o = {k: (v[sl] if isinstance(v, np.ndarray) and len(v) == len(r.t_s) else v)
         for k, v in r.out.items()}
    return PieceRun(r.t_s[sl], r.motor_angle_rad[sl], r.output_angle_rad[sl], r.torque_nm[sl],
                    None if r.torque_true_nm is None else r.torque_true_nm[sl], o, 0,
                    None if r.fold is None else r.fold[sl],
                    None if r.feedforward_nm is None else r.feedforward_nm[sl], r.segment)


def analysis_view(runs: list[PieceRun], which=None, max_total: int = ANALYSIS_MAX_SAMPLES,
                  chunk: int = ANALYSIS_CHUNK) -> list[PieceRun]:
    """The samples spectra and fits look at: after each piece's warm-up, of
    one fold if `which` is given (TRAIN for detection and fitting, HELD_OUT
    for judging), as contiguous stretches; a long record is thinned to
    evenly spaced contiguous chunks totalling at most max_total samples.
    Deterministic in the run lengths, so views of two replays of the same
    data cover the same samples.  Metrics (RMS values) always use all
    samples of their fold."""
    spans = []
    for i, r in enumerate(runs):
        if which is None or r.fold is None:
            stretches = [(r.warm, len(r.t_s))]
        else:
            m = (r.fold == which).astype(np.int8)
            d = np.diff(np.r_[0, m, 0])
            stretches = list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))
        for a, n in stretches:
            while a < n:
                b = min(a + chunk, n)
                if b - a >= 64:
                    spans.append((i, a, b))
                a = b
    total = sum(b - a for _, a, b in spans)
    if total <= max_total:
        keep = spans
    else:
        k = max(1, int(max_total // chunk))
        idx = np.unique(np.linspace(0, len(spans) - 1, k).round().astype(int))
        keep = [spans[j] for j in idx]
    return [_slice_run(runs[i], a, b) for i, a, b in keep]
