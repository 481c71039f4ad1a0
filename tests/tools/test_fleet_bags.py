"""hdsense fleet on MCAP and rosbag2 logs (docs/results/fleet.md, "Logs").

The reference is the CSV path: each bag is written (rosbags' writer, CDR)
from a simulated log's numbers, and a CSV holding exactly the numbers the
bag reader gives (stamps in ns -> s) is written beside it.  The fleet's
record of the bag must equal the CSV's, column for column: the bag's
reader (rosbags, CDR, the log contract of docs/how-to/ros2.md) against numpy's
CSV reader.  A bag of two joints gives two records, each its CSV's; a
bag cut into time windows keeps every message once."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hdtools.fleet import catalog, chunks, job, record, simfleet, trends  # noqa: E402
from hdtools.rosio import bagin, topics  # noqa: E402

OPTIONS = {"gear_ratio": 100.0, "loop": False}
T0_NS = 1_767_600_000 * 10**9          # 2026-01-05T08:00:00Z
JOINTS = ("shoulder", "wrist")


@pytest.fixture(scope="module")
def sim_logs(hdsim, tmp_path_factory):
    root = tmp_path_factory.mktemp("simfleet")
    simfleet.generate(root, hdsim, n_joints=2, days=1, logs_per_day=1, log_s=40.0, seed=9)
    return sorted(root.rglob("*.csv"))


def _columns(csv_path: Path) -> dict:
    from hdtools.analysis.results import read_csv
    header, arr = read_csv(csv_path)
    return {h: arr[:, i] for i, h in enumerate(header)}


def _write_bag(target: Path, storage, logs: dict[str, dict]):
    """One JointState topic naming every joint in each message (effort: the
    raw torque, as a team's tau_J), and the contract's Float64 channels of
    the motor angle and the feed-forward per joint."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from hdtools.rosio.messages import TYPESTORE
    T = TYPESTORE.types
    names = list(logs)
    first = logs[names[0]]
    t_ns = (T0_NS + np.round(first["t_s"] * 1e9)).astype(np.int64)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(target, version=9, storage_plugin=plugin) as w:
        js = w.add_connection(topics.JOINT_STATES, topics.JOINT_STATE_TYPE, typestore=TYPESTORE)
        ch = {(j, c): w.add_connection(topics.channel_topic(j, bagin.EXTRA_COLUMNS[c]),
                                       topics.FLOAT_TYPE, typestore=TYPESTORE)
              for j in names for c in ("motor_angle_rad", "torque_feedforward_nm")}
        for k, ns in enumerate(t_ns):
            sec, nsec = divmod(int(ns), 10**9)
            msg = T[topics.JOINT_STATE_TYPE](
                header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
                    sec=sec, nanosec=nsec), frame_id=""), name=names,
                position=np.array([logs[j]["output_angle_rad"][k] for j in names]),
                velocity=np.zeros(0), effort=np.array([logs[j]["torque_nm"][k] for j in names]))
            w.write(js, int(ns), TYPESTORE.serialize_cdr(msg, topics.JOINT_STATE_TYPE))
            for (j, c), conn in ch.items():
                w.write(conn, int(ns), TYPESTORE.serialize_cdr(
                    T[topics.FLOAT_TYPE](data=float(logs[j][c][k])), topics.FLOAT_TYPE))
    return t_ns


def _twin_csv(path: Path, t_ns, cols: dict):
    """The numbers the bag reader gives, as a CSV (repr: exact)."""
    t_s = (t_ns - t_ns[0]) * 1e-9
    keys = ("torque_nm", "output_angle_rad", "motor_angle_rad", "torque_feedforward_nm")
    rows = "\n".join(",".join(repr(float(v)) for v in vals)
                     for vals in zip(t_s, *(cols[k] for k in keys)))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("t_s," + ",".join(keys) + "\n" + rows + "\n")


