"""`hdsense monitor`: watch one joint live on a CAN bus.

  hdsense monitor can0                         # SocketCAN; Ctrl-C ends
  hdsense monitor can0 --log run.log --plot    # record + live torque plot
  hdsense monitor -i pcan --channel PCAN_USBBUS1 --bitrate 1000000 --node 3
  hdsense monitor can0 --duration 10 --log run.log --plot-png run.png

Shows, once per --interval, the decoded telemetry of one node (raw,
filtered and ripple torque, motor velocity), fault bits by name, the last
heartbeat (state, record statuses), telemetry rate, lost telemetry
(sequence gaps), bus load, and how many frames were foreign (other devices,
other joint nodes) or malformed (this node's identifiers with a wrong
length, remote/FD/error frames).  Events (BOOT report, state and fault
changes, sequence gaps, answers to commands) are printed as they happen.
Only this node's frames are decoded; a bad frame is counted, never fatal.

--log FILE records every frame on the bus as a `candump -l` log (the
format `hdsense canlog decode` and `hdsense analyze` read), written under a
temporary name in FILE's directory, flushed every half second in whole
lines, and renamed to FILE when the monitor ends.  Unless --passive, the
monitor asks the joint (GET_PARAM) for telemetry_rate_hz, motor_cpr,
output_cpr, gear_ratio and angle_telemetry_every at the start, so the log
carries what its decoding needs.

On SocketCAN the monitor asks the kernel for an 8 MiB receive buffer
(root: always; others: up to net.core.rmem_max, which may be raised with
`sysctl -w net.core.rmem_max=8388608`); the summary shows what it got
(rx_buffer_bytes).  Frames the kernel drops from a full buffer never reach
the monitor: they show as lost telemetry (sequence gaps) only.

--plot opens a live plot of raw / filtered / ripple torque over the last
--window seconds (needs a display); --plot-png FILE writes the same plot
at the end (works headless).

--mcap FILE / --rosbag DIR write the telemetry as ROS 2 messages
(/joint_states, /diagnostics, /hdjoint/JOINT/...; --joint NAME), whole
or not at all; --foxglove serves them live on ws://127.0.0.1:8765
(docs/ros2.md).

Ends after --duration seconds, on Ctrl-C or SIGTERM, or when the plot
window is closed: the summary is printed, the log renamed, exit 0.
Exit status: 0 ok; 2 bad command line; 3 the log, PNG, MCAP or rosbag2
folder could not be written (temporaries removed; an old FILE is left as
it was) or the Foxglove server could not start;
5 the CAN interface cannot be opened or failed.
"""
from __future__ import annotations

import argparse
import os
import signal
import socket
import sys
import tempfile
import time
from collections import deque

import can
import numpy as np

from . import canproto, protocol
from .cmd_canlog import _node
from .joint import BusError, Joint, NoAnswer, open_bus
from .safeio import OutputError, UsageError
from .telemetry import telemetry_period_s

FLUSH_S = 0.5
# python-can leaves its SocketCAN socket at net.core.rmem_default (~200 KiB:
# about 280 frames, under 0.1 s of 1 kHz telemetry), so a monitor held up
# longer (a plot redraw, a busy machine) lost frames; measured in the VM
# test (tests/vm, docs/socketcan.md).  8 MiB holds seconds of telemetry.
RX_BUFFER_BYTES = 8 << 20
SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)     # Linux; not in Python 3.11
QUERY_PARAMS = ("telemetry_rate_hz", "angle_telemetry_every", "motor_cpr", "output_cpr",
                "gear_ratio")
_TYPE_NAME = {f.type: f.name for f in protocol.frames()}


# ------------------------------------------------------------------ frames
def candump_line(msg: can.Message, iface: str) -> str:
    """One `candump -l` line: "(sec.usec) IFACE ID#DATA"."""
    ts = max(0.0, float(msg.timestamp or 0.0))
    sec = int(ts)
    usec = min(999999, int(round((ts - sec) * 1e6)))
    if msg.is_error_frame:
        ident = f"{0x20000000 | (msg.arbitration_id & 0x1FFFFFFF):08X}"
    elif msg.is_extended_id:
        ident = f"{msg.arbitration_id & 0x1FFFFFFF:08X}"
    else:
        ident = f"{msg.arbitration_id & 0x7FF:03X}"
    if msg.is_remote_frame:
        body = "R" + (str(msg.dlc) if msg.dlc else "")
    elif msg.is_fd:
        flags = (1 if msg.bitrate_switch else 0) | (2 if msg.error_state_indicator else 0)
        body = f"#{flags:X}{bytes(msg.data).hex().upper()}"
    else:
        body = bytes(msg.data).hex().upper()
    return f"({sec}.{usec:06d}) {iface} {ident}#{body}\n"


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


