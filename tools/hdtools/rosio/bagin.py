"""A bag as `hdsense analyze` input: the log contract of docs/how-to/ros2.md
("Reading bags"), turned into the columns the CSV reader gives
(hdtools.analysis.loading), so the same unit, gap and reset rules apply.
EXTRA_COLUMNS and RAW_TORQUE_CHANNEL below are that table's channels; the
rest comes from JointState (stamp, position, velocity, effort)."""
from __future__ import annotations

import os
from array import array
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..safeio import UsageError
from . import topics

# a bag whose stamps step back this often is not in time order (a reset
# now and then is a new segment, as in a CSV)
MAX_BACK_STEP_FRACTION = 0.01
SHOW_NAMES = 8
_CHANNEL = topics.signal_channels()
# analysis column -> channel; the motor current has no frame yet: its
# channel is named by the same rule (a current in A)
EXTRA_COLUMNS = {"motor_angle_rad": topics.MOTOR_ANGLE,
                 "torque_feedforward_nm": _CHANNEL["FfTorque"],
                 "motor_current_a": "motor_current" + topics.UNIT_SUFFIX["A"]}
RAW_TORQUE_CHANNEL = _CHANNEL["TorqueRaw"]
CHANNELS = (RAW_TORQUE_CHANNEL,) + tuple(EXTRA_COLUMNS.values())


class BagError(UsageError):
    """Bad bag input (exit status 2)."""


def is_bag(path) -> bool:
    p = Path(path)
    return (p.suffix in (".mcap", ".db3") and not p.is_dir()) or (
        p.is_dir() and (p / "metadata.yaml").is_file())


def _names(items) -> str:
    items = sorted(items)
    more = f", ... ({len(items) - SHOW_NAMES} more)" if len(items) > SHOW_NAMES else ""
    return ", ".join(items[:SHOW_NAMES]) + more


def _open(path: Path):
    from rosbags.highlevel import AnyReader
    if not os.path.exists(path):
        raise BagError(f"{path}: no such file or folder")
    if path.is_file() and not os.access(path, os.R_OK):
        raise BagError(f"{path}: cannot read (permission denied)")
    reader = AnyReader([path])
    try:
        reader.open()
    except Exception as exc:  # noqa: BLE001 - rosbags raises many kinds for a bad file
        raise BagError(f"{path}: not a readable bag: {_why(exc)}") from None
    return reader


def _why(exc: Exception) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text.replace("; please report issue.", "").replace(" please report issue.", "")[:200]


@contextmanager
def _opened(path: Path, what: str):
    """An open reader; any failure of the storage or the CDR decoder while
    it is used becomes one BagError line."""
    reader = _open(path)
    try:
        yield reader
    except BagError:
        raise
    except Exception as exc:  # noqa: BLE001 - a truncated chunk, a bad CDR payload
        raise BagError(f"{path}: cannot read the bag's {what}: {_why(exc)}") from None
    finally:
        try:
            reader.close()
        except Exception:  # noqa: BLE001 - nothing left to save
            pass


def read(path, joint: str | None, window_ns=None) -> tuple[dict, list[str]]:
    """(columns, notes) for the joint (None: the bag's only joint).
    window_ns: (start, stop), the messages whose log time is in
    [start, stop) only (a chunk of a long bag, hdtools.fleet.chunks)."""
    path = Path(path)
    with _opened(path, "messages") as reader:
        return _read(reader, path, joint, window_ns)


def _joint_connections(reader, path):
    js = [c for c in reader.connections if c.msgtype == topics.JOINT_STATE_TYPE]
    if js:
        return js
    found = {f"{c.topic} ({c.msgtype})" for c in reader.connections}
    raise BagError(f"{path}: no {topics.JOINT_STATE_TYPE} topic" +
                   (f" (topics: {_names(found)})" if found else " (the bag has no topics)"))


def _contract_topics(reader) -> tuple[dict, dict]:
    """({topic: (joint, channel)} of every contract channel of type Float64,
    {(joint, channel): msgtype} of those of another type)."""
    ns = topics.NAMESPACE.strip("/")
    good, bad = {}, {}
    for c in reader.connections:
        parts = c.topic.split("/")
        if len(parts) == 4 and parts[1] == ns and parts[3] in CHANNELS:
            if c.msgtype == topics.FLOAT_TYPE:
                good[c.topic] = (parts[2], parts[3])
            else:
                bad[(parts[2], parts[3])] = c.msgtype
    return good, bad


def index(path) -> dict:
    """What a fleet needs to know of a bag without reading its messages
    (hdtools.fleet.catalog): its joints (those of its contract channels,
    and those the first JointState message names), the log times of its
    first and last message [ns], and its size in bytes."""
    path = Path(path)
    with _opened(path, "index") as reader:
        joints = {j for j, _ in _contract_topics(reader)[0].values()}
        for conn, _stamp, raw in reader.messages(_joint_connections(reader, path)):
            joints.update(reader.deserialize(raw, conn.msgtype).name)
            break
        files = [path] if path.is_file() else [f for f in path.iterdir() if f.is_file()]
        return {"joints": sorted(joints), "start_ns": int(reader.start_time),
                "end_ns": int(reader.end_time), "bytes": sum(f.stat().st_size for f in files)}


