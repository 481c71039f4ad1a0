"""Load a torque log (CSV or candump) and turn it into clean, uniformly
sampled pieces the filter can replay.  The log contract is in
docs/design/analyze.md ("Input"); what is done to messy data, in order (all of it
counted in Data.cleaning and said in Data.notes):

  0. the path must be a readable regular file (a directory, FIFO, device or
     unreadable file is refused before anything is read);
  1. CSV: UTF-8 with or without BOM, CRLF or LF, quoted fields; rows with
     fewer fields than the header and empty or unparsable fields are
     counted; a row missing a value the analysis needs (time, torque, an
     angle, the feed-forward, the truth) is dropped;
  2. units: the time column in seconds, or detected as milli/microseconds
     from its median step; angles in radians, or detected as degrees from
     an implausible speed, a gear ratio 57.3x off or the velocity column;
     what cannot be decided is refused with a message saying which (give
     --time-unit / --angle-unit);
  3. per `segment` value, in file order: a time that steps back (a reset,
     a clock step, two runs joined end to end) starts a new segment; a
     repeated time stamp drops the later row; the sample period ts is the
     median time step;
  4. a step > GAP_FACTOR * ts is a gap and splits the segment (the filter
     restarts after it; a gap is never read as a change of anything); a
     shorter step (a few lost samples) is bridged by the resampling below;
  5. rows that repeat the previous torque and angles exactly (a standing
     joint with a quantized sensor, or a logger repeating itself) are data
     and kept (counted);
  6. angles are unwrapped; each piece is linearly resampled onto a uniform
     grid of period ts when its steps jitter by more than JITTER_TOL;
     pieces shorter than MIN_PIECE samples are dropped.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .errors import InputError
from .logfile import ANGLES, KNOWN, REQUIRED_IF_PRESENT, TORQUE, check_path, read_file

__all__ = ["ANGLES", "KNOWN", "REQUIRED_IF_PRESENT", "TORQUE", "Data", "InputError", "Piece",
           "check_path", "load"]

GAP_FACTOR = 5.0
MIN_PIECE = 64
JITTER_TOL = 0.01
# The analysis skips each piece's first 2 s (filter convergence) and needs
# something after it.
MIN_DURATION_S = 4.0

# Sample periods a torque log can have [s] (50 kHz .. 20 Hz); a median step
# outside it is read in other units when exactly one of ms / us fits.
TS_RANGE_S = (2e-5, 0.05)
TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
# Fastest plausible speeds of a geared joint [rad/s]: a motor at 19 000 rpm,
# a gear output at 290 rpm.  Faster in radians but plausible in degrees ->
# the column is in degrees.
MAX_SPEED_RAD_S = {"motor_angle_rad": 2000.0, "output_angle_rad": 30.0}
GEAR_RATIO_RANGE = (20.0, 400.0)
DEG = math.pi / 180.0

@dataclass
class Piece:
    """One contiguous, uniformly sampled stretch of data."""
    segment: str
    t_s: np.ndarray
    torque_nm: np.ndarray
    motor_angle_rad: np.ndarray | None
    output_angle_rad: np.ndarray | None
    torque_true_nm: np.ndarray | None = None
    output_velocity_rad_s: np.ndarray | None = None
    feedforward_nm: np.ndarray | None = None
    motor_current_a: np.ndarray | None = None

    def __len__(self):
        return len(self.t_s)


@dataclass
class Data:
    pieces: list[Piece]
    ts_s: float
    has_motor: bool
    has_output: bool
    has_truth: bool
    source: str
    cleaning: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    has_feedforward: bool = False
    has_current: bool = False
    units: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return sum(len(p) for p in self.pieces)

    def subset(self, pieces) -> "Data":
        return Data(list(pieces), self.ts_s, self.has_motor, self.has_output, self.has_truth,
                    self.source, has_feedforward=self.has_feedforward,
                    has_current=self.has_current, units=self.units)


# --- units ---------------------------------------------------------------------

def _time_unit(t, seg, given, path):
    """Scale of the time column (1, 1e-3 or 1e-6) and how it was decided."""
    if given:
        return TIME_SCALE[given], f"time column in {given} (--time-unit)"
    k = _stride(len(t))
    d = t[1::k] - t[:-1:k]
    same = seg[1::k] == seg[:-1:k]
    d = d[same & (d > 0) & np.isfinite(d)]
    if len(d) == 0:
        raise InputError(f"{path}: no increasing time steps in 't_s'")
    step = float(np.median(d))
    fits = [u for u, s in TIME_SCALE.items() if TS_RANGE_S[0] <= step * s <= TS_RANGE_S[1]]
    if fits and fits[0] == "s":
        return 1.0, None
    if len(fits) == 1:
        u = fits[0]
        return TIME_SCALE[u], (f"time column read as {u}: its median step {step:g} would be a "
                               f"{1 / step:.3g} Hz log in seconds, {1 / (step * TIME_SCALE[u]):.5g} "
                               f"Hz in {u} (override with --time-unit)")
    which = " or ".join(fits) if fits else "none of s, ms, us"
    raise InputError(f"{path}: cannot tell the unit of 't_s': median step {step:g} fits "
                     f"{which} for a sample rate of 20 Hz..50 kHz; give --time-unit s|ms|us")


def _stride(n):
    """A step that leaves at most UNIT_SAMPLES of n (unit checks need
    robust statistics, not every sample)."""
    return max(1, n // UNIT_SAMPLES)


UNIT_SAMPLES = 200_000


def _speed_p90(angle, t, seg):
    k = _stride(len(t))
    d = angle[1::k] - angle[:-1:k]
    dt = t[1::k] - t[:-1:k]
    ok = (seg[1::k] == seg[:-1:k]) & (dt > 0) & np.isfinite(d)
    s = np.abs(d[ok]) / dt[ok]
    s = s[s > 0]
    return float(np.percentile(s, 90)) if len(s) > 10 else 0.0


def _angle_units(cols, seg, given, path):
    """{column: 'rad' | 'deg'} and notes."""
    names = [a for a in ANGLES if a in cols]
    if given:
        return {a: given for a in names}, [f"angles in {given} (--angle-unit)"]
    unit, notes = {}, []
    t = cols["t_s"]
    for a in names:
        p90 = _speed_p90(cols[a], t, seg)
        lim = MAX_SPEED_RAD_S[a]
        unit[a] = "rad"
        if p90 > lim:
            if p90 * DEG <= lim:
                unit[a] = "deg"
                notes.append(f"{a} read as degrees: it moves at {p90:.4g}/s (90th percentile), "
                             f"not plausible in rad/s (> {lim:g}), {p90 * DEG:.3g} rad/s in "
                             "degrees (override with --angle-unit)")
            else:
                raise InputError(f"{path}: {a} moves at {p90:.4g}/s (90th percentile): not a "
                                 "plausible joint speed in rad/s or deg/s; check the column's "
                                 "unit (--angle-unit rad|deg)")
    if "output_velocity_rad_s" in cols and "output_angle_rad" in cols and unit[
            "output_angle_rad"] == "rad":
        k = _stride(len(t))
        v, th = cols["output_velocity_rad_s"], cols["output_angle_rad"]
        d, dt = th[1::k] - th[:-1:k], t[1::k] - t[:-1:k]
        vm = 0.5 * (v[1::k] + v[:-1:k])
        ok = (seg[1::k] == seg[:-1:k]) & (dt > 0) & np.isfinite(vm) & np.isfinite(d)
        big = ok & (np.abs(vm) > 0.2 * (np.percentile(np.abs(vm[ok]), 90) if ok.any() else 0))
        if big.sum() > 20:
            k = float(np.median((d[big] / dt[big]) / vm[big]))
            if abs(k / (1 / DEG) - 1) < 0.1:
                unit["output_angle_rad"] = "deg"
                notes.append("output_angle_rad read as degrees: it changes 57.3x faster than "
                             "output_velocity_rad_s says (override with --angle-unit)")
    if len(names) == 2 and all(unit[a] == "rad" for a in names):
        n = _encoder_ratio(cols["motor_angle_rad"], cols["output_angle_rad"], seg)
        lo, hi = GEAR_RATIO_RANGE
        if n and not lo <= abs(n) <= hi:
            if lo <= abs(n) / DEG <= hi:
                unit["output_angle_rad"] = "deg"
                notes.append(f"output_angle_rad read as degrees: motor/output increments give a "
                             f"gear ratio of {n:.4g} in radians, {n / DEG:.4g} with the output in "
                             "degrees (override with --angle-unit)")
            elif lo <= abs(n) * DEG <= hi:
                unit["motor_angle_rad"] = "deg"
                notes.append(f"motor_angle_rad read as degrees: motor/output increments give a "
                             f"gear ratio of {n:.4g} in radians, {n * DEG:.4g} with the motor in "
                             "degrees (override with --angle-unit)")
    return unit, notes


def _encoder_ratio(m, o, seg):
    k = _stride(len(m))
    dm, do = m[1::k] - m[:-1:k], o[1::k] - o[:-1:k]
    ok = (seg[1::k] == seg[:-1:k]) & np.isfinite(dm) & np.isfinite(do) & (np.abs(do) > 0)
    if not ok.any():
        return None
    # Wraps are rare steps far above the rest: leave out the largest 1 %.
    ok &= (np.abs(dm) <= np.percentile(np.abs(dm[ok]), 99)) & (
        np.abs(do) <= np.percentile(np.abs(do[ok]), 99))
    den = float(np.sum(do[ok] ** 2))
    return float(np.sum(dm[ok] * do[ok]) / den) if den > 0 else None


# --- cleaning ------------------------------------------------------------------

def _new_stats(n):
    return {"rows_in": int(n), "blank_rows": 0, "short_rows": 0, "empty_fields": 0,
            "unparsable_fields": 0, "non_finite": 0, "time_steps_back": 0,
            "duplicate_time": 0, "repeated_values": 0, "gaps": 0, "gap_time_s": 0.0,
            "bridged_steps": 0,
            "resampled_pieces": 0, "dropped_short_pieces": 0, "dropped_short_rows": 0,
            "segments": 0, "columns_ignored": []}


def load(path, fs_hz: float | None = None, time_unit: str | None = None,
         angle_unit: str | None = None, joint: str | None = None, window_ns=None) -> Data:
    """joint: which JointState joint of a bag (MCAP, rosbag2; rosio.bagin);
    window_ns: the bag's messages in [start, stop) log time only."""
    from ..rosio import bagin
    stats = _new_stats(0)
    bag_notes = []
    if bagin.is_bag(path):
        cols, bag_notes = bagin.read(path, joint, window_ns)
        source = "bag"
    else:
        path = check_path(path)
        cols, source = read_file(path, stats)
        if joint:
            bag_notes = [f"--joint {joint} ignored: {source} input has one joint"]
    n = len(cols[TORQUE])
    stats["rows_in"] = int(n) + stats["blank_rows"]
    seg = cols.pop("segment", None)
    seg = np.zeros(n, dtype="<U1") if seg is None else np.asarray(seg)
    # Rows missing a value the analysis needs.
    ok = np.ones(n, bool)
    for k in REQUIRED_IF_PRESENT:
        if k in cols:
            ok &= np.isfinite(cols[k])
    stats["non_finite"] = int((~ok).sum())
    if stats["non_finite"]:
        cols = {k: v[ok] for k, v in cols.items()}
        seg = seg[ok]
    n = int(ok.sum())
    if n < 2:
        raise InputError(f"{path}: fewer than 2 valid rows")
    notes = []
    if "t_s" in cols:
        scale, note = _time_unit(cols["t_s"], seg, time_unit, path)
        cols["t_s"] = cols["t_s"] * scale
        if note:
            notes.append(note)
        if fs_hz:
            notes.append(f"--fs {fs_hz:g} Hz ignored: the log has a time column")
    else:
        if not fs_hz:
            raise InputError(f"{path}: no 't_s' column: give the sample rate with --fs HZ")
        if not (math.isfinite(fs_hz) and fs_hz > 0):
            raise InputError(f"--fs must be a positive number (got {fs_hz})")
        # Time restarts per segment value.
        t = np.empty(n)
        for s in _segment_names(seg):
            m = seg == s
            t[m] = np.arange(int(m.sum())) / fs_hz
        cols["t_s"] = t
    units, unotes = _angle_units(cols, seg, angle_unit, path)
    notes += unotes
    for a, u in units.items():
        if u == "deg":
            cols[a] = cols[a] * DEG
    raw = []
    names = _segment_names(seg)
    for s in names:
        sub = cols if len(names) == 1 else {k: v[seg == s] for k, v in cols.items()}
        raw.extend(_split_back_steps(str(s), sub, stats))
    stats["segments"] = len({s for s, _ in raw})
    steps = [np.diff(sub["t_s"]) for _, sub in raw if len(sub["t_s"]) > 1]
    if not steps:
        raise InputError(f"{path}: fewer than 2 valid rows")
    ts = float(np.median(np.concatenate(steps)))
    if not (ts > 0 and math.isfinite(ts)):
        raise InputError(f"{path}: cannot determine the sample period (median step {ts})")
    pieces = []
    for s, sub in raw:
        pieces.extend(_split_and_resample(s, sub, ts, stats))
    if not pieces:
        raise InputError(f"{path}: no contiguous stretch of at least {MIN_PIECE} samples "
                         f"(sample period {ts * 1e3:.4g} ms)")
    total_s = sum(len(p) for p in pieces) * ts
    if total_s < MIN_DURATION_S:
        raise InputError(f"{path}: {total_s:.3g} s of usable data ({sum(len(p) for p in pieces)} "
                         f"samples at {1 / ts:.5g} Hz); the analysis needs at least "
                         f"{MIN_DURATION_S:g} s (the filter converges over the first 2 s)")
    data = Data(pieces, ts, "motor_angle_rad" in cols, "output_angle_rad" in cols,
                "torque_true_nm" in cols, source, stats,
                has_feedforward="torque_feedforward_nm" in cols,
                has_current="motor_current_a" in cols,
                units={"time": time_unit or ("s" if "t_s" in cols else "--fs"), **units})
    data.notes = bag_notes + notes + _describe(stats, ts)
    return data


