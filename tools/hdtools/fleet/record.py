"""One log -> one compact record (a flat row of the fleet's Parquet store).

The record runs the analysis pipeline's own parts, not a second analysis:
the loader (hdtools.analysis.loading: units, gaps, cleaning), the gear
ratio (pipeline.gear_of), the folds, the reference model (the paper's
structure with the recommended tuning, Model.starting) replayed once
through the C filter (replay.replay), its metrics in and out of sample, and
line fits (spectra.fit_line, the fit analyze reports lines with).  That is
the "light" path, ~1/300 of the time of the whole loop; with loop=True the
whole `analyze` loop runs too and the record keeps what it added.

Every value is a deterministic function of the log's bytes and the options:
the same log gives the same record, bit for bit, on any worker."""
from __future__ import annotations

import math

import numpy as np

from ..analysis import loading, pipeline, replay as rp, spectra
from ..analysis.model import Model, estimate_noise_nm, slow_step_nm
from . import chunks

RECORD_VERSION = 1
# Orders whose raw-torque line each record fits: the modelled meshing lines
# (motor 2, 4), misalignment (output 1), and where new lines of damage show.
MOTOR_SCAN = (1, 2, 3, 4)
OUTPUT_SCAN = (1, 2)
GEAR_TOLERANCE = 0.02       # a log whose ratio is 2 % off the fleet's is another joint type
SLOW_BLOCK_S = 0.02         # slow-torque regression on 20 ms means (as detect.py)

ID_COLUMNS = (("key", "string"), ("path", "string"), ("chunk", "int64"), ("joint", "string"),
              ("start_utc", "string"), ("start_day", "float64"), ("status", "string"),
              ("message", "string"))


def line_columns():
    cols = []
    for lock, orders in (("motor", MOTOR_SCAN), ("output", OUTPUT_SCAN)):
        for k in orders:
            cols += [(f"{lock}{k}_amp_nm", "float64"), (f"{lock}{k}_phase_rad", "float64")]
    return cols


VALUE_COLUMNS = (
    ("chunk_offset_s", "float64"), ("duration_s", "float64"), ("samples", "int64"), ("ts_s", "float64"),
    ("gear_ratio", "float64"), ("gear_source", "string"),
    *line_columns(),
    ("motor2_filtered_amp_nm", "float64"), ("motor4_filtered_amp_nm", "float64"),
    ("viscous_nm_s_rad", "float64"), ("coulomb_nm", "float64"),
    ("gain_vs_feedforward", "float64"), ("offset_nm", "float64"),
    ("slow_fit_out_of_sample_rms_nm", "float64"),
    ("noise_nm", "float64"), ("gaps", "int64"), ("bad_fields", "int64"),
    ("filter_resets", "int64"), ("frozen_fraction", "float64"),
    ("in_sample_innovation_rms_nm", "float64"), ("out_of_sample_innovation_rms_nm", "float64"),
    ("loop_run", "bool"), ("loop_added", "string"),
    ("loop_out_of_sample_innovation_after_nm", "float64"))
COLUMNS = ID_COLUMNS + VALUE_COLUMNS


def _lines(runs):
    """Amplitude and phase of each scanned order in the raw torque (slow
    torque removed first), and of the modelled motor lines in the filtered
    torque (what the filter leaves)."""
    raw = [np.asarray(r.torque_nm, float)[r.warm:] for r in runs]
    filt = [r.filtered[r.warm:] for r in runs]
    ts = float(np.median(np.diff(runs[0].t_s)))
    out = {}

    def fit(sig, lock, k):
        ph = [k * (r.motor_angle_rad if lock == "motor" else r.output_angle_rad)[r.warm:]
              for r in runs]
        amp, phase, _ = spectra.fit_line(spectra.highpass_for_line(sig, ph, ts), ph)
        return amp, phase

    for lock, orders in (("motor", MOTOR_SCAN), ("output", OUTPUT_SCAN)):
        for k in orders:
            out[f"{lock}{k}_amp_nm"], out[f"{lock}{k}_phase_rad"] = fit(raw, lock, k)
    for k in (2, 4):
        out[f"motor{k}_filtered_amp_nm"] = fit(filt, "motor", k)[0]
    return out


def _block_means(x, n):
    m = len(x) // n
    return np.asarray(x[:m * n], float).reshape(m, n).mean(axis=1)


