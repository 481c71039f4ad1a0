"""docs/how-to/ros2.md against the protocol: the ros2_control mapping table and
URDF block against firmware/hd_protocol.def and the DBC, the topics table
and the Foxglove layout against the channels the writer makes (no build,
no ROS)."""
from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

from hdtools import canproto, protocol
from hdtools.rosio import messages, topics

DOC = (ROOT / "docs" / "how-to" / "ros2.md").read_text()
TRANSPORT_PARAMS = {"can_interface"}       # the only hardware param that is not a joint parameter


def block(name: str) -> str:
    m = re.search(rf"<!-- BEGIN {re.escape(name)} -->\n(.*?)<!-- END {re.escape(name)} -->",
                  DOC, re.S)
    assert m, f"docs/how-to/ros2.md has no {name} block"
    return m.group(1)


def table(name: str) -> list[dict]:
    lines = [ln for ln in block(name).splitlines() if ln.startswith("|")]
    head = [c.strip() for c in lines[0].strip("|").split("|")]
    return [dict(zip(head, (c.strip().strip("`") for c in ln.strip("|").split("|"))))
            for ln in lines[2:]]


INTERFACES = table("ros2_control:interfaces")
DB = canproto.load_db(1)


def test_every_mapped_frame_signal_and_unit_is_the_protocols():
    frames = {f.name: f for f in protocol.frames()}
    for row in INTERFACES:
        if row["frame"] == "-":
            assert row["kind"] == "command" and "no frame yet" in row["conversion"], row
            continue
        frame = frames[row["frame"]]                   # a frame of hd_protocol.def
        assert frame.direction == ("tx" if row["kind"] == "state" else "rx"), row
        signal = DB.get_message_by_name(row["frame"]).get_signal_by_name(row["signal"])
        assert (signal.unit or "") == row["unit"], row


def test_every_telemetry_signal_is_mapped():
    mapped = {(r["frame"], r["signal"]) for r in INTERFACES}
    for frame in ("TELEM_A", "TELEM_B", "TELEM_C", "FEEDFORWARD"):
        for s in DB.get_message_by_name(frame).signals:
            if "Seq" in s.name or s.name == "OutputPresent":
                continue                   # framing: the sequence, the output-encoder flag
            assert (frame, s.name) in mapped, f"{frame}.{s.name} is not in docs/how-to/ros2.md"


def test_urdf_block_has_the_tables_interfaces_and_real_parameters():
    xml = re.search(r"```xml\n(.*?)```", block("ros2_control:urdf"), re.S).group(1)
    root = ET.fromstring(xml)
    joint = root.find("joint")
    got = {(e.tag.split("_")[0], e.get("name")) for e in joint}
    want = {(r["kind"], r["interface"]) for r in INTERFACES}
    assert got == want
    keys = {p.key for p in protocol.params()}
    for p in root.find("hardware").findall("param"):
        assert p.get("name") in keys | TRANSPORT_PARAMS, p.get("name")
        if p.get("name") in keys:
            assert protocol.param_by_key(p.get("name")).check(float(p.text)) is None


def test_topics_table_is_what_the_writer_makes():
    rows = table("ros2:topics")
    doc = {r["topic"].replace("JOINT", "j"): r["type"] for r in rows}
    made = dict(messages.Encoder("j", 1).connections())
    assert doc == made


def test_layout_names_only_channels_a_recording_has():
    layout = json.loads((ROOT / "docs" / "foxglove-layout.json").read_text())
    topics_made = {t.replace("/joint1/", "/JOINT/") for t, _ in
                   messages.Encoder("joint1", 1).connections()}
    paths = re.findall(r'"(/[A-Za-z0-9_/]+)(?:\.|")', json.dumps(layout["configById"]))
    assert paths
    for p in paths:
        assert p in topics_made or p.replace("/joint1/", "/JOINT/") in topics_made, p


@pytest.mark.parametrize("topic", [t for t, _ in messages.Encoder("j", 1).connections()])
def test_topic_names_are_valid_ros_names(topic):
    assert re.fullmatch(r"(/[A-Za-z][A-Za-z0-9_]*)+", topic)
    assert topics.check_joint_name("j") == "j"


def test_log_contract_table_is_what_analyze_reads():
    from hdtools.rosio import bagin
    rows = {r["analysis column"]: r["from the bag"] for r in table("ros2:contract")}
    for column, channel in bagin.EXTRA_COLUMNS.items():
        assert rows[column] == topics.channel_topic("JOINT", channel)
    raw = topics.channel_topic("JOINT", bagin.RAW_TORQUE_CHANNEL)
    assert rows["torque_nm"].startswith(f"`{raw}` where present".strip("`"))
    assert set(rows) == set(bagin.EXTRA_COLUMNS) | {"t_s", "torque_nm", "output_angle_rad",
                                                    "output_velocity_rad_s"}
