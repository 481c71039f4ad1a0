"""Load a torque log (CSV or candump) and turn it into clean, uniformly
sampled segments the filter can replay.

What is done to messy data, in order, per `segment` value (everything is
counted and reported in Data.notes / Data.cleaning):
  1. rows with a non-finite time, torque or angle are dropped;
  2. rows are sorted by time (out-of-order rows counted);
  3. rows with a repeated time stamp are dropped (first kept);
  4. stale rows (torque and angle identical to the previous row: the logger
     repeated an old sample) are dropped;
  5. angles are unwrapped (a jump over pi between samples is a wrap);
  6. the nominal period ts is the median time step; a step > GAP_FACTOR * ts
     is a gap and splits the segment (the filter restarts after a gap);
  7. each piece is linearly resampled onto a uniform grid of period ts when
     its time steps jitter by more than 1 %; pieces shorter than MIN_PIECE
     samples are dropped.
"""
from __future__ import annotations

import csv
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

GAP_FACTOR = 2.5
MIN_PIECE = 64
JITTER_TOL = 0.01

KNOWN = ("t_s", "torque_nm", "motor_angle_rad", "output_angle_rad",
         "output_velocity_rad_s", "segment", "torque_true_nm")


class InputError(ValueError):
    """Bad input: the message says what is wrong and what is expected."""


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

    @property
    def n(self) -> int:
        return sum(len(p) for p in self.pieces)


def _read_csv(path: Path) -> tuple[dict, list[str]]:
    with open(path, newline="") as fh:
        header = next(csv.reader(fh), None)
    if not header:
        raise InputError(f"{path}: empty file, expected a CSV header line")
    header = [h.strip() for h in header]
    if "torque_nm" not in header:
        raise InputError(f"{path}: no 'torque_nm' column (columns: {', '.join(header)}); "
                         "the measured torque is required")
    if "motor_angle_rad" not in header and "output_angle_rad" not in header:
        raise InputError(f"{path}: needs 'motor_angle_rad' or 'output_angle_rad' "
                         f"(columns: {', '.join(header)})")
    num = [h for h in header if h in KNOWN and h != "segment"]
    idx = [header.index(h) for h in num]
    cols: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # "no data" is reported below
        try:
            arr = np.loadtxt(path, delimiter=",", skiprows=1, usecols=idx, dtype=np.float64,
                             ndmin=2)
        except ValueError:
            # Empty or non-numeric fields: slower reader that turns them into NaN.
            arr = np.genfromtxt(path, delimiter=",", skip_header=1, usecols=idx,
                                dtype=np.float64, ndmin=2, invalid_raise=False)
    if arr.size == 0:
        raise InputError(f"{path}: no data rows")
    for j, h in enumerate(num):
        cols[h] = arr[:, j]
    if "segment" in header:
        j = header.index("segment")
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))[1:]
        seg = np.array([r[j].strip() if len(r) > j else "" for r in rows if r])
        if len(seg) != len(arr):
            raise InputError(f"{path}: rows have inconsistent field counts")
        cols["segment"] = seg
    return cols, header


def _read_candump(path: Path) -> tuple[dict, list[str]]:
    from . import candump
    return candump.read(path), []


def load(path: str | Path, fs_hz: float | None = None) -> Data:
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file")
    with open(path, "rb") as fh:
        head = fh.read(64)
    if head.lstrip().startswith(b"("):
        cols, _ = _read_candump(path)
        source = "candump"
    else:
        try:
            cols, _ = _read_csv(path)
        except UnicodeDecodeError as exc:
            raise InputError(f"{path}: not a text CSV (byte {exc.start}: "
                             f"{exc.reason})") from None
        source = "csv"
    n = len(cols["torque_nm"])
    if "t_s" not in cols:
        if not fs_hz:
            raise InputError(f"{path}: no 't_s' column: give the sample rate with --fs HZ")
        cols["t_s"] = np.arange(n) / fs_hz
        # With a segment column, time restarts per segment.
    seg = cols.get("segment")
    if seg is None:
        seg = np.zeros(n, dtype="<U1")
    has_motor = "motor_angle_rad" in cols
    has_output = "output_angle_rad" in cols
    clean = {"rows_in": int(n), "non_finite": 0, "out_of_order": 0, "duplicate_time": 0,
             "stale": 0, "gaps": 0, "gap_time_s": 0.0, "resampled_pieces": 0,
             "dropped_short_pieces": 0, "segments": 0}
    raw_pieces = []
    for s in dict.fromkeys(seg.tolist()):
        m = seg == s
        sub = {k: v[m] for k, v in cols.items() if k != "segment"}
        if "t_s" not in cols or fs_hz and "t_s" not in cols:
            pass
        raw_pieces.append((str(s), sub))
    clean["segments"] = len(raw_pieces)
    steps = []
    prepared = []
    for s, sub in raw_pieces:
        sub = _clean_segment(sub, clean)
        if sub is None:
            continue
        if len(sub["t_s"]) > 1:
            steps.append(np.diff(sub["t_s"]))
        prepared.append((s, sub))
    if not steps:
        raise InputError(f"{path}: fewer than 2 valid rows")
    ts = float(np.median(np.concatenate(steps)))
    if not (ts > 0 and math.isfinite(ts)):
        raise InputError(f"{path}: cannot determine the sample period (median step {ts})")
    if fs_hz and "t_s" in cols and abs(1.0 / fs_hz - ts) > 0.02 * ts:
        note = (f"--fs {fs_hz:g} Hz disagrees with the time column (median step "
                f"{ts * 1e3:.4g} ms); the time column is used")
    else:
        note = None
    pieces = []
    for s, sub in prepared:
        pieces.extend(_split_and_resample(s, sub, ts, clean))
    if not pieces:
        raise InputError(f"{path}: no contiguous stretch of at least {MIN_PIECE} samples")
    data = Data(pieces, ts, has_motor, has_output, "torque_true_nm" in cols, source, clean)
    if note:
        data.notes.append(note)
    data.notes.extend(_describe(clean, ts))
    return data


