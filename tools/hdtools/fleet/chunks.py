"""Long CSV logs in chunks, one task each, so that a worker's memory is one
chunk's, not one log's (a 10 h log does not load whole).

The client cuts the log's data rows into byte ranges of at most
`chunk_bytes`, each ending at a line end (`ranges`: it reads one line per
cut, never the log).  A task writes the header and its range to a
temporary file on the worker and loads that with the ordinary loader
(`extracted`); the chunk's start is the time of its first row after the
loader's unit detection, relative to the log's first row, so a chunk's
record sits at its own place on the joint's timeline."""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager

CHUNK_BYTES = 64 << 20      # ~1.5 h of a 5-column 200 Hz CSV; a chunk loads in < 1 GB


def ranges(path, chunk_bytes=CHUNK_BYTES):
    """[(start, end)] byte ranges of the data rows, or None when the log is
    one task (small enough, or not a CSV: a candump log is read whole)."""
    size = os.path.getsize(path)
    if size <= chunk_bytes:
        return None
    with open(path, "rb") as fh:
        if fh.read(1) == b"(":
            return None
        fh.seek(0)
        fh.readline()
        start, out = fh.tell(), []
        while start < size:
            end = min(start + chunk_bytes, size)
            if end < size:
                fh.seek(end)
                fh.readline()
                end = fh.tell()
            out.append((start, end))
            start = end
    return out


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


@contextmanager
def extracted(path, byte_range, buf_bytes=1 << 20):
    """(temporary CSV of the header and the range, the log's first raw t_s);
    the file is removed after."""
    start, end = byte_range
    fd, tmp = tempfile.mkstemp(prefix="hdfleet-chunk-", suffix=".csv")
    try:
        with open(path, "rb") as src, os.fdopen(fd, "wb") as dst:
            header = src.readline()
            first = _first_time(header, src.readline())
            dst.write(header)
            src.seek(start)
            left = end - start
            while left > 0:
                block = src.read(min(buf_bytes, left))
                if not block:
                    break
                dst.write(block)
                left -= len(block)
        yield tmp, first
    finally:
        try:
            os.unlink(tmp)
        except OSError:
            pass
