"""Calibration CSV reader (format in docs/how-to/calibration.md)."""
from __future__ import annotations

import csv
import io
import math

from .lib import CalibError, ExperimentData

REQUIRED = ["experiment", "direction", "position_deg", "torque_nm"]
FLOAT32_MAX = 3.4028234663852886e38   # the C library computes in float32
BRIDGE = ["bridge_v", "bridge_counts"]
DIRECTIONS = {"load": False, "unload": True}


def _fields(line: str, no: int) -> list[str]:
    try:
        return next(csv.reader(io.StringIO(line)), [])
    except csv.Error as exc:
        raise CalibError(f"line {no}: {exc}") from None


def _control_char(line: str) -> str | None:
    """The first control character of a line (tab allowed), else None."""
    return next((c for c in line if (ord(c) < 32 and c != "\t") or ord(c) == 127), None)


def _names(cols: list[str], most: int = 4, width: int = 24) -> str:
    """Column names for a message (printable: control characters are refused
    first), each cut at `width`, at most `most`."""
    shown = [c if len(c) <= width else c[:width] + "..." for c in cols[:most]]
    return ", ".join(shown) + (f" and {len(cols) - most} more" if len(cols) > most else "")


def read_csv(text: str, counts_per_volt: float | None = None) -> list[ExperimentData]:
    """Parses the CSV; '#' lines are comments.  Raises CalibError with the
    line number for anything it cannot use."""
    # split on newlines only (splitlines also breaks at \f, \x1c, U+2028 ...,
    # which would shift the line numbers in the messages)
    lines = [(i + 1, ln.rstrip("\r")) for i, ln in enumerate(text.split("\n"))
             if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise CalibError("empty input: no header line")
    for no, ln in lines:
        bad = _control_char(ln)
        if bad is not None:
            raise CalibError(f"line {no}: control character 0x{ord(bad):02X}")
    header_no, header = lines[0]
    cols = [c.strip().lower() for c in _fields(header, header_no)]
    unknown = [c for c in cols if c not in REQUIRED + BRIDGE]
    if unknown:
        raise CalibError(f"line {header_no}: unknown column(s) {_names(unknown)}; expected "
                         f"{', '.join(REQUIRED)} and one of {' or '.join(BRIDGE)}")
    missing = [c for c in REQUIRED if c not in cols]
    if missing:
        raise CalibError(f"line {header_no}: missing column(s) {', '.join(missing)}")
    if len(set(cols)) != len(cols):
        raise CalibError(f"line {header_no}: duplicate column names")
    bridge = [c for c in BRIDGE if c in cols]
    if len(bridge) != 1:
        raise CalibError(f"line {header_no}: need exactly one of bridge_v or bridge_counts")
    bcol = bridge[0]
    scale = 1.0
    if bcol == "bridge_counts":
        if not counts_per_volt or not (counts_per_volt > 0) or not math.isfinite(counts_per_volt):
            raise CalibError("bridge output in ADC counts: give --counts-per-volt (> 0)")
        scale = 1.0 / counts_per_volt
    idx = {c: i for i, c in enumerate(cols)}
    exps: dict[str, ExperimentData] = {}
    for no, ln in lines[1:]:
        row = [c.strip() for c in _fields(ln, no)]
        if len(row) != len(cols):
            raise CalibError(f"line {no}: {len(row)} fields, header has {len(cols)}")
        name = row[idx["experiment"]]
        if not name:
            raise CalibError(f"line {no}: empty experiment id")
        d = row[idx["direction"]].lower()
        if d not in DIRECTIONS:
            raise CalibError(f"line {no}: direction '{row[idx['direction']]}' is not load or unload")
        try:
            pos = float(row[idx["position_deg"]])
            t = float(row[idx["torque_nm"]])
            v = float(row[idx[bcol]]) * scale
        except ValueError as exc:
            raise CalibError(f"line {no}: not a number ({exc})") from None
        # NaN/Inf are passed on: the C library rejects them with its message,
        # but the line number is only known here.
        if not all(math.isfinite(x) for x in (pos, t, v)):
            raise CalibError(f"line {no}: non-finite value (NaN or Inf)")
        if any(abs(x) > FLOAT32_MAX for x in (pos, t, v)):
            raise CalibError(f"line {no}: value beyond the float32 range (3.4e38)")
        e = exps.get(name)
        if e is None:
            e = exps[name] = ExperimentData(name, pos, [], [], [])
        elif pos != e.position_deg:
            raise CalibError(f"line {no}: experiment {name} changes flexspline position "
                             f"({e.position_deg} -> {pos}); one position per experiment")
        e.torque_nm.append(t)
        e.bridge_v.append(v)
        e.unload.append(DIRECTIONS[d])
    if not exps:
        raise CalibError("no data rows after the header")
    return list(exps.values())
