"""Which files are logs, whose joint they are, when they start, and the key
that says whether a stored record is up to date (docs/results/fleet.md, "Logs").

Identity, first that applies:
  1. a sidecar LOG.json next to the log: {"joint": "...", "start_utc":
     "2026-01-05T08:00:00Z"};
  2. the path: .../<joint>/<YYYY-MM-DDTHH-MM-SS>[Z].<ext> (the directory is
     the joint, the file name the UTC start);
  3. a bag (.mcap, .db3, or a rosbag2 folder with metadata.yaml) names its
     own joints (JointState names, /hdjoint/<joint>/... channels) and its
     start (the first message's log time).  A bag of one joint is one log;
     a bag of several is one log per joint, each named <prefix>.<name>
     when 1 or 2 gives a prefix, else <name>.
A log with none of these is refused (reported, the rest goes on)."""
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
BAG_SUFFIXES = (".mcap", ".db3")          # a bare bag file (rosio.bagin)
BAG_FOLDER_FILE = "metadata.yaml"         # a rosbag2 folder: one log, never walked into
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
    bag_joint: str | None = None     # the joint a bag's task reads (None: the log's only one)
    bag: dict | None = None          # rosio.bagin.index of a bag


def _start_of(text):
    for fmt in NAME_FORMATS + ("%Y-%m-%dT%H:%M:%SZ", "%Y-%m-%dT%H:%M:%S%z"):
        try:
            t = datetime.strptime(text, fmt)
        except ValueError:
            continue
        return t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t.astimezone(timezone.utc)
    return None


def _given(ref: LogRef):
    """(joint, start, problem) from the sidecar, else from the path."""
    side = Path(ref.path + ".json")
    if side.is_file():
        try:
            meta = json.loads(read_bytes(side, 1 << 16).decode("utf-8"))
            return str(meta["joint"]), _start_of(str(meta["start_utc"])), None
        except (UsageError, ValueError, KeyError, TypeError, UnicodeDecodeError) as exc:
            return None, None, f"sidecar {side.name}: not {{\"joint\", \"start_utc\"}} JSON ({exc})"
    p = Path(ref.path)
    start = _start_of(p.stem)
    return (p.parent.name or None) if start is not None else None, start, None


def _identify(ref: LogRef) -> list[LogRef]:
    joint, start, ref.problem = _given(ref)
    if ref.problem:
        return [ref]
    refs = [ref]
    if is_bag(ref.path):
        refs = _bag_refs(ref, joint)
        if len(refs) > 1 or ref.problem:
            joint = None
        if start is None and ref.bag:
            start = datetime.fromtimestamp(ref.bag["start_ns"] // 10**9, timezone.utc)
    for r in refs:
        j = joint or r.joint
        if r.problem is None and (not j or start is None):
            r.problem = ("joint and start time not known: name it <joint>/<YYYY-MM-DDTHH-MM-SS>"
                         f"{Path(r.path).suffix} or give a sidecar {Path(r.path).name}.json")
        if r.problem is None:
            r.joint = j
            r.start_utc = start.strftime("%Y-%m-%dT%H:%M:%SZ")
            r.start_day = (start - EPOCH).total_seconds() / 86400.0
    return refs


def is_bag(path) -> bool:
    p = Path(path)
    return (p.is_file() and p.suffix in BAG_SUFFIXES) or (p.is_dir() and (p / BAG_FOLDER_FILE).is_file())


def _bag_refs(ref: LogRef, prefix) -> list[LogRef]:
    """The bag's joints: one ref each (the bag's only joint: ref itself)."""
    from ..rosio import bagin
    try:
        ref.bag = bagin.index(ref.path)
    except UsageError as exc:
        ref.problem = str(exc).replace(f"{ref.path}: ", "", 1).replace(ref.path, ref.rel)
        return [ref]
    names = ref.bag["joints"]
    if len(names) <= 1:
        ref.joint = names[0] if names else None
        return [ref]
    return [LogRef(ref.path, ref.rel, joint=f"{prefix}.{n}" if prefix else n, bag_joint=n,
                   bag=ref.bag) for n in names]


def discover(inputs) -> list[LogRef]:
    """Every log under the inputs (directories walked, globs expanded), in
    sorted order, with its identity.  UsageError when an input names
    nothing or nothing in it is a log."""
    refs, seen = [], set()
    for inp in inputs:
        if os.path.isdir(inp):
            found = []
            if is_bag(inp):
                found, base = [inp], os.path.dirname(os.path.normpath(inp)) or "."
            else:
                for dirpath, dirnames, files in os.walk(inp):
                    bags = sorted(d for d in dirnames if not d.startswith(".")
                                  and is_bag(os.path.join(dirpath, d)))
                    dirnames[:] = sorted(d for d in dirnames if not d.startswith(".")
                                         and d not in bags)
                    found += [os.path.join(dirpath, f) for f in files + bags
                              if f.endswith(LOG_SUFFIXES + BAG_SUFFIXES) or f in bags
                              if not f.startswith(".")]
                base = inp
        else:
            found = [f for f in glob.glob(inp, recursive=True) if is_bag(f) or (
                os.path.isfile(f) and f.endswith(LOG_SUFFIXES))]
            if not found and not glob.has_magic(inp):
                if os.path.exists(inp):
                    raise UsageError(f"{inp}: not a log (.csv, candump .log, .mcap, .db3 or a "
                                     "rosbag2 folder) or a directory")
                raise UsageError(f"{inp}: no such file or directory")
            base = os.path.dirname(inp.split("*")[0]) or "."
        for f in sorted(found):
            key = os.path.realpath(f)
            if key not in seen:
                seen.add(key)
                ref = LogRef(f, os.path.relpath(f, base))
                if not os.path.isfile(f) and not is_bag(f):     # a FIFO would block the hash
                    ref.problem = "not a regular file (FIFO, device or socket)"
                    refs.append(ref)
                else:
                    refs += _identify(ref)
    if not refs:
        raise UsageError(f"no logs (*.csv, *.log, *.mcap, *.db3, rosbag2 folders) in "
                         f"{', '.join(inputs)}")
    return refs


def content_key(ref: LogRef, options: dict) -> str:
    """sha256 of the record version, the options, the log's bytes and its
    sidecar's: a record stored under this key is up to date.  An unreadable
    log hashes its error (it is refused again, not retried forever); a
    file that is not regular is never opened."""
    h = hashlib.sha256(json.dumps([record.RECORD_VERSION, options, ref.rel, ref.problem]
                                  + ([ref.bag_joint] if ref.bag_joint else []),
                                  sort_keys=True).encode())
    inside = sorted(os.path.join(ref.path, f) for f in os.listdir(ref.path)) \
        if os.path.isdir(ref.path) else [ref.path]
    for p in inside + [ref.path + ".json"]:
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