def grow_rx_buffer(bus) -> int | None:
    """Enlarges the receive buffer of a SocketCAN bus (SO_RCVBUFFORCE as
    root, else SO_RCVBUF, which the kernel caps at net.core.rmem_max);
    returns the size granted, or None for other interfaces."""
    sock = getattr(bus, "socket", None)
    if not isinstance(sock, socket.socket) or sock.family != getattr(socket, "AF_CAN", -1):
        return None
    for option in (SO_RCVBUFFORCE, socket.SO_RCVBUF):
        try:
            sock.setsockopt(socket.SOL_SOCKET, option, RX_BUFFER_BYTES)
            break
        except OSError:
            continue
    return sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)


# ---------------------------------------------------------------- recorder
class LogRecorder:
    """candump -l lines to a temporary file next to the target; whole lines,
    flushed every FLUSH_S; renamed over the target by close()."""

    def __init__(self, path: str, iface: str):
        self.path, self.iface = path, "".join(c if c.isalnum() or c in "-_." else "_"
                                              for c in iface) or "can0"
        directory, base = os.path.split(os.path.abspath(path))
        if os.path.isdir(path):
            raise OutputError(f"{path}: cannot write: is a directory")
        try:
            fd, self.tmp = tempfile.mkstemp(prefix=f".{base}.", suffix=".tmp", dir=directory)
        except OSError as exc:
            raise OutputError(f"{path}: cannot write: {exc.strerror}") from None
        mask = os.umask(0)
        os.umask(mask)
        os.fchmod(fd, 0o666 & ~mask)
        self.f = os.fdopen(fd, "w", encoding="ascii", newline="\n")
        self.pending: list[str] = []
        self.last_flush = time.monotonic()

    def write(self, msg: can.Message) -> None:
        self.pending.append(candump_line(msg, self.iface))
        if time.monotonic() - self.last_flush >= FLUSH_S:
            self.flush()

    def flush(self) -> None:
        self.last_flush = time.monotonic()
        if not self.pending:
            return
        text, self.pending = "".join(self.pending), []
        try:
            self.f.write(text)
            self.f.flush()
        except OSError as exc:
            self.abort()
            raise OutputError(f"{self.path}: write failed: {exc.strerror}") from None

    def close(self) -> None:
        self.flush()
        try:
            os.fsync(self.f.fileno())
            self.f.close()
            os.replace(self.tmp, self.path)
        except OSError as exc:
            self.abort()
            raise OutputError(f"{self.path}: cannot write: {exc.strerror}") from None

    def abort(self) -> None:
        try:
            self.f.close()
        except OSError:
            pass
        try:
            os.unlink(self.tmp)
        except OSError:
            pass


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
        for key in QUERY_PARAMS:
            if key in self.params:
                out.append(f"param {key} = {self.params[key]:g}")
        return out


RESET_CAUSES = ("POWER_ON", "PIN", "SOFTWARE", "WATCHDOG", "BROWNOUT", "LOCKUP", "CLOCK")


def boot_report(d: dict) -> str:
    """The BOOT frame as one line."""
    cause = int(d["ResetCause"])
    names = [n for i, n in enumerate(RESET_CAUSES) if cause & (1 << i)] or [f"0x{cause:02X}"]
    status = protocol.name_of(protocol.record_statuses(), d["BootConfigStatus"])
    fault = f"HardFault at PC 0x{int(d['FaultPc']):08X}" if d["FaultRecord"] else "no fault record"
    return (f"reset {'|'.join(names)}, configuration "
            f"{'from the saved record' if d['ConfigFromRecord'] else 'defaults'} ({status}), "
            f"{fault}, protocol {d['ProtocolVersion']}")


