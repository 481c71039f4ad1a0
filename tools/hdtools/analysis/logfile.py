"""Reading a torque log file for hdtools.analysis.loading: the path checks,
the CSV reader (fast numpy path, then a counting row-by-row reader for
messy files) and the hand-off of candump -l logs to analysis/candump.py.
Column names and what a row needs are the log contract of docs/design/analyze.md
("Input")."""
from __future__ import annotations

import csv
import math
import os
import stat
import warnings
from pathlib import Path

import numpy as np

from .errors import InputError

TORQUE = "torque_nm"
ANGLES = ("motor_angle_rad", "output_angle_rad")
# Recognised columns; others are ignored.  A row missing one of REQUIRED_IF_
# PRESENT (when the column exists) is dropped; the others may be missing.
KNOWN = ("t_s", TORQUE) + ANGLES + (
    "output_velocity_rad_s", "segment", "torque_true_nm", "torque_feedforward_nm",
    "motor_current_a")
REQUIRED_IF_PRESENT = ("t_s", TORQUE) + ANGLES + ("torque_true_nm", "torque_feedforward_nm")


def check_path(path) -> Path:
    """The input must be a readable regular file: anything else is refused
    here, in one line, before any reading (a FIFO would block or be
    consumed, a directory is a user slip)."""
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise InputError(f"{p}: no such file") from None
    except OSError as exc:
        raise InputError(f"{p}: cannot access ({exc.strerror})") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{p}: is a directory, expected a CSV or candump -l log file, or a "
                         "rosbag2 folder (with metadata.yaml)")
    if not stat.S_ISREG(st.st_mode):
        kind = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode)
                else "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode)
                else "not a regular file")
        raise InputError(f"{p}: is {kind}, expected a regular CSV or candump -l log file")
    try:
        with open(p, "rb") as fh:
            fh.read(1)
    except OSError as exc:
        raise InputError(f"{p}: cannot read ({exc.strerror})") from None
    return p


def _header(path: Path) -> list[str]:
    with open(path, newline="", encoding="utf-8-sig") as fh:
        header = next(csv.reader(fh), None)
    if not header or not any(h.strip() for h in header):
        raise InputError(f"{path}: empty file, expected a CSV header line")
    header = [h.strip() for h in header]
    if len(header) == 1 and (";" in header[0] or "\t" in header[0]):
        raise InputError(f"{path}: the header has one field ({header[0][:60]!r}): "
                         "expected comma-separated columns")
    if TORQUE not in header:
        raise InputError(f"{path}: no 'torque_nm' column (columns: {', '.join(header)}); "
                         "the measured torque is required")
    if not any(a in header for a in ANGLES):
        raise InputError(f"{path}: needs 'motor_angle_rad' or 'output_angle_rad' "
                         f"(columns: {', '.join(header)})")
    dup = sorted({h for h in header if h in KNOWN and header.count(h) > 1})
    if dup:
        raise InputError(f"{path}: column(s) {', '.join(dup)} appear more than once")
    return header


def _fast(path, idx):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return np.loadtxt(path, delimiter=",", skiprows=1, usecols=idx, dtype=np.float64,
                          ndmin=2, quotechar='"', encoding="utf-8-sig")


def _slow(path, header, names, stats):
    """Row by row (csv module): counts short rows and empty or unparsable
    fields; such values become NaN."""
    idx = [header.index(h) for h in names]
    seg_j = header.index("segment") if "segment" in header else None
    rows, seg = [], []
    with open(path, newline="", encoding="utf-8-sig") as fh:
        rd = csv.reader(fh)
        next(rd, None)
        for r in rd:
            if not r or (len(r) == 1 and not r[0].strip()):
                stats["blank_rows"] += 1
                continue
            if len(r) < len(header):
                stats["short_rows"] += 1
            vals = []
            for j in idx:
                s = r[j].strip() if j < len(r) else ""
                if not s:
                    stats["empty_fields"] += 1
                    vals.append(math.nan)
                    continue
                try:
                    vals.append(float(s))
                except ValueError:
                    stats["unparsable_fields"] += 1
                    vals.append(math.nan)
            rows.append(vals)
            if seg_j is not None:
                seg.append(r[seg_j].strip() if seg_j < len(r) else "")
    arr = np.array(rows, float).reshape(-1, len(idx))
    return arr, (np.array(seg) if seg_j is not None else None)


def _read_csv(path: Path, stats: dict) -> dict:
    header = _header(path)
    names = [h for h in header if h in KNOWN and h != "segment"]
    stats["columns_ignored"] = [h for h in header if h not in KNOWN]
    seg = None
    try:
        arr = _fast(path, [header.index(h) for h in names])
        if "segment" in header:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                seg = np.loadtxt(path, delimiter=",", skiprows=1, usecols=[header.index("segment")],
                                 dtype=str, ndmin=1, quotechar='"', encoding="utf-8-sig")
                seg = np.char.strip(seg)
            if len(seg) != len(arr):
                raise ValueError("segment column length")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not a UTF-8 text CSV (byte {exc.start}: {exc.reason})") from None
    except ValueError:
        # Short rows, empty or non-numeric fields: the slow reader counts them.
        try:
            arr, seg = _slow(path, header, names, stats)
        except UnicodeDecodeError as exc:
            raise InputError(f"{path}: not a UTF-8 text CSV (byte {exc.start}: "
                             f"{exc.reason})") from None
        except csv.Error as exc:
            raise InputError(f"{path}: malformed CSV ({exc})") from None
    if arr.size == 0:
        raise InputError(f"{path}: no data rows")
    cols = {h: arr[:, j] for j, h in enumerate(names)}
    if seg is not None:
        cols["segment"] = seg
    return cols


def read_file(path: Path, stats: dict) -> tuple[dict, str]:
    """(columns, "candump" | "csv") of a text log."""
    with open(path, "rb") as fh:
        head = fh.read(64)
    try:
        if head.lstrip().startswith(b"("):
            return _read_candump(path), "candump"
        return _read_csv(path, stats), "csv"
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (byte {exc.start}): expected a CSV or "
                         "candump -l log") from None


def _read_candump(path: Path) -> dict:
    from . import candump     # python-can and cantools only for candump logs
    return candump.read(path)