def _segment_names(seg):
    """Distinct segment values in order of first appearance."""
    if len(seg) and (seg == seg[0]).all():
        return [seg[0]]
    _, first = np.unique(seg, return_index=True)
    return [seg[i] for i in sorted(first)]


def _split_back_steps(s, sub, stats):
    """File order is kept: a time that steps back starts a new segment
    (named s, s#2, ...); a repeated time stamp drops the later row; rows
    repeating the previous values are counted and kept."""
    t = sub["t_s"]
    d = np.diff(t)
    dup = np.r_[False, d == 0]
    stats["duplicate_time"] += int(dup.sum())
    if dup.any():
        sub = {k: v[~dup] for k, v in sub.items()}
    t = sub["t_s"]
    back = np.flatnonzero(np.diff(t) < 0) + 1
    stats["time_steps_back"] += len(back)
    same = np.ones(len(t) - 1, bool) if len(t) > 1 else np.zeros(0, bool)
    same &= sub[TORQUE][1:] == sub[TORQUE][:-1]
    for a in ANGLES:
        if a in sub:
            same &= sub[a][1:] == sub[a][:-1]
    stats["repeated_values"] += int(same.sum())
    out = []
    for j, (a, b) in enumerate(zip(np.r_[0, back], np.r_[back, len(t)])):
        name = s if j == 0 else f"{s}#{j + 1}"
        out.append((name, {k: v[a:b] for k, v in sub.items()}))
    return out


