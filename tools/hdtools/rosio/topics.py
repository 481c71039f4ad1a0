"""Topic names and message types of the joint's recordings (docs/how-to/ros2.md).

Nothing here lists a signal by hand: the extra channels are the signals of
the telemetry frames in firmware/hdjoint.dbc (itself generated from
firmware/hd_protocol.def), named in snake case with the DBC's unit as the
suffix (TorqueRaw "Nm" -> torque_raw_nm).  Sequence counters are framing,
not signals, and TorqueFiltered is JointState.effort, so neither gets a
channel of its own.
"""
from __future__ import annotations

import re

from .. import canproto

JOINT_STATES = "/joint_states"
DIAGNOSTICS = "/diagnostics"
NAMESPACE = "/hdjoint"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
FLOAT_TYPE = "std_msgs/msg/Float64"
DIAGNOSTIC_TYPE = "diagnostic_msgs/msg/DiagnosticArray"
METADATA_KEY = "hdjoint"          # rosbag2 custom_data keys start with it

# Frames whose signals get channels: what the joint sends per sample, and
# the controller's feed-forward when it is on the bus.
SAMPLE_FRAMES = ("TELEM_A", "TELEM_B")
SIGNAL_FRAMES = SAMPLE_FRAMES + ("FEEDFORWARD",)
EFFORT_SIGNAL = "TorqueFiltered"
# Derived per sample from TELEM_C's counts (hdtools.telemetry.angles):
# the motor angle has no DBC signal of its own; the output angle is
# JointState.position.
MOTOR_ANGLE = "motor_angle_rad"
UNIT_SUFFIX = {"Nm": "_nm", "rad/s": "_rad_s", "rad": "_rad", "A": "_a", "": ""}
JOINT_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,63}$")


def snake(name: str) -> str:
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name).lower()


def _is_counter(signal) -> bool:
    return "Seq" in signal.name          # SeqA, SeqB, FfSeq: the frames' sequence numbers


def sample_signals() -> tuple[str, ...]:
    """DBC names of the signals of one telemetry sample (TELEM_A + TELEM_B)."""
    db = canproto.load_db(1)
    return tuple(s.name for f in SAMPLE_FRAMES for s in db.get_message_by_name(f).signals
                 if not _is_counter(s))


def signal_channels() -> dict[str, str]:
    """{DBC signal name: channel name} of every signal with its own channel,
    in the DBC's order."""
    db = canproto.load_db(1)
    out = {}
    for frame in SIGNAL_FRAMES:
        for s in db.get_message_by_name(frame).signals:
            if _is_counter(s) or s.name == EFFORT_SIGNAL:
                continue
            out[s.name] = snake(s.name) + UNIT_SUFFIX.get(s.unit or "", "")
    return out


def channel_topic(joint: str, channel: str) -> str:
    return f"{NAMESPACE}/{joint}/{channel}"


def check_joint_name(name: str) -> str:
    """A joint name that is also a valid ROS 2 topic token (it names the
    joint's channels); ValueError otherwise."""
    if not JOINT_NAME.match(name or ""):
        raise ValueError(f"joint name {name!r}: use letters, digits and '_', starting with a "
                         "letter (at most 64 characters)")
    return name
