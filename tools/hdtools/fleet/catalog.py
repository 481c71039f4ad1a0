"""Which files are logs, whose joint they are, when they start, and the key
that says whether a stored record is up to date (docs/fleet.md, "Logs").

Identity, first that applies:
  1. a sidecar LOG.json next to the log: {"joint": "...", "start_utc":
     "2026-01-05T08:00:00Z"};
  2. the path: .../<joint>/<YYYY-MM-DDTHH-MM-SS>[Z].<ext> (the directory is
     the joint, the file name the UTC start).
A log with neither is refused (reported, the rest goes on)."""
from __future__ import annotations

import glob
import hashlib
import json
import os
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from ..safeio import UsageError, read_bytes
from . import record

LOG_SUFFIXES = (".csv", ".log")           # CSV and candump -l (loading.py decides)
EPOCH = datetime(2026, 1, 1, tzinfo=timezone.utc)   # start_day counts days from here
NAME_FORMATS = ("%Y-%m-%dT%H-%M-%S", "%Y-%m-%dT%H-%M-%SZ", "%Y%m%dT%H%M%SZ", "%Y%m%dT%H%M%S")
HASH_CHUNK = 1 << 20


@dataclass
class LogRef:
    path: str               # as found
    rel: str                # relative to the input it was found under (the record's path)
    joint: str | None = None
    start_utc: str | None = None
    start_day: float | None = None
    problem: str | None = None   # identity could not be told: why


def _start_of(text):
    for fmt in NAME_FORMATS + ("%Y-%m-%dT%H:%M:%SZ", "%Y-%m-%dT%H:%M:%S%z"):
        try:
            t = datetime.strptime(text, fmt)
        except ValueError:
            continue
        return t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t.astimezone(timezone.utc)
    return None


def _identify(ref: LogRef) -> LogRef:
    side = Path(ref.path + ".json")
    joint, start = None, None
    if side.is_file():
        try:
            meta = json.loads(read_bytes(side, 1 << 16).decode("utf-8"))
            joint, start = str(meta["joint"]), _start_of(str(meta["start_utc"]))
        except (UsageError, ValueError, KeyError, TypeError, UnicodeDecodeError) as exc:
            ref.problem = f"sidecar {side.name}: not {{\"joint\", \"start_utc\"}} JSON ({exc})"
            return ref
    else:
        p = Path(ref.path)
        joint, start = p.parent.name or None, _start_of(p.stem)
    if not joint or start is None:
        ref.problem = ("joint and start time not known: name it <joint>/<YYYY-MM-DDTHH-MM-SS>"
                       f"{Path(ref.path).suffix} or give a sidecar {Path(ref.path).name}.json")
        return ref
    ref.joint = joint
    ref.start_utc = start.strftime("%Y-%m-%dT%H:%M:%SZ")
    ref.start_day = (start - EPOCH).total_seconds() / 86400.0
    return ref


def discover(inputs) -> list[LogRef]:
    """Every log under the inputs (directories walked, globs expanded), in
    sorted order, with its identity.  UsageError when an input names
    nothing or nothing in it is a log."""
    refs, seen = [], set()
    for inp in inputs:
        if os.path.isdir(inp):
            found = []
            for dirpath, dirnames, files in os.walk(inp):
                dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
                found += [os.path.join(dirpath, f) for f in files
                          if f.endswith(LOG_SUFFIXES) and not f.startswith(".")]
            base = inp
        else:
            found = [f for f in glob.glob(inp, recursive=True) if os.path.isfile(f)
                     and f.endswith(LOG_SUFFIXES)]
            if not found and not glob.has_magic(inp):
                if os.path.exists(inp):
                    raise UsageError(f"{inp}: not a log (.csv or candump .log) or a directory")
                raise UsageError(f"{inp}: no such file or directory")
            base = os.path.dirname(inp.split("*")[0]) or "."
        for f in sorted(found):
            key = os.path.realpath(f)
            if key not in seen:
                seen.add(key)
                ref = LogRef(f, os.path.relpath(f, base))
                if not os.path.isfile(f):     # a FIFO would block the hash
                    ref.problem = "not a regular file (FIFO, device or socket)"
                    refs.append(ref)
                else:
                    refs.append(_identify(ref))
    if not refs:
        raise UsageError(f"no logs (*.csv, *.log) in {', '.join(inputs)}")
    return refs


def content_key(ref: LogRef, options: dict) -> str:
    """sha256 of the record version, the options, the log's bytes and its
    sidecar's: a record stored under this key is up to date.  An unreadable
    log hashes its error (it is refused again, not retried forever); a
    file that is not regular is never opened."""
    h = hashlib.sha256(json.dumps([record.RECORD_VERSION, options, ref.rel, ref.problem],
                                  sort_keys=True).encode())
    for p in (ref.path, ref.path + ".json"):
        if not os.path.isfile(p):
            h.update(b"\0absent")
            continue
        try:
            with open(p, "rb") as fh:
                while chunk := fh.read(HASH_CHUNK):
                    h.update(chunk)
        except OSError as exc:
            h.update(f"\0error {exc.errno}".encode())
    return h.hexdigest()[:32]