def _read(reader, path: Path, joint: str | None, window_ns=None):
    """One pass over the bag (the storage parses every record of a chunk
    once per pass): JointState for the joint, every contract channel."""
    js_conns = _joint_connections(reader, path)
    good, bad = _contract_topics(reader)
    extra = [c for c in reader.connections if c.topic in good]
    stamps, cols = array("q"), {k: array("d") for k in ("position", "velocity", "effort")}
    series = {key: (array("q"), array("d")) for key in good.values()}
    present: set[str] = set()
    index_of: dict[tuple, int | None] = {}
    want = joint
    start, stop = window_ns or (None, None)
    for conn, stamp, raw in reader.messages(js_conns + extra, start=start, stop=stop):
        if conn.topic in good:
            t, v = series[good[conn.topic]]
            t.append(stamp)
            v.append(reader.deserialize(raw, conn.msgtype).data)
            continue
        m = reader.deserialize(raw, conn.msgtype)
        names = tuple(m.name)
        present.update(names)
        if want is None:
            if len(present) > 1:
                raise BagError(f"{path}: several joints ({_names(present)}): choose one with "
                               "--joint NAME")
            want = names[0] if names else None
        if names not in index_of:
            index_of[names] = names.index(want) if want in names else None
        i = index_of[names]
        if i is None:
            continue
        stamps.append(m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec)
        for k, arr in cols.items():
            v = getattr(m, k)
            arr.append(float(v[i]) if len(v) > i else np.nan)
    if want is None or not stamps:
        if joint is not None:
            raise BagError(f"{path}: no joint {joint!r} in {topics.JOINT_STATE_TYPE}" +
                           (f" (joints: {_names(present)})" if present else
                            " (no JointState message names a joint)"))
        raise BagError(f"{path}: no JointState message names a joint")
    for (j, channel), msgtype in bad.items():
        if j == want:
            raise BagError(f"{path}: {topics.channel_topic(j, channel)} is {msgtype}, expected "
                           f"{topics.FLOAT_TYPE}")
    mine = {channel: (np.frombuffer(t, np.int64), np.frombuffer(v, float))
            for (j, channel), (t, v) in series.items() if j == want}
    return _columns(path, want, np.frombuffer(stamps, np.int64),
                    {k: np.frombuffer(v, float) for k, v in cols.items()}, mine)


def _check_order(t_ns: np.ndarray, path) -> None:
    back = int(np.sum(np.diff(t_ns) < 0))
    if back > max(1, MAX_BACK_STEP_FRACTION * len(t_ns)):
        raise BagError(f"{path}: the JointState stamps step back {back} times in {len(t_ns)} "
                       "messages: not a recording in time order")


def _align(t_ns: np.ndarray, series) -> np.ndarray:
    """A channel's values at the JointState stamps: exact where the stamps
    are the same, linear in between, NaN outside its span."""
    ct, cv = series
    order = np.argsort(ct, kind="stable")
    ct, cv = ct[order], cv[order]
    if len(ct) == 0:
        return np.full(len(t_ns), np.nan)
    x0 = ct[0]
    out = np.interp((t_ns - x0).astype(float), (ct - x0).astype(float), cv)
    out[(t_ns < ct[0]) | (t_ns > ct[-1])] = np.nan
    return out


def _columns(path, joint, t_ns, js, series):
    _check_order(t_ns, path)
    notes = [f"bag: {topics.JOINT_STATE_TYPE} of joint {joint!r}, {len(t_ns)} messages"]
    cols = {"t_s": (t_ns - t_ns[0]) * 1e-9}
    raw = series.get(RAW_TORQUE_CHANNEL)
    if raw is not None:
        cols["torque_nm"] = _align(t_ns, raw)
        notes.append(f"torque_nm from {topics.channel_topic(joint, RAW_TORQUE_CHANNEL)} "
                     "(JointState.effort is the filtered torque there)")
    elif np.isfinite(js["effort"]).any():
        cols["torque_nm"] = js["effort"]
        notes.append("torque_nm from JointState.effort")
    else:
        raise BagError(f"{path}: joint {joint!r} has no effort in its JointState messages and "
                       f"no {topics.channel_topic(joint, RAW_TORQUE_CHANNEL)}")
    if np.isfinite(js["position"]).any():
        cols["output_angle_rad"] = js["position"]
    if np.isfinite(js["velocity"]).any() and "output_angle_rad" in cols:
        cols["output_velocity_rad_s"] = js["velocity"]
    for column, channel in EXTRA_COLUMNS.items():
        if channel in series:
            cols[column] = _align(t_ns, series[channel])
            notes.append(f"{column} from {topics.channel_topic(joint, channel)}")
    if "motor_angle_rad" not in cols and "output_angle_rad" not in cols:
        raise BagError(f"{path}: joint {joint!r} has neither JointState.position nor "
                       f"{topics.channel_topic(joint, topics.MOTOR_ANGLE)}: an angle is needed")
    return cols, notes