@pytest.fixture(scope="module")
def bags(sim_logs, tmp_path_factory):
    """bags/: a bare .mcap of one joint (named by the path convention), a
    rosbag2 sqlite3 folder of two joints (named by the bag); twins/: CSVs."""
    root = tmp_path_factory.mktemp("bags")
    one = {"wrist": _columns(sim_logs[0])}
    two = {j: _columns(p) for j, p in zip(JOINTS, sim_logs)}
    (root / "bags" / "arm1").mkdir(parents=True)
    t_ns = _write_bag(root / "bags" / "arm1" / "2026-01-05T08-00-00.mcap", "mcap", one)
    _twin_csv(root / "twins" / "arm1" / "2026-01-05T08-00-00.csv", t_ns, one["wrist"])
    t_ns = _write_bag(root / "bags" / "arm2_bag", "sqlite3", two)
    for j in JOINTS:
        _twin_csv(root / "twins" / j / "2026-01-05T08-00-00.csv", t_ns, two[j])
    return root


def _records(store) -> dict:
    import pyarrow.parquet as pq
    rows = pq.read_table(Path(store) / "records.parquet").to_pylist()
    return {r["joint"]: r for r in rows}


VALUE_NAMES = [n for n, _ in record.VALUE_COLUMNS if n != "gear_source"]


def _same(a, b):
    if isinstance(a, float) and isinstance(b, float):
        return (math.isnan(a) and math.isnan(b)) or a == b
    return a == b


def test_discovery_names_bag_joints_by_path_and_by_bag(bags):
    refs = catalog.discover([str(bags / "bags")])
    got = {(r.rel, r.joint, r.bag_joint, r.start_utc) for r in refs}
    assert got == {("arm1/2026-01-05T08-00-00.mcap", "arm1", None, "2026-01-05T08:00:00Z"),
                   ("arm2_bag", "shoulder", "shoulder", "2026-01-05T08:00:00Z"),
                   ("arm2_bag", "wrist", "wrist", "2026-01-05T08:00:00Z")}
    assert len({catalog.content_key(r, OPTIONS) for r in refs}) == 3


def test_bag_records_equal_their_csv_twins(bags, tmp_path):
    th = trends.load_thresholds()
    s_bag = job.run([str(bags / "bags")], tmp_path / "b", OPTIONS, th, direct=True, quiet=True)
    s_csv = job.run([str(bags / "twins")], tmp_path / "c", OPTIONS, th, direct=True, quiet=True)
    assert s_bag["refused"] == [] and s_csv["refused"] == []
    b, c = _records(tmp_path / "b"), _records(tmp_path / "c")
    assert set(b) == {"arm1", "shoulder", "wrist"}
    for j in b:
        diff = [n for n in VALUE_NAMES if not _same(b[j][n], c[j][n])]
        assert diff == [], f"{j}: {[(n, b[j][n], c[j][n]) for n in diff]}"
        assert b[j]["start_utc"] == c[j]["start_utc"]
    # a second run finds every record up to date (the folder's files hashed)
    again = job.run([str(bags / "bags")], tmp_path / "b", OPTIONS, th, direct=True, quiet=True)
    assert again["analysed"] == 0 and again["skipped_up_to_date"] == 3


def test_bag_in_windows_keeps_every_message_once(bags):
    ref = next(r for r in catalog.discover([str(bags / "bags")]) if r.joint == "wrist")
    parts = chunks.parts(ref, chunk_bytes=ref.bag["bytes"] // 3)
    assert len(parts) == 4 and all(p["joint"] == "wrist" for p in parts)
    whole = bagin.read(ref.path, "wrist")[0]["t_s"]
    counts = [len(bagin.read(ref.path, "wrist", p["window_ns"])[0]["t_s"]) for p in parts]
    assert sum(counts) == len(whole) and min(counts) > 0
    rec = [record.analyze_log(ref.path, gear_ratio=100.0, **p) for p in parts]
    assert sum(r["samples"] for r in rec) == len(whole)
    starts = [r["chunk_offset_s"] for r in rec]
    assert starts[0] == 0.0 and all(b > a for a, b in zip(starts, starts[1:]))
