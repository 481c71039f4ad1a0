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
Motor current: with the model's current term (model.current_config, from a
joint configuration's current_* keys) the log's `motor_current_a` column goes
to hd_pipeline_run too, which forms T_cur as the firmware's tick does
(filter/hd_slow.c; a NaN sample gives T_cur = 0 and re-primes its low-pass).

Fixed angle profile (model.profile, docs/design/analyze.md "Profile"): output-locked
lines the geometry fit found run as output blocks with output_learn_scale 0
(they predict and turn with the output angle but never learn), their state
imported into the C filter at each piece's first sample
(hd_kf_profile_import), as the firmware does from a stored profile record.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import cfilter
from .loadlevel import load_of
from .loading import Data
from .model import Model

TRAIN, HELD_OUT, WARMUP = 0, 1, -1
FOLD_NAMES = {TRAIN: "in_sample", HELD_OUT: "out_of_sample"}
# Blocks of the timeline alternate A, B, A, B...: at least MIN_BLOCK_S long,
# at most MAX_TIMELINE_BLOCKS of them (not the filter's blocks).
MIN_BLOCK_S = 8.0
MAX_TIMELINE_BLOCKS = 8


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
    return np.asarray(th_m, float), np.asarray(th_o, float)


def warmup_samples(n, ts_s):
    # The filter starts from zero state: skip its convergence (and the
    # start-up at low speed) in every metric and spectrum.
    return int(min(n // 4, max(2.0 / ts_s, 50)))


def folds(data: Data) -> list[np.ndarray]:
    """Per piece, each sample's fold: the usable samples (after each piece's
    warm-up), laid end to end, are cut into 2 m blocks of equal length
    (m = the most that keeps a block >= MIN_BLOCK_S, at least 1, at most
    MAX_TIMELINE_BLOCKS / 2) that alternate TRAIN, HELD_OUT.  Deterministic in the
    piece lengths."""
    warm = [warmup_samples(len(p), data.ts_s) for p in data.pieces]
    usable = sum(len(p) - w for p, w in zip(data.pieces, warm))
    m = int(np.clip(usable * data.ts_s // (2 * MIN_BLOCK_S), 1, MAX_TIMELINE_BLOCKS // 2))
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


_ANGLES: dict = {}
# Samples replayed through the C filter since the last reset (the
# benchmark reports it as full-record equivalents).
REPLAYED = {"samples": 0}


def _angles_of(data: Data, gear_ratio):
    """Per piece (motor angle, output angle, their increments), computed
    once per log and gear ratio and shared by every replay."""
    key = (id(data.pieces[0]) if data.pieces else 0, len(data.pieces), gear_ratio)
    if key not in _ANGLES:
        if len(_ANGLES) >= 4:
            _ANGLES.clear()
        out = []
        for p in data.pieces:
            th_m, th_o = angles(p, gear_ratio, data.has_motor, data.has_output)
            out.append((th_m, th_o, np.diff(th_m, prepend=th_m[0]).astype(np.float32),
                        np.diff(th_o, prepend=th_o[0]).astype(np.float32)))
        _ANGLES[key] = (data.pieces, out)     # the pieces keep the key's id alive
    return _ANGLES[key][1]


_LOADS: dict = {}   # id(data.pieces) -> (pieces, the record's load_nm): one per record


def _record_load(data: Data, angles) -> float:
    """The load a profile fitted on this record is an average at
    (loadlevel.load_of: what `hdsense analyze` writes as load_nm); -1 when the
    motor never turns fast enough to say."""
    key = id(data.pieces)
    if key not in _LOADS:
        load = load_of(((p.torque_nm, p.feedforward_nm, a[0])
                                     for p, a in zip(data.pieces, angles)), data.ts_s)
        _LOADS[key] = (data.pieces, -1.0 if load is None else load)
    return _LOADS[key][1]


def replay(data: Data, model: Model, fold=None) -> list[PieceRun]:
    cfg = model.kf_config(data.ts_s)
    cfilter.check(cfg)
    exp = model.expected_config()
    cur = model.current_config(data.ts_s)
    fold = folds(data) if fold is None else fold
    runs = []
    angles = _angles_of(data, model.gear_ratio)
    load = _record_load(data, angles) if model.profile else -1.0
    for k, (p, (th_m, th_o, dm, do)) in enumerate(zip(data.pieces, angles)):
        ff = p.feedforward_nm
        imp = None
        if model.profile:
            lines = [(cfilter.LOCK_BY_NAME[ln.lock], int(round(ln.order)), ln.a_nm, ln.b_nm)
                     for ln in model.profile]
            imp = (lines, th_m[0], th_o[0], 0.0, load)
        out = cfilter.run(cfg, exp, p.torque_nm, dm, do, ff,
                          track_bandwidth_hz=model.track_bandwidth_hz, profile=imp,
                          motor_current_a=p.motor_current_a, current=cur)
        REPLAYED["samples"] += len(p)
        runs.append(PieceRun(p.t_s, th_m, th_o, p.torque_nm, p.torque_true_nm, out,
                             warmup_samples(len(p), data.ts_s), fold[k], ff, p.segment))
    return runs


def _rms(x):
    return float(np.sqrt(np.mean(x ** 2))) if len(x) else float("nan")


METRIC_CHUNK = 500_000      # samples at a time: temporaries stay small on long logs


def metrics(runs: list[PieceRun], which=None, bands: bool = False) -> dict:
    """RMS metrics over every sample after the warm-up, and per fold as
    in_sample_* (fold A) and out_of_sample_* (fold B); with `which`, the
    plain keys are those of that fold.  bands: also the error against truth
    split into frequency bands (error_bands).  Sums per fold accumulate run
    by run in float64 (np.bincount over the fold labels): no copy of the
    record."""
    truth = all(r.torque_true_nm is not None for r in runs)
    names = ("n", "e2", "nll", "r", "r2", "err2", "raw2")
    acc = {k: np.zeros(2) for k in names}
    frozen, total = 0, 0
    for r in runs:
        o = r.out
        for a in range(r.warm, len(r.t_s), METRIC_CHUNK):
            sl = slice(a, min(a + METRIC_CHUNK, len(r.t_s)))
            f = r.fold[sl].astype(np.intp)

            def add(key, x):
                acc[key] += np.bincount(f, weights=x, minlength=2)[:2]
            e = o["innovation_nm"][sl]
            s = o["innovation_var_nm2"][sl]
            res = o["torque_filtered_nm"][sl] - o["torque_expected_nm"][sl]
            acc["n"] += np.bincount(f, minlength=2)[:2]
            add("e2", e * e)
            add("nll", np.log(s) + e * e / s)
            add("r", res)
            add("r2", res * res)
            if truth:
                tt = r.torque_true_nm[sl]
                err = o["torque_filtered_nm"][sl] - tt
                raw = r.torque_nm[sl] - tt
                add("err2", err * err)
                add("raw2", raw * raw)
            frozen += int(np.count_nonzero(o["status"][sl] & cfilter.STATUS_FROZEN))
            total += len(e)

    def summary(sel):
        v = {k: float(acc[k][sel].sum()) for k in names}
        n = v["n"]
        if not n:
            return {"innovation_rms_nm": float("nan"), "innovation_nll": float("nan"),
                    "model_residual_rms_nm": float("nan"), "samples": 0}
        m = {"innovation_rms_nm": float(np.sqrt(v["e2"] / n)),
             "innovation_nll": float(0.5 * v["nll"] / n),
             "model_residual_rms_nm": float(np.sqrt(max(v["r2"] / n - (v["r"] / n) ** 2, 0.0))),
             "samples": int(n)}
        if truth:
            m["error_rms_nm"] = float(np.sqrt(v["err2"] / n))
            m["raw_error_rms_nm"] = float(np.sqrt(v["raw2"] / n))
        return m
    m = summary(slice(None) if which is None else [which])
    m["filter_resets"] = int(sum(r.out["reset_count"] for r in runs))
    m["frozen_fraction"] = frozen / total if total else 0.0
    for fo, name in FOLD_NAMES.items():
        for key, v in summary([fo]).items():
            m[f"{name}_{key}"] = v
    if bands and truth:
        m.update(error_bands(runs))
    return m


ERROR_SPLIT_HZ = 2.0


def _highpass(x, ts_s, split_hz, chunk=1 << 17):
    """Zero-phase high-pass with the squared magnitude of a 4th-order
    Butterworth (what filtfilt of one gives), applied in the frequency
    domain, chunk by chunk with 2 / split_hz of neighbouring samples on each
    side (the record's ends reflected), so memory stays bounded."""
    pad = min(len(x) - 1, int(round(2.0 / (split_hz * ts_s))))
    xp = np.r_[x[pad:0:-1], x, x[-2:-pad - 2:-1]] if pad > 0 else np.asarray(x)
    out = np.empty(len(x))
    for a in range(0, len(x), chunk):
        b = min(a + chunk, len(x))
        y = xp[a:b + 2 * pad]
        f = np.fft.rfftfreq(len(y), ts_s)
        r = (f / split_hz) ** 8
        out[a:b] = np.fft.irfft(np.fft.rfft(y) * (r / (1.0 + r)), len(y))[pad:pad + b - a]
    return out


def error_bands(runs: list[PieceRun], split_hz: float = ERROR_SPLIT_HZ) -> dict:
    """The error against truth split at split_hz (zero-phase, the squared
    magnitude of a 4th-order Butterworth, per piece after its warm-up).
    Above it: what the motor-locked (and fixed) blocks leave or inject, i.e.
    the ripple band at any useful motor speed.  Below it: output-locked
    lines, the offset and load torque the ripple blocks may take (an
    output-order-1 line at 1.5 rad/s is 0.24 Hz).  A piece shorter than
    2/split_hz counts as slow only.  Empty when the sample rate is below
    4 x split_hz."""
    ts = float(np.median(np.diff(runs[0].t_s))) if runs and len(runs[0].t_s) > 1 else 0.0
    if not ts > 0 or 1.0 / ts < 4 * split_hz:
        return {}
    fast, slow = [], []
    for r in runs:
        e = (r.filtered - r.torque_true_nm)[r.warm:]
        hp = _highpass(e, ts, split_hz) if len(e) * ts >= 2.0 / split_hz else np.zeros_like(e)
        fast.append(hp)
        slow.append(e - hp)
    fast, slow = np.concatenate(fast), np.concatenate(slow)
    return {"error_split_hz": split_hz,
            "error_fast_rms_nm": float(np.sqrt(np.mean(fast ** 2))),
            "error_slow_rms_nm": float(np.sqrt(np.mean(slow ** 2)))}


ANALYSIS_MAX_SAMPLES = 400_000
ANALYSIS_CHUNK = 100_000


def _slice_run(r: PieceRun, a: int, b: int, copy: bool = False) -> PieceRun:
    sl = slice(a, b)

    def cut(v):
        if v is None:
            return None
        return v[sl].copy() if copy else v[sl]
    o = {k: (cut(v) if isinstance(v, np.ndarray) and len(v) == len(r.t_s) else v)
         for k, v in r.out.items()}
    return PieceRun(cut(r.t_s), cut(r.motor_angle_rad), cut(r.output_angle_rad),
                    cut(r.torque_nm), cut(r.torque_true_nm), o, 0, cut(r.fold),
                    cut(r.feedforward_nm), r.segment)


def analysis_view(runs: list[PieceRun], which=None, max_total: int = ANALYSIS_MAX_SAMPLES,
                  chunk: int = ANALYSIS_CHUNK, copy: bool = False) -> list[PieceRun]:
    """The samples spectra and fits look at: after each piece's warm-up, of
    one fold if `which` is given (TRAIN for detection and fitting, HELD_OUT
    for judging), as contiguous stretches; a long record is thinned to
    evenly spaced contiguous chunks totalling at most max_total samples.
    Deterministic in the run lengths, so views of two replays of the same
    data cover the same samples.  Metrics (RMS values) always use all
    samples of their fold.  copy: the view owns its arrays (the replay can
    be dropped)."""
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
    return [_slice_run(runs[i], a, b, copy) for i, a, b in keep]


def window(runs: list[PieceRun], seconds: float = 4.0) -> dict:
    """A short stretch after the warm-up of the longest run (for the torque
    plot): time, measured, filtered and true torque, copied."""
    k = int(np.argmax([len(r.t_s) for r in runs]))
    r = runs[k]
    ts = float(np.median(np.diff(r.t_s[:100])))
    sl = slice(r.warm, min(len(r.t_s), r.warm + int(seconds / ts)))
    return {"piece": k, "t_s": np.array(r.t_s[sl], float), "torque_nm": np.array(r.torque_nm[sl], float),
            "filtered_nm": r.filtered[sl].copy(),
            "true_nm": None if r.torque_true_nm is None else np.array(r.torque_true_nm[sl], float)}