def _split_and_resample(s: str, sub: dict, ts: float, stats: dict) -> list[Piece]:
    t = sub["t_s"]
    if len(t) < 2:
        stats["dropped_short_pieces"] += 1
        stats["dropped_short_rows"] += len(t)
        return []
    dt = np.diff(t)
    cut = np.flatnonzero(dt > GAP_FACTOR * ts) + 1
    stats["gaps"] += len(cut)
    stats["bridged_steps"] += int(np.sum((dt > 1.5 * ts) & (dt <= GAP_FACTOR * ts)))
    stats["gap_time_s"] += float(dt[cut - 1].sum()) if len(cut) else 0.0
    out = []
    for a, b in zip(np.r_[0, cut], np.r_[cut, len(t)]):
        if b - a < MIN_PIECE:
            stats["dropped_short_pieces"] += 1
            stats["dropped_short_rows"] += int(b - a)
            continue
        part = {k: v[a:b] for k, v in sub.items()}
        for k in ANGLES:
            if k in part:
                part[k] = np.unwrap(part[k])
        tp = part["t_s"]
        d = np.diff(tp)
        if np.max(np.abs(d - ts)) > JITTER_TOL * ts:
            grid = tp[0] + ts * np.arange(int(np.floor((tp[-1] - tp[0]) / ts + 1e-9)) + 1)
            part = {k: np.interp(grid, tp, v) for k, v in part.items() if k != "t_s"} | {
                "t_s": grid}
            stats["resampled_pieces"] += 1
        out.append(Piece(s, part["t_s"], part[TORQUE], part.get("motor_angle_rad"),
                         part.get("output_angle_rad"), part.get("torque_true_nm"),
                         part.get("output_velocity_rad_s"), part.get("torque_feedforward_nm"),
                         part.get("motor_current_a")))
    return out


