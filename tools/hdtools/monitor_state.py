"""What `hdsense monitor` knows about one joint, fed one frame at a time:
frame classification (this node, other joints, foreign, malformed), the
decoded telemetry, heartbeat, BOOT, answers and control state (CTRL_STATE),
sequence gaps, bus load, and the status line and summary made of them."""
from __future__ import annotations

import re
import time
from collections import deque

import can

from . import canproto, paths, protocol
from .canshared import boot_report
from .safeio import OutputError
from .telemetry import telemetry_period_s

QUERY_PARAMS = ("telemetry_rate_hz", "angle_telemetry_every", "motor_cpr", "output_cpr",
                "gear_ratio")
_TYPE_NAME = {f.type: f.name for f in protocol.frames()}


def _c_names(rel: str, pattern: str, block_end: str | None = None) -> dict[int, str]:
    """{value: NAME} of the constants `pattern` matches in a C header of the
    source tree (or its installed copy), inside the block that ends at
    `block_end` if given: the control modes, limits and flags are named
    where the firmware defines them."""
    text = paths.source_file(rel).read_text()
    if block_end is not None:
        end = text.index(block_end)
        text = text[text.rindex("{", 0, end):end]
    return {int(v, 0): n for n, v in re.findall(pattern, text)}


CTRL_MODES = {v: n for v, n in _c_names("control/hd_ctrl.h", r"HD_CTRL_([A-Z_]+)\s*=\s*(\d+),",
                                          "} hd_ctrl_mode_t;").items() if n != "MODE_COUNT"}
CTRL_MODE_NAMES = tuple(CTRL_MODES[i] for i in sorted(CTRL_MODES))   # by code
CTRL_LIMITS = _c_names("control/hd_ctrl.h", r"#define HD_CTRL_LIM_([A-Z_]+)\s+(0x[0-9a-fA-F]+)u")
CTRL_FLAGS = _c_names("firmware/hd_can_proto.h",
                      r"#define HD_CAN_CTRL_FLAG_([A-Z_]+)\s+(0x[0-9a-fA-F]+)u")


def bit_names(bits: int, names: dict[int, str]) -> str:
    """"A|B" of the set bits (unknown ones in hex), "-" for none."""
    out = [n for b, n in sorted(names.items()) if bits & b]
    rest = bits & ~sum(names)
    if rest:
        out.append(f"0x{rest:02X}")
    return "|".join(out) or "-"


def ctrl_mode_name(mode: int) -> str:
    return CTRL_MODES.get(int(mode), f"mode {int(mode)}")


# ------------------------------------------------------------------ frames
def frame_bits(msg: can.Message) -> int:
    """Bits a classic frame takes on the wire, stuff bits not counted (so
    the bus load shown is a lower bound, within ~15 %)."""
    n = 0 if msg.is_remote_frame else min(len(msg.data), 8)
    return (67 if msg.is_extended_id else 47) + 8 * n


def classify(msg: can.Message) -> tuple[str, int | None, str | None]:
    """("error" | "foreign" | "joint", node, frame type name) of a frame:
    a joint frame has our 29-bit prefix, a known frame type and a node in
    1..127; everything else on the bus is foreign."""
    if msg.is_error_frame:
        return "error", None, None
    ident = msg.arbitration_id
    if not msg.is_extended_id or (ident & ~0xFFFF) != protocol.ID_PREFIX:
        return "foreign", None, None
    ftype, node = (ident >> 8) & 0xFF, ident & 0xFF
    name = _TYPE_NAME.get(ftype)
    if name is None or not protocol.NODE_MIN <= node <= protocol.NODE_MAX:
        return "foreign", None, None
    return "joint", node, name


def malformed_reason(msg: can.Message, name: str) -> str | None:
    if msg.is_remote_frame:
        return "remote frame"
    if msg.is_fd:
        return "CAN FD frame"
    want = protocol.frame(name).dlc
    if len(msg.data) != want:
        return f"{len(msg.data)} data bytes, {name} has {want}"
    return None


