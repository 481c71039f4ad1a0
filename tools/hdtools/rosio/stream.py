"""Samples to every output at once (Recording), and the monitor's decoded
frames to samples as they arrive (Live).

Time: a sample is stamped on the host clock at device time, as the
monitor places it: stamp = the host time of the first sample + the
unwrapped telemetry sequence x the period (hdtools.telemetry), so host
jitter and USB batching do not reach the stamps; before the period is
known (no telemetry_rate_hz answer yet) the host's receive time is used.

Angles, causally (the monitor cannot wait for the next TELEM_C): a sample
with TELEM_C takes its counts (unwrapped, / motor_cpr, output_cpr); the
samples after it add the integral of MotorVelocity (the output: divided by
gear_ratio).  A sample is held until its TELEM_C (same sequence) or the
next pair arrives: one sample of delay.  `canlog convert` has the whole
log and interpolates instead (hdtools.telemetry.angles)."""
from __future__ import annotations

import math

from .. import canproto, protocol, telemetry
from . import messages


class Recording:
    """One Encoder, several sinks (BagOutput, the live server): each
    message is encoded once and given to all."""

    def __init__(self, encoder: messages.Encoder, sinks: list):
        self.encoder, self.sinks = encoder, list(sinks)
        self.samples = 0

    def _put(self, items, stamp_ns: int) -> None:
        for topic, msgtype, data in items:
            for sink in self.sinks:
                sink.write(topic, msgtype, data, stamp_ns)

    def sample(self, s: dict) -> None:
        self._put(self.encoder.sample(s), s["stamp_ns"])
        self.samples += 1

    def value(self, signal: str, v: float, stamp_ns: int) -> None:
        if math.isfinite(v):
            self._put([self.encoder.value(signal, v)], stamp_ns)

    def diagnostics(self, stamp_ns: int, state, faults: int, values: dict) -> None:
        self._put([self.encoder.diagnostics(stamp_ns, state, faults, values)], stamp_ns)

    def close(self) -> None:
        """Every file completed first, then all renamed: a failure leaves
        none of them (the live server just stops)."""
        files = [s for s in self.sinks if hasattr(s, "commit")]
        for sink in files:
            sink.finish()
        for sink in files:
            sink.commit()
        for sink in self.sinks:
            if sink not in files:
                sink.close()

    def abort(self) -> None:
        for sink in self.sinks:
            abort = getattr(sink, "abort", None)
            if abort is not None:
                abort()


HOLD_S = 1.0          # samples held at most this long waiting for the period


def _ns(t_s: float) -> int:
    return int(round(t_s * 1e9))