def _clean_segment(sub: dict, clean: dict) -> dict | None:
    angle_keys = [k for k in ("motor_angle_rad", "output_angle_rad") if k in sub]
    ok = np.isfinite(sub["t_s"]) & np.isfinite(sub["torque_nm"])
    for k in angle_keys:
        ok &= np.isfinite(sub[k])
    clean["non_finite"] += int((~ok).sum())
    sub = {k: v[ok] for k, v in sub.items()}
    if len(sub["t_s"]) < 2:
        return None
    t = sub["t_s"]
    if np.any(np.diff(t) < 0):
        clean["out_of_order"] += int((np.diff(t) < 0).sum())
        order = np.argsort(t, kind="stable")
        sub = {k: v[order] for k, v in sub.items()}
    keep = np.ones(len(sub["t_s"]), bool)
    keep[1:] = np.diff(sub["t_s"]) > 0
    clean["duplicate_time"] += int((~keep).sum())
    sub = {k: v[keep] for k, v in sub.items()}
    same = sub["torque_nm"][1:] == sub["torque_nm"][:-1]
    for k in angle_keys:
        same &= sub[k][1:] == sub[k][:-1]
    # A standing joint legitimately repeats its angle; only a repeated torque
    # to the last bit together with it marks a stale (re-sent) row.
    keep = np.ones(len(sub["t_s"]), bool)
    keep[1:] = ~same
    clean["stale"] += int((~keep).sum())
    sub = {k: v[keep] for k, v in sub.items()}
    for k in angle_keys:
        sub[k] = np.unwrap(sub[k])
    return sub


def _split_and_resample(s: str, sub: dict, ts: float, clean: dict) -> list[Piece]:
    t = sub["t_s"]
    dt = np.diff(t)
    cut = np.flatnonzero(dt > GAP_FACTOR * ts) + 1
    clean["gaps"] += len(cut)
    clean["gap_time_s"] += float(dt[cut - 1].sum()) if len(cut) else 0.0
    out = []
    for a, b in zip(np.r_[0, cut], np.r_[cut, len(t)]):
        if b - a < MIN_PIECE:
            clean["dropped_short_pieces"] += 1
            continue
        part = {k: v[a:b] for k, v in sub.items()}
        tp = part["t_s"]
        d = np.diff(tp)
        if np.max(np.abs(d - ts)) > JITTER_TOL * ts:
            grid = tp[0] + ts * np.arange(int(np.floor((tp[-1] - tp[0]) / ts)) + 1)
            part = {k: np.interp(grid, tp, v) for k, v in part.items() if k != "t_s"} | {
                "t_s": grid}
            clean["resampled_pieces"] += 1
        out.append(Piece(s, part["t_s"], part["torque_nm"], part.get("motor_angle_rad"),
                         part.get("output_angle_rad"), part.get("torque_true_nm"),
                         part.get("output_velocity_rad_s")))
    return out


def _describe(c: dict, ts: float) -> list[str]:
    notes = [f"sample period {ts * 1e3:.4g} ms ({1 / ts:.5g} Hz, median time step)"]
    if c["non_finite"]:
        notes.append(f"dropped {c['non_finite']} rows with missing/non-finite values")
    if c["out_of_order"]:
        notes.append(f"sorted {c['out_of_order']} out-of-order time steps")
    if c["duplicate_time"]:
        notes.append(f"dropped {c['duplicate_time']} rows with a repeated time stamp")
    if c["stale"]:
        notes.append(f"dropped {c['stale']} stale rows (torque and angle repeated exactly)")
    if c["gaps"]:
        notes.append(f"split at {c['gaps']} gaps (> {GAP_FACTOR} samples, "
                     f"{c['gap_time_s']:.3g} s in total); the filter restarts after each")
    if c["resampled_pieces"]:
        notes.append(f"resampled {c['resampled_pieces']} irregularly sampled stretches "
                     "onto a uniform grid (linear interpolation)")
    if c["dropped_short_pieces"]:
        notes.append(f"dropped {c['dropped_short_pieces']} stretches shorter than "
                     f"{MIN_PIECE} samples")
    return notes