# ------------------------------------------------------------------- state
class MonitorState:
    """Everything the monitor knows, fed one frame at a time (feed never
    raises on a frame: bad ones are counted)."""

    def __init__(self, node: int | None, bitrate: int, window_s: float, events=None):
        self.node = node
        self.bitrate = bitrate
        self.events = events or (lambda line: None)
        self.dbs: dict[int, object] = {}
        self.frames = self.node_frames = self.foreign = self.errors = 0
        self.malformed = 0
        self.malformed_why: dict[str, int] = {}
        self.other_nodes: dict[int, int] = {}
        self.pairs = self.lost = self.angle_frames = 0
        self.pending_a = None
        self.last_seq = None
        self.last_pair_t = None
        self.sample = None
        self.faults_seen = 0
        self.faults_window = 0
        self.heartbeat = None
        self.heartbeats = 0
        self.boots: list[dict] = []
        self.params: dict[str, float] = {}
        self.acks = 0
        self.bits = 0
        self.first_t = self.last_t = None
        self.step = 0                      # unwrapped telemetry sequence
        self.maxlen = 1
        self.set_window(window_s, 1000.0)
        self.window_s = window_s
        self.load_samples: deque = deque(maxlen=4000)   # (t, bits)
        self.ctrl = None            # the last CTRL_STATE (a board with a drive)
        self.ctrl_frames = 0
        self.ctrl_limits_seen = self.ctrl_limits_window = 0
        self.listener = None    # listener(kind, t, decoded, state): the ROS 2 outputs (rosio)

    def _tell(self, kind: str, t: float, d: dict) -> None:
        if self.listener is not None:
            self.listener(kind, t, d, self)

    def set_window(self, window_s: float, rate_hz: float) -> None:
        n = max(16, int(window_s * max(rate_hz, 1.0)) + 1)
        if n != self.maxlen:
            self.maxlen = n
            self.trace = {k: deque(getattr(self, "trace", {}).get(k, ()), maxlen=n)
                          for k in ("step", "raw", "filt", "ripple")}

    @property
    def period_s(self) -> float | None:
        rate = self.params.get("telemetry_rate_hz")
        if rate:
            return telemetry_period_s(rate)
        return None

    def db(self, node: int):
        if node not in self.dbs:
            self.dbs[node] = canproto.load_db(node)
        return self.dbs[node]

    def feed(self, msg: can.Message) -> None:
        try:
            self._feed(msg)
        except OutputError:
            raise                   # an output (rosio's) failed: not a bad frame
        except Exception as exc:  # noqa: BLE001 - a frame never stops the monitor
            self.malformed += 1
            why = f"undecodable: {type(exc).__name__}"
            self.malformed_why[why] = self.malformed_why.get(why, 0) + 1

    def _feed(self, msg: can.Message) -> None:
        t = float(msg.timestamp or time.time())
        self.frames += 1
        bits = frame_bits(msg)
        self.bits += bits
        self.load_samples.append((t, bits))
        self.first_t = t if self.first_t is None else self.first_t
        self.last_t = t
        kind, node, name = classify(msg)
        if kind == "error":
            self.errors += 1
            return
        if kind == "foreign":
            self.foreign += 1
            return
        if self.node is None:
            self.node = node
            self.events(f"node {node}: the first joint heard (--node to choose another)")
        if node != self.node:
            self.foreign += 1
            self.other_nodes[node] = self.other_nodes.get(node, 0) + 1
            return
        why = malformed_reason(msg, name)
        if why is not None:
            self.malformed += 1
            key = f"{name}: {why}"
            self.malformed_why[key] = self.malformed_why.get(key, 0) + 1
            return
        self.node_frames += 1
        d = self.db(node).get_message_by_name(name).decode(bytes(msg.data), decode_choices=False)
        getattr(self, f"_on_{name.lower()}", lambda *_: None)(t, d)

    # ---- per frame type
    def _on_telem_a(self, t, d):
        self.pending_a = (t, d)

    def _on_telem_b(self, t, d):
        if self.pending_a is None or self.pending_a[1]["SeqA"] != d["SeqB"]:
            self.pending_a = None
            return
        a = self.pending_a[1]
        self.pending_a = None
        seq = d["SeqB"]
        if self.last_seq is not None:
            steps = (seq - self.last_seq) % 256
            period = self.period_s
            if period and self.last_pair_t is not None:
                wraps = round(((t - self.last_pair_t) / period - steps) / 256)
                steps += 256 * max(0, wraps)
            if steps == 0:
                return                      # a repeated frame
            if steps > 1:
                self.lost += steps - 1
                self.events(f"sequence gap: {steps - 1} telemetry sample(s) lost")
            self.step += steps
        self.last_seq, self.last_pair_t = seq, t
        self.pairs += 1
        valid = canproto.torque_valid(a)
        self.sample = {"raw": a["TorqueRaw"] if valid else float("nan"),
                       "filt": a["TorqueFiltered"] if valid else float("nan"),
                       "ripple": a["Ripple"], "vel": d["MotorVelocity"],
                       "faults": int(d["Faults"]), "kf": int(d["KfStatus"])}
        new = int(d["Faults"]) & ~self.faults_seen
        if new:
            self.events("faults: " + canproto.faults_str(new))
        self.faults_seen |= int(d["Faults"])
        self.faults_window |= int(d["Faults"])
        for k in ("raw", "filt", "ripple"):
            self.trace[k].append(self.sample[k])
        self.trace["step"].append(self.step)
        self._tell("telemetry", t, {**a, **d, "step": self.step})

    def _on_telem_c(self, t, d):
        self.angle_frames += 1
        self._tell("angles", t, d)

    def _on_ctrl_state(self, t, d):
        c = {"asked": ctrl_mode_name(d["CtrlModeAsked"]), "run": ctrl_mode_name(d["CtrlModeRun"]),
             "limits": int(d["CtrlLimits"]), "torque_ref_nm": float(d["CtrlTorqueRef"]),
             "current_a": float(d["CtrlCurrent"]), "seq": int(d["CtrlSeq"]),
             "flags": int(d["CtrlFlags"])}
        last = self.ctrl
        if last is None or (last["asked"], last["run"]) != (c["asked"], c["run"]):
            self.events(f"control: mode {c['run']} (asked {c['asked']})")
        if last is None or last["flags"] != c["flags"]:
            self.events(f"control: flags {bit_names(c['flags'], CTRL_FLAGS)}")
        new = c["limits"] & ~self.ctrl_limits_seen
        if new:   # once per limit: a limit can shape every tick
            self.events(f"control: limited by {bit_names(new, CTRL_LIMITS)}")
        self.ctrl_limits_seen |= c["limits"]
        self.ctrl_limits_window |= c["limits"]
        self.ctrl = c
        self.ctrl_frames += 1

    def ctrl_text(self, limits: int) -> str:
        c = self.ctrl
        return (f"{c['run']} (asked {c['asked']}), torque ref {c['torque_ref_nm']:+.2f} Nm, "
                f"current {c['current_a']:+.3f} A, limits {bit_names(limits, CTRL_LIMITS)}, "
                f"flags {bit_names(c['flags'], CTRL_FLAGS)}, setpoint seq {c['seq']}")

    def _on_feedforward(self, t, d):
        self._tell("feedforward", t, d)

    def _on_heartbeat(self, t, d):
        rec = protocol.record_statuses()
        hb = {"state": protocol.name_of(protocol.states(), d["State"]),
              "faults": int(d["HbFaults"]), "deadline_misses": int(d["DeadlineMisses"]),
              "calib": protocol.name_of(rec, d["CalibStatus"]),
              "config": protocol.name_of(rec, d["ConfigStatus"]),
              "profile": protocol.name_of(rec, d["ProfileStatus"])}
        if self.heartbeat is None or hb["state"] != self.heartbeat["state"]:
            self.events(f"state {hb['state']} (calibration {hb['calib']}, configuration "
                        f"{hb['config']})")
        self.heartbeat = hb
        self.heartbeats += 1
        self._tell("heartbeat", t, d)

    def _on_boot(self, t, d):
        boot = boot_report(d)
        self.boots.append(boot)
        self.events("BOOT: " + boot)

    def _on_ack(self, t, d):
        self.acks += 1
        self._tell("ack", t, d)
        op = protocol.name_of(protocol.opcodes(), d["AckOpcode"])
        res = protocol.name_of(protocol.results(), d["AckResult"])
        if op in ("GET_PARAM", "SET_PARAM") and res == "OK":
            try:
                p = protocol.param_by_id(d["AckAux"])
            except KeyError:
                return
            self.params[p.key] = d["AckValue"]
            if p.key == "telemetry_rate_hz" and d["AckValue"] > 0:
                self.set_window(self.window_s, d["AckValue"])
        elif res != "OK":
            self.events(f"answer: {op} token {d['AckToken']} -> {res}")

    # ---- summaries
    def bus_load(self, now: float, span_s: float = 1.0) -> float:
        bits = sum(b for t, b in self.load_samples if t > now - span_s)
        return 100.0 * bits / (self.bitrate * span_s)

    def status_line(self, now: float) -> str:
        node = self.node if self.node is not None else "?"
        parts = [f"node {node}"]
        hb = self.heartbeat
        parts.append(f"{hb['state']}" if hb else "no heartbeat")
        s = self.sample
        if s:
            parts.append(f"raw {s['raw']:+8.2f} filt {s['filt']:+8.2f} ripple {s['ripple']:+7.3f} Nm"
                         f"  vel {s['vel']:+9.3f} rad/s")
        else:
            parts.append("no telemetry")
        parts.append("faults " + canproto.faults_str(self.faults_window |
                                                      (hb["faults"] if hb else 0)))
        if hb:
            parts.append(f"calib {hb['calib']} config {hb['config']}")
        if self.ctrl:
            parts.append("ctrl " + self.ctrl_text(self.ctrl_limits_window))
            self.ctrl_limits_window = 0
        parts.append(f"lost {self.lost}")
        parts.append(f"load {self.bus_load(now):.0f}%")
        parts.append(f"foreign {self.foreign} malformed {self.malformed}")
        self.faults_window = 0
        return " | ".join(parts)

    def summary(self, wall_s: float) -> list[str]:
        span = (self.last_t - self.first_t) if self.frames > 1 else 0.0
        out = [f"duration_s = {wall_s:.2f}",
               f"node = {self.node if self.node is not None else 'none heard'}",
               f"frames = {self.frames}", f"node_frames = {self.node_frames}",
               f"telemetry_pairs = {self.pairs}", f"angle_frames = {self.angle_frames}",
               f"lost_telemetry = {self.lost}",
               f"foreign_frames = {self.foreign}", f"malformed_frames = {self.malformed}",
               f"error_frames = {self.errors}"]
        if self.other_nodes:
            out.append("other_joint_nodes = " + ", ".join(
                f"{n} ({c} frames)" for n, c in sorted(self.other_nodes.items())))
        for why, n in sorted(self.malformed_why.items()):
            out.append(f"malformed: {why} = {n}")
        if span > 0:
            out.append(f"telemetry_rate_hz = {max(self.pairs - 1, 0) / span:.1f}")
            out.append(f"bus_load_pct = {100.0 * self.bits / (self.bitrate * span):.1f} "
                       f"(at {self.bitrate} bit/s, stuff bits not counted)")
        out.append(f"faults_seen = {canproto.faults_str(self.faults_seen)}")
        out.append(f"heartbeats = {self.heartbeats}")
        if self.heartbeat:
            hb = self.heartbeat
            out.append(f"last_heartbeat = {hb['state']}, faults {canproto.faults_str(hb['faults'])}"
                       f", calibration {hb['calib']}, configuration {hb['config']}, deadline "
                       f"misses {hb['deadline_misses']}")
        out.append(f"boots = {len(self.boots)}")
        if self.ctrl_frames:
            out.append(f"ctrl_state_frames = {self.ctrl_frames}")
            out.append(f"last_ctrl_state = {self.ctrl_text(self.ctrl['limits'])}")
            out.append(f"ctrl_limits_seen = {bit_names(self.ctrl_limits_seen, CTRL_LIMITS)}")
        for key in QUERY_PARAMS:
            if key in self.params:
                out.append(f"param {key} = {self.params[key]:g}")
        return out