def _slow_fit(runs, ts_s):
    """Friction, gain and offset: the filtered torque's 20 ms means regressed
    on [feed-forward, output velocity, its sign, 1] in fold A (the
    controller's feed-forward knows the payload and inertia, not the
    friction; without a feed-forward the gain is not identifiable: NaN).
    The fit's residual in fold B says whether it holds."""
    n = max(1, int(round(SLOW_BLOCK_S / ts_s)))
    rows = {rp.TRAIN: [], rp.HELD_OUT: []}
    for r in runs:
        w = np.gradient(np.asarray(r.output_angle_rad, float), ts_s)
        cols = [r.filtered, w]
        ff = r.feedforward_nm
        cols.insert(1, np.zeros_like(w) if ff is None else np.asarray(ff, float))
        for f in rows:
            sel = r.fold == f
            # contiguous runs of one fold: block means within them only
            edges = np.flatnonzero(np.diff(np.r_[0, sel.astype(np.int8), 0]))
            for a, b in zip(edges[::2], edges[1::2]):
                rows[f].append(np.column_stack([_block_means(c[a:b], n) for c in cols]))
    has_ff = all(r.feedforward_nm is not None for r in runs)

    def design(m):
        cols = ([m[:, 1]] if has_ff else []) + [m[:, 2], np.sign(m[:, 2]), np.ones(len(m))]
        return np.column_stack(cols), m[:, 0]

    a = np.concatenate(rows[rp.TRAIN]) if rows[rp.TRAIN] else np.zeros((0, 3))
    x, y = design(a)
    if len(y) < 10:
        return {"viscous_nm_s_rad": math.nan, "coulomb_nm": math.nan,
                "gain_vs_feedforward": math.nan, "offset_nm": math.nan,
                "slow_fit_out_of_sample_rms_nm": math.nan}
    coef = np.linalg.lstsq(x, y, rcond=None)[0]
    b_rows = np.concatenate(rows[rp.HELD_OUT]) if rows[rp.HELD_OUT] else a
    xb, yb = design(b_rows)
    gain = float(coef[0]) if has_ff else math.nan
    c = coef[1:] if has_ff else coef
    return {"viscous_nm_s_rad": float(c[0]), "coulomb_nm": float(c[1]),
            "gain_vs_feedforward": gain, "offset_nm": float(c[2]),
            "slow_fit_out_of_sample_rms_nm": float(np.sqrt(np.mean((yb - xb @ coef) ** 2)))}


def _quiet(*_a):
    pass


def analyze_log(path, gear_ratio=None, motor_orders=(2, 4), output_orders=(1,), loop=False,
                byte_range=None, window_ns=None, origin_ns=0, joint=None):
    """The record's values for one log, for the chunk of its data rows in
    byte_range, or for a bag's messages in window_ns (chunks.py; origin_ns:
    the bag's first message, where the chunk offsets count from); joint: the
    bag's joint to read (None: its only one).  loading.InputError on bad
    input."""
    if byte_range is None:
        rec, _ = _analyze(path, gear_ratio, motor_orders, output_orders, loop,
                          joint=joint, window_ns=window_ns)
        rec["chunk_offset_s"] = 0.0 if window_ns is None else (window_ns[0] - origin_ns) * 1e-9
        return rec
    with chunks.extracted(path, byte_range) as (tmp, where):
        try:
            rec, data = _analyze(tmp, gear_ratio, motor_orders, output_orders, loop)
        except loading.InputError as exc:
            raise loading.InputError(str(exc).replace(tmp, str(path))) from None
    scale = loading.TIME_SCALE.get(data.units.get("time", "s"), 1.0)
    first_t = where.get("first_t")
    rec["chunk_offset_s"] = (where["offset_s"] if "offset_s" in where else
                             float(data.pieces[0].t_s[0]) - first_t * scale
                             if first_t is not None else math.nan)
    return rec


def _analyze(path, gear_ratio, motor_orders, output_orders, loop, joint=None, window_ns=None):
    data = loading.load(path, joint=joint, window_ns=window_ns)
    g = pipeline.gear_of(data, None, _quiet)
    if gear_ratio is not None:
        if abs(g["value"] - gear_ratio) > GEAR_TOLERANCE * gear_ratio and g["source"] != "assumed":
            raise loading.InputError(f"gear ratio {g['value']:.4g} ({g['source']}), "
                                     f"the fleet's is {gear_ratio:g} (--gear-ratio)")
        g = {"value": float(gear_ratio), "source": "given"}
    noise = float(np.median([estimate_noise_nm(p.torque_nm) for p in data.pieces]))
    fold = rp.folds(data)
    slow = float(np.median([slow_step_nm(p.torque_nm - (0 if p.feedforward_nm is None
                                                        else p.feedforward_nm), data.ts_s)
                            for p in data.pieces]))
    model = Model.starting(g["value"], data.ts_s, noise, motor_orders, output_orders, 0.0,
                           slow_step_nm=slow)
    runs = rp.replay(data, model, fold)
    met = rp.metrics(runs)
    cl = data.cleaning
    rec = {"duration_s": float(sum(p.t_s[-1] - p.t_s[0] for p in data.pieces)),
           "samples": int(data.n), "ts_s": float(data.ts_s),
           "gear_ratio": float(g["value"]), "gear_source": g["source"],
           **_lines(runs), **_slow_fit(runs, data.ts_s), "noise_nm": noise,
           "gaps": int(cl.get("gaps", 0)),
           "bad_fields": int(sum(cl.get(k, 0) for k in ("short_rows", "empty_fields",
                                                        "unparsable_fields", "non_finite"))),
           "filter_resets": int(met.get("filter_resets", 0)),
           "frozen_fraction": float(met.get("frozen_fraction", 0.0)),
           "in_sample_innovation_rms_nm": float(met["in_sample_innovation_rms_nm"]),
           "out_of_sample_innovation_rms_nm": float(met["out_of_sample_innovation_rms_nm"]),
           "loop_run": False, "loop_added": None,
           "loop_out_of_sample_innovation_after_nm": math.nan}
    if loop:
        rep = pipeline.analyze(path, gear_ratio=g["value"], motor_orders=motor_orders,
                               output_orders=output_orders, log=_quiet, joint=joint,
                               window_ns=window_ns)
        rec["loop_run"] = True
        rec["loop_added"] = "; ".join(pipeline.label(e) for e in rep["effects"] if e["added"])
        rec["loop_out_of_sample_innovation_after_nm"] = float(
            rep["metrics_after"]["out_of_sample_innovation_rms_nm"])
    return rec, data