def _describe(c: dict, ts: float) -> list[str]:
    notes = [f"sample period {ts * 1e3:.4g} ms ({1 / ts:.5g} Hz, median time step)"]
    if c["columns_ignored"]:
        notes.append(f"ignored unknown column(s): {', '.join(c['columns_ignored'])}")
    if c["short_rows"] or c["empty_fields"] or c["unparsable_fields"]:
        notes.append(f"{c['short_rows']} rows with fewer fields than the header, "
                     f"{c['empty_fields']} empty and {c['unparsable_fields']} unparsable fields "
                     "(read as missing)")
    if c["blank_rows"]:
        notes.append(f"skipped {c['blank_rows']} blank lines")
    if c["non_finite"]:
        notes.append(f"dropped {c['non_finite']} rows with a missing or non-finite value")
    if c["time_steps_back"]:
        notes.append(f"the time steps back {c['time_steps_back']} times (a reset, a clock step or "
                     "joined runs): each starts a new segment")
    if c["duplicate_time"]:
        notes.append(f"dropped {c['duplicate_time']} rows with a repeated time stamp")
    if c["repeated_values"]:
        notes.append(f"{c['repeated_values']} rows repeat the previous torque and angle exactly "
                     "(a standing joint with a quantized sensor, or a repeated sample): kept as data")
    if c["gaps"]:
        notes.append(f"split at {c['gaps']} gaps (> {GAP_FACTOR} samples, "
                     f"{c['gap_time_s']:.3g} s in total); the filter restarts after each")
    if c["bridged_steps"]:
        notes.append(f"{c['bridged_steps']} steps of 1.5..{GAP_FACTOR:g} sample periods (lost "
                     "samples) bridged by the resampling")
    if c["resampled_pieces"]:
        notes.append(f"resampled {c['resampled_pieces']} irregularly sampled stretches "
                     "onto a uniform grid (linear interpolation)")
    if c["dropped_short_pieces"]:
        notes.append(f"dropped {c['dropped_short_pieces']} stretches shorter than "
                     f"{MIN_PIECE} samples ({c['dropped_short_rows']} rows)")
    return notes