# -------------------------------------------------------------------- plot
class Plot:
    """raw / filtered / ripple torque over the last window (matplotlib)."""

    def __init__(self, interactive: bool, title: str):
        import matplotlib
        if not interactive:
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        self.plt = plt
        if interactive:
            if matplotlib.get_backend().lower() in ("agg", "pdf", "svg", "ps", "cairo",
                                                    "template"):
                raise UsageError("--plot needs a display (no interactive matplotlib backend); "
                                 "use --plot-png FILE instead")
            plt.ion()
        self.fig, (self.ax, self.ax_r) = plt.subplots(
            2, 1, figsize=(12, 6.5), dpi=100, sharex=True, height_ratios=(3, 1.4))
        self.fig.suptitle(title)
        (self.l_raw,) = self.ax.plot([], [], lw=0.8, color="0.6", label="raw (TorqueRaw)")
        (self.l_filt,) = self.ax.plot([], [], lw=1.2, color="C0", label="filtered (TorqueFiltered)")
        (self.l_rip,) = self.ax_r.plot([], [], lw=1.0, color="C3", label="ripple removed (Ripple)")
        self.ax.set_ylabel("torque [N m]")
        self.ax_r.set_ylabel("ripple [N m]")
        self.ax_r.set_xlabel("device time [s] (telemetry sequence x period)")
        for a in (self.ax, self.ax_r):
            a.grid(True, alpha=0.3)
            a.legend(loc="upper left")
        self.fig.tight_layout()
        self.closed = False
        if interactive:
            self.fig.canvas.mpl_connect("close_event", self._closed)
            self.plt.show(block=False)

    def _closed(self, _event) -> None:
        self.closed = True

    def update(self, state: MonitorState) -> None:
        tr = state.trace
        if not tr["step"]:
            return
        period = state.period_s or 1e-3
        x = np.asarray(tr["step"], float) * period
        for line, key in ((self.l_raw, "raw"), (self.l_filt, "filt"), (self.l_rip, "ripple")):
            line.set_data(x, np.asarray(tr[key], float))
        for a in (self.ax, self.ax_r):
            a.relim()
            a.autoscale_view()

    def pump(self) -> None:
        self.fig.canvas.draw_idle()
        self.fig.canvas.flush_events()

    def save(self, path: str) -> None:
        from .safeio import Outputs
        with Outputs() as out:
            with out.path(path) as tmp:
                self.fig.savefig(tmp, format="png")
            out.commit()


# --------------------------------------------------------------------- run
class _Stop(Exception):
    pass


def _on_sigterm(signum, frame):
    raise _Stop()


def _query(bus, feed, node: int, say) -> None:
    joint = Joint(bus, node, timeout_s=0.3)
    joint.on_frame = feed
    for key in QUERY_PARAMS:
        try:
            joint.get(protocol.param_by_key(key))   # the answer reaches state through feed
        except NoAnswer:
            say(f"node {node}: no answer to GET_PARAM {key} (passive from here)")
            return


