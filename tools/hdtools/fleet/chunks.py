"""Long logs in chunks, one task each, so that a worker's memory is one
chunk's, not one log's (a 10 h log does not load whole).

A bag (MCAP, rosbag2) is cut in windows of log time of equal length, as
many as its bytes need (`parts`); a task reads its window's messages only
(rosio.bagin.read(window_ns)), and the chunk's start is the window's.

The client cuts the log's data rows into byte ranges of at most
`chunk_bytes`, each ending at a line end (`ranges`: it reads one line per
cut, never the log).  A task writes the header and its range to a
temporary file on the worker and loads that with the ordinary loader
(`extracted`); the chunk's start is the time of its first row after the
loader's unit detection, relative to the log's first row, so a chunk's
record sits at its own place on the joint's timeline."""
from __future__ import annotations

import math
import os
import tempfile
from contextlib import contextmanager

CHUNK_BYTES = 64 << 20      # ~1.5 h of a 5-column 200 Hz CSV; a chunk loads in < 1 GB


def parts(ref, chunk_bytes=CHUNK_BYTES):
    """The tasks of one log (catalog.LogRef): [part] with the keyword
    arguments of record.analyze_log for each (byte_range of a text log,
    window_ns of a bag, the bag's joint), or None for one plain task."""
    if ref.bag is not None:
        n = max(1, -(-ref.bag["bytes"] // chunk_bytes))
        t0, t1 = ref.bag["start_ns"], ref.bag["end_ns"] + 1
        cuts = [t0 + (t1 - t0) * i // n for i in range(n + 1)]
        out = [{"window_ns": (a, b), "origin_ns": t0} if n > 1 else {}
               for a, b in zip(cuts, cuts[1:])]
        if ref.bag_joint:
            for o in out:
                o["joint"] = ref.bag_joint
        return out if (n > 1 or ref.bag_joint) else None
    try:
        rng = ranges(ref.path, chunk_bytes)
    except OSError:
        return None          # the task refuses the log with the loader's message
    return None if rng is None else [{"byte_range": r} for r in rng]


def ranges(path, chunk_bytes=CHUNK_BYTES):
    """[(start, end)] byte ranges of the data rows, or None when the log is
    one task (small enough).  A CSV's rows start after its header; a
    candump log's after its preamble (the lines before its first TELEM_A:
    the BOOT and parameter answers a recording starts with), and every cut
    is moved to a TELEM_A line, so that a sample's frames stay together."""
    size = os.path.getsize(path)
    if size <= chunk_bytes:
        return None
    with open(path, "rb") as fh:
        candump = fh.read(1) == b"("
        fh.seek(0)
        start = _preamble_end(fh) if candump else len(fh.readline())
        out = []
        while start < size:
            end = min(start + chunk_bytes, size)
            if end < size:
                fh.seek(end)
                fh.readline()
                end = _next_sample(fh) if candump else fh.tell()
            out.append((start, end))
            start = end
    return out


# A TELEM_A frame of any node: identifier 0x01D002nn (hdtools.canproto).
_TELEM_A_PREFIX = b"1D002"
MAX_SCAN_LINES = 4096       # a cut looks this far for a TELEM_A, then cuts anyway


def _is_telem_a(line: bytes) -> bool:
    parts = line.split()
    return len(parts) >= 3 and parts[2].split(b"#")[0].upper().lstrip(b"0").startswith(
        _TELEM_A_PREFIX) and len(parts[2].split(b"#")[0]) == 8


def _next_sample(fh) -> int:
    """The offset of the next TELEM_A line from here (or of the line
    MAX_SCAN_LINES on, or the end)."""
    for _ in range(MAX_SCAN_LINES):
        pos = fh.tell()
        line = fh.readline()
        if not line or _is_telem_a(line):
            return pos
    return fh.tell()


def _preamble_end(fh) -> int:
    fh.seek(0)
    return _next_sample(fh)


def _first_time(header: bytes, line: bytes):
    """The raw t_s of a data row (None if it has none or it does not parse)."""
    names = [h.strip().strip('"') for h in header.decode("utf-8-sig", "replace").split(",")]
    if "t_s" not in names:
        return None
    fields = line.decode("utf-8", "replace").split(",")
    try:
        return float(fields[names.index("t_s")].strip().strip('"'))
    except (IndexError, ValueError):
        return None


def _host_time(line: bytes):
    """The candump time stamp "(1700000000.000123)" of a line, or None."""
    try:
        return float(line.split()[0].strip(b"()"))
    except (IndexError, ValueError):
        return None


@contextmanager
def extracted(path, byte_range, buf_bytes=1 << 20):
    """(temporary log of the header or preamble and the range, where the
    chunk starts): {"first_t": the log's first raw t_s} for a CSV (the
    record places the chunk after the loader's unit detection), {"offset_s":
    host seconds from the log's first sample} for a candump log.  The file
    is removed after."""
    start, end = byte_range
    fd, tmp = tempfile.mkstemp(prefix="hdfleet-chunk-", suffix=".log")
    try:
        with open(path, "rb") as src, os.fdopen(fd, "wb") as dst:
            candump = src.read(1) == b"("
            src.seek(0)
            if candump:
                head_end = _preamble_end(src)
                src.seek(0)
                dst.write(src.read(head_end))
                first, src_first = _host_time(src.readline()), None
                src.seek(start)
                src_first = _host_time(src.readline())
                where = {"offset_s": (src_first - first) if None not in (first, src_first)
                         else math.nan}
            else:
                header = src.readline()
                where = {"first_t": _first_time(header, src.readline())}
                dst.write(header)
            src.seek(start)
            left = end - start
            while left > 0:
                block = src.read(min(buf_bytes, left))
                if not block:
                    break
                dst.write(block)
                left -= len(block)
        yield tmp, where
    finally:
        try:
            os.unlink(tmp)
        except OSError:
            pass
