"""One telemetry sample, a heartbeat or a fault change -> ROS 2 messages,
serialized to CDR by rosbags (its copy of the ROS 2 Humble definitions;
JointState, Float64 and DiagnosticArray are the same in every release
since).

A sample is a dict: "stamp_ns" (int, the host clock), the decoded
TELEM_A/B signals by their DBC names, and "output_angle_rad",
"output_velocity_rad_s", "motor_angle_rad" (None when unknown).
"""
from __future__ import annotations

import math

import numpy as np
from rosbags.typesys import Stores, get_typestore

from .. import canproto, protocol
from . import topics

TYPESTORE = get_typestore(Stores.ROS2_HUMBLE)
_T = TYPESTORE.types
Time = _T["builtin_interfaces/msg/Time"]
Header = _T["std_msgs/msg/Header"]
JointState = _T[topics.JOINT_STATE_TYPE]
Float64 = _T[topics.FLOAT_TYPE]
DiagnosticArray = _T[topics.DIAGNOSTIC_TYPE]
DiagnosticStatus = _T["diagnostic_msgs/msg/DiagnosticStatus"]
KeyValue = _T["diagnostic_msgs/msg/KeyValue"]
SAMPLE_SIGNALS = topics.sample_signals()
# DiagnosticStatus levels by joint state: a stopped or starting joint is
# STALE (its values are not live), a degraded one WARN.
LEVEL_OF_STATE = {"RUN": DiagnosticStatus.OK, "DEGRADED": DiagnosticStatus.WARN,
                  "INIT": DiagnosticStatus.STALE, "STOPPED": DiagnosticStatus.STALE}


def header(stamp_ns: int, frame_id: str = "") -> Header:
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    return Header(stamp=Time(sec=sec, nanosec=nsec), frame_id=frame_id)


def _arr(value) -> np.ndarray:
    """A one-joint JointState field: empty when unknown (the message's
    convention for "not measured")."""
    ok = value is not None and math.isfinite(value)
    return np.array([value] if ok else [], np.float64)


def serialize(msg, msgtype: str) -> bytes:
    return bytes(TYPESTORE.serialize_cdr(msg, msgtype))


class Encoder:
    """Messages of one joint: (topic, msgtype, cdr bytes) tuples."""

    def __init__(self, joint: str, node: int):
        self.joint, self.node = topics.check_joint_name(joint), node
        self.channels = topics.signal_channels()
        self.topic = {sig: topics.channel_topic(joint, ch) for sig, ch in self.channels.items()}
        self.topic[topics.MOTOR_ANGLE] = topics.channel_topic(joint, topics.MOTOR_ANGLE)

    def connections(self) -> list[tuple[str, str]]:
        """(topic, msgtype) of every channel, in a fixed order."""
        return ([(topics.JOINT_STATES, topics.JOINT_STATE_TYPE),
                 (topics.DIAGNOSTICS, topics.DIAGNOSTIC_TYPE)] +
                [(t, topics.FLOAT_TYPE) for t in self.topic.values()])

    def sample(self, s: dict) -> list[tuple[str, str, bytes]]:
        torque_ok = math.isfinite(s.get(topics.EFFORT_SIGNAL, math.nan))
        js = JointState(header=header(s["stamp_ns"]), name=[self.joint],
                        position=_arr(s.get("output_angle_rad")),
                        velocity=_arr(s.get("output_velocity_rad_s")),
                        effort=_arr(s[topics.EFFORT_SIGNAL] if torque_ok else None))
        out = [(topics.JOINT_STATES, topics.JOINT_STATE_TYPE,
                serialize(js, topics.JOINT_STATE_TYPE))]
        for sig, topic in self.topic.items():
            v = s.get(sig)
            if v is None or not math.isfinite(v):
                continue                    # not sent, or "not available": no message
            out.append((topic, topics.FLOAT_TYPE, serialize(Float64(data=float(v)),
                                                            topics.FLOAT_TYPE)))
        return out

    def value(self, signal: str, v: float) -> tuple[str, str, bytes]:
        """One signal outside the telemetry pair (the feed-forward)."""
        return (self.topic[signal], topics.FLOAT_TYPE,
                serialize(Float64(data=float(v)), topics.FLOAT_TYPE))

    def diagnostics(self, stamp_ns: int, state: str | None, faults: int,
                    values: dict[str, str]) -> tuple[str, str, bytes]:
        """The joint's status: the heartbeat's state and record statuses, or
        a change of the telemetry's fault bits (state None: keeps WARN if
        any fault)."""
        level = LEVEL_OF_STATE.get(state, DiagnosticStatus.OK)
        if faults and level == DiagnosticStatus.OK:
            level = DiagnosticStatus.WARN
        message = (state or "telemetry") + (": " + canproto.faults_str(faults) if faults else "")
        kv = [KeyValue(key="faults", value=canproto.faults_str(faults))] + [
            KeyValue(key=k, value=str(v)) for k, v in values.items()]
        status = DiagnosticStatus(level=np.uint8(level), name=f"hdjoint/{self.joint}",
                                  message=message, hardware_id=f"hdjoint node {self.node}",
                                  values=kv)
        arr = DiagnosticArray(header=header(stamp_ns), status=[status])
        return topics.DIAGNOSTICS, topics.DIAGNOSTIC_TYPE, serialize(arr, topics.DIAGNOSTIC_TYPE)


def heartbeat_values(d: dict) -> tuple[str, int, dict[str, str]]:
    """(state, fault bits, key values) of a decoded HEARTBEAT (raw codes or
    cantools' choice names)."""
    rec = protocol.record_statuses()

    def name(entries, v):
        return v if isinstance(v, str) else protocol.name_of(entries, int(v))
    values = {"state": name(protocol.states(), d["State"]),
              "calibration": name(rec, d["CalibStatus"]),
              "configuration": name(rec, d["ConfigStatus"]),
              "profile": name(rec, d["ProfileStatus"]),
              "deadline_misses": str(int(d["DeadlineMisses"]))}
    return values["state"], int(d["HbFaults"]), values