class Live:
    """MonitorState's listener: listener(kind, t_host_s, decoded, state)."""

    def __init__(self, recording: Recording):
        self.rec = recording
        self.queue: list[dict] = []         # samples not yet emitted (the last waits for TELEM_C)
        self.period_s: float | None = None
        self.host0_ns: int | None = None
        self.motor_anchor = self.output_anchor = None     # unwrapped counts
        self.motor_rad = self.output_rad = None
        self.faults = 0

    def __call__(self, kind: str, t: float, d: dict, state) -> None:
        getattr(self, "_" + kind)(t, d, state)

    def _resolve_period(self, state, final: bool) -> None:
        """Samples are held until the monitor's queries are answered (the
        period from telemetry_rate_hz, and gear_ratio, asked last) or HOLD_S
        passed; without an answer (--passive) the period is estimated from
        the host stamps."""
        if self.period_s is not None:
            return
        late = final or self.queue[-1]["t_host"] - self.queue[0]["t_host"] >= HOLD_S
        if state.period_s and ("gear_ratio" in state.params or late):
            self.period_s = state.period_s
        elif late:
            guess, _ = telemetry.estimate_period_s([q["t_host"] for q in self.queue],
                                                   [q["seq"] for q in self.queue])
            self.period_s = guess or telemetry.TICK_S

    def _telemetry(self, t, d, state) -> None:
        s = {k: float(d[k]) for k in messages.SAMPLE_SIGNALS if k in d}
        if not canproto.torque_valid(d):
            s["TorqueRaw"] = s["TorqueFiltered"] = math.nan    # "not available"
        s["t_host"], s["seq"], s["step"] = t, d["SeqB"], d["step"]
        self.queue.append(s)
        if self.host0_ns is None:
            self.host0_ns = _ns(t)
        self._resolve_period(state, final=False)
        self._emit(state, keep_last=True)
        if int(d["Faults"]) != self.faults:
            self.faults = int(d["Faults"])
            self.rec.diagnostics(_ns(t), None, self.faults, {})

    def _angles(self, t, d, state) -> None:
        if not self.queue or self.queue[-1]["seq"] != d["SeqC"]:
            return
        # the counts are scaled when the sample is emitted: by then the
        # held samples have the cpr answers too
        self.queue[-1]["counts"] = (int(d["MotorCounts"]),
                                    int(d["OutputCounts"]) if int(d["OutputPresent"]) else None)
        self._emit(state, keep_last=False)

    def flush(self, state) -> None:
        """Emits everything held (the monitor is ending)."""
        if self.queue:
            self._resolve_period(state, final=True)
            self._emit(state, keep_last=False)

    def _emit(self, state, keep_last: bool) -> None:
        if self.period_s is None:
            return
        ready = self.queue[:-1] if keep_last else self.queue
        self.queue = self.queue[-1:] if keep_last else []
        gear = state.params.get("gear_ratio")
        for s in ready:
            self._angle(s, gear, state.params)
            s["stamp_ns"] = self.host0_ns + _ns(s["step"] * self.period_s)
            s["output_velocity_rad_s"] = s["MotorVelocity"] / gear if gear else None
            self.rec.sample(s)

    def _angle(self, s: dict, gear: float | None, params: dict) -> None:
        vel = s.get("MotorVelocity", 0.0)
        counts = s.get("counts")
        if counts is not None:
            motor, output = counts
            if params.get("motor_cpr"):
                self.motor_anchor = _unwrap(self.motor_anchor, motor, telemetry.MOTOR_COUNTS_MOD)
                self.motor_rad = self.motor_anchor * 2 * math.pi / params["motor_cpr"]
            if output is not None and params.get("output_cpr"):
                self.output_anchor = _unwrap(self.output_anchor, output,
                                             telemetry.OUTPUT_COUNTS_MOD)
                self.output_rad = self.output_anchor * 2 * math.pi / params["output_cpr"]
        else:
            if self.motor_rad is not None:
                self.motor_rad += vel * self.period_s
            if self.output_rad is not None and gear:
                self.output_rad += vel / gear * self.period_s
        s["motor_angle_rad"], s["output_angle_rad"] = self.motor_rad, self.output_rad

    def _heartbeat(self, t, d, state) -> None:
        st, faults, values = messages.heartbeat_values(d)
        self.rec.diagnostics(_ns(t), st, faults, values)

    def _feedforward(self, t, d, state) -> None:
        self.rec.value("FfTorque", float(d["FfTorque"]), _ns(t))

    def _ack(self, t, d, state) -> None:
        pass                    # parameters reach state.params; VERSION/INFO: MonitorOutputs


def _unwrap(prev: int | None, counts: int, modulus: int) -> int:
    if prev is None:
        return counts
    step = (counts - prev + modulus // 2) % modulus - modulus // 2
    return prev + step


def device_metadata(params: dict, boots: list[str], items: dict[str, str], joint: str,
                    node: int) -> dict[str, str]:
    """rosbag2 custom_data: hdjoint.joint, .node, .boot, .version.<item>,
    .info.<item>, .param.<key> (all strings)."""
    from .. import cli
    out = {"hdjoint.joint": joint, "hdjoint.node": str(node),
           "hdjoint.hdsense": cli.version(),
           "hdjoint.host_param_table_crc": f"0x{protocol.param_table_crc():08X}"}
    if boots:
        out["hdjoint.boot"] = boots[-1]
    for name, value in items.items():
        code = protocol.by_name(protocol.info_items(), name).code
        out[f"hdjoint.{'version' if code < 16 else 'info'}.{name.lower()}"] = value
    for key, value in sorted(params.items()):
        out[f"hdjoint.param.{key}"] = f"{value:.9g}"
    return out