def run(args) -> int:
    if args.duration is not None and not args.duration > 0:
        raise UsageError("--duration must be a positive number of seconds")
    channel = args.channel_opt or args.channel
    if not channel:
        raise UsageError("give the CAN interface (e.g. can0) or --channel")
    out = sys.stdout
    tty = out.isatty()

    def say(line: str) -> None:
        out.write(("\r\x1b[K" if tty else "") + line + "\n")
        out.flush()

    state = MonitorState(args.node, args.bitrate, args.window, events=say)
    plot = None
    if args.plot or args.plot_png:
        plot = Plot(interactive=args.plot, title=f"hdsense monitor {channel}")
    bus = open_bus(args.interface, channel, args.bitrate)
    rx_buffer = grow_rx_buffer(bus)
    recorder = None
    from .rosio import cli as rosio_cli
    ros = None
    old_term = signal.getsignal(signal.SIGTERM)
    start = time.monotonic()
    try:
        if args.log:
            recorder = LogRecorder(args.log, channel)
        ros = rosio_cli.MonitorOutputs.open(args, say)
        state.listener = ros.listener if ros else None

        def feed(msg):
            if recorder is not None:
                recorder.write(msg)
            state.feed(msg)

        signal.signal(signal.SIGTERM, _on_sigterm)
        say(f"monitor: {args.interface} {channel}, node "
            f"{args.node if args.node is not None else '(first heard)'}"
            + (f", recording to {args.log}" if args.log else ""))
        next_status = start + args.interval
        next_plot = start
        queried = args.passive
        try:
            while True:
                now = time.monotonic()
                if args.duration is not None and now - start >= args.duration:
                    break
                if plot is not None and plot.closed:
                    break
                try:
                    msg = bus.recv(timeout=0.05)
                except can.CanError as exc:
                    raise BusError(f"{channel}: receive failed: {' '.join(str(exc).split())}") \
                        from None
                if msg is not None:
                    feed(msg)
                if not queried and state.node is not None:
                    queried = True
                    _query(bus, feed, state.node, say)
                    if ros:
                        ros.query(bus, feed, state.node, say)
                if now >= next_status:
                    next_status = now + args.interval
                    line = state.status_line(time.time())
                    if tty:
                        out.write("\r\x1b[K" + line)
                        out.flush()
                    elif not args.quiet:
                        say(line)
                if plot is not None and args.plot and now >= next_plot:
                    next_plot = now + 0.1
                    plot.update(state)
                    plot.pump()
                if recorder is not None and now - recorder.last_flush >= FLUSH_S:
                    recorder.flush()
        except (KeyboardInterrupt, _Stop):
            if tty:
                out.write("\n")
            say("monitor: stopped")
        if recorder is not None:
            recorder.close()
            recorder = None
        if ros:
            ros.close(state)
            ros = None
        if plot is not None and args.plot_png:
            plot.update(state)
            plot.save(args.plot_png)
    finally:
        signal.signal(signal.SIGTERM, old_term)
        if recorder is not None:
            recorder.abort()
        if ros:
            ros.abort()
        bus.shutdown()
    lines = state.summary(time.monotonic() - start)
    if rx_buffer is not None:
        lines.append(f"rx_buffer_bytes = {rx_buffer}")
    if args.log:
        lines.append(f"log = {args.log}")
    if args.plot_png:
        lines.append(f"plot = {args.plot_png}")
    lines += rosio_cli.summary_lines(args)
    out.write("\n".join(lines) + "\n")
    return 0


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (v > 0 and v < 1e9):
        raise argparse.ArgumentTypeError(f"{text} must be a positive number")
    return v


def add_bus_arguments(p, channel_optional: bool = False) -> None:
    if channel_optional:
        p.add_argument("channel", nargs="?", metavar="IFACE",
                       help="CAN channel, e.g. can0 (or --channel)")
        p.add_argument("--channel", dest="channel_opt", metavar="CHANNEL",
                       help="CAN channel (instead of IFACE)")
    else:
        p.add_argument("channel", metavar="IFACE", help="CAN channel, e.g. can0")
    p.add_argument("-i", "--interface", default="socketcan",
                   help="python-can interface (socketcan, pcan, kvaser, slcan, virtual, ...; "
                        "default socketcan)")
    p.add_argument("--bitrate", type=int, default=1000000,
                   help="bit rate in bit/s (opens non-SocketCAN adapters at it; bus load "
                        "is computed against it; default 1000000)")


def register(subparsers) -> None:
    from .cli import version
    p = subparsers.add_parser("monitor", help="watch a joint live on a CAN bus",
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"hdsense monitor {version()}")
    add_bus_arguments(p, channel_optional=True)
    p.add_argument("--node", type=_node, default=None,
                   help=f"node id {protocol.NODE_MIN}..{protocol.NODE_MAX} "
                        "(default: the first joint heard)")
    p.add_argument("--log", metavar="FILE", help="record every frame as a candump -l log")
    p.add_argument("--duration", type=_positive, default=None, metavar="S",
                   help="stop after S seconds (default: until Ctrl-C)")
    p.add_argument("--interval", type=_positive, default=0.5, metavar="S",
                   help="status line period (default 0.5 s)")
    p.add_argument("--window", type=_positive, default=5.0, metavar="S",
                   help="plot window (default 5 s)")
    p.add_argument("--plot", action="store_true", help="live torque plot (needs a display)")
    p.add_argument("--plot-png", metavar="FILE", help="write the torque plot here at the end")
    from .rosio import cli as rosio_cli
    rosio_cli.add_output_arguments(p, live=True)
    p.add_argument("--passive", action="store_true",
                   help="send nothing (no GET_PARAM queries at the start)")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no status lines when stdout is not a terminal (events and summary only)")
    p.set_defaults(func=run)
