"""`hdsense control`: one-off setpoints and a step test on a joint with a
drive (issue 23; the frames: docs/reference/protocol.md, "Control frames").

  hdsense control can0 set torque --torque 5 --hold 1
  hdsense control can0 set impedance --position 0.2 --kp 50 --kd 1
  hdsense control can0 set stop
  hdsense control can0 step --to 10 [--from 0] [--mode torque] [--csv step.csv]
  hdsense control can0 identify --condition clamped --out clamped.json  (hdtools.cmd_tune)

set: GAINS first when --kp or --kd is given, then the setpoint, streamed at
--rate for --hold seconds (0: sent once); prints the joint's CTRL_STATE
that answers the last one, and its filtered torque.  A setpoint lasts only
while it is streamed: once the tool stops, the joint's watchdog runs DAMP
after ctrl_watchdog_ms and STOP after ctrl_damp_ms more (docs/design/firmware.md).

step: streams --from for --before seconds, then --to for --after seconds,
recording CTRL_STATE and the telemetry (TELEM_A) the joint sends; t = 0 is
the first CTRL_STATE carrying the step's sequence number, in the joint's
time stamps.  Reports the step response of the joint's filtered torque:
the value before the step and its final value (means over the last fifth
of each phase), rise time (10 % to 90 % of the measured step), overshoot
beyond the final value (% of the step), settling time (from t = 0 until
it stays within --band of the final value; default 2 % of the step), and
the last torque reference and current command.  --csv FILE writes the
record (t_s, setpoint_nm, torque_ref_nm, current_a, mode_run, limits,
torque_filtered_nm, torque_raw_nm), whole or not at all.

Exit status: 0 done; 1 the joint refused a setpoint or the gains (its ACK
SETPOINT_REFUSED names the result); 2 bad command line (a value not
finite or outside the frame's range, an unknown mode); 3 the CSV could not
be written; 5 the CAN interface cannot be used or the joint did not answer
(no CTRL_STATE within --timeout: not a joint with a drive on this node).
"""
from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass

import can

from . import protocol, safeio
from .cmd_calib import _finite    # a finite float, or argparse's one-line error
from .canshared import add_bus_arguments, node_id as _node
# The names where the firmware defines them (monitor_state reads control/hd_ctrl.h
# and hd_can_proto.h; the protocol schema does not carry them yet).
from .monitor_state import CTRL_FLAGS, CTRL_LIMITS, CTRL_MODE_NAMES as MODES, bit_names
from .joint import BusError, Joint, NoAnswer, open_bus
from .safeio import HdError, UsageError

SIGNAL_OF = {"torque": "SpTorque", "position": "SpPosition", "velocity": "SpVelocity",
             "kp": "GainKp", "kd": "GainKd"}
CSV_COLUMNS = ("t_s", "setpoint_nm", "torque_ref_nm", "current_a", "mode_run", "limits",
               "torque_filtered_nm", "torque_raw_nm")


class Refused(HdError):
    code = 1


# ------------------------------------------------------------ the joint
@dataclass
class Record:
    """One received frame that matters: a CTRL_STATE (state set) or a
    TELEM_A (torque set), in the joint's time."""
    t_s: float
    state: dict | None = None
    torque_filtered_nm: float = math.nan
    torque_raw_nm: float = math.nan


class Controller:
    """Sends SETPOINT / GAINS frames to one node (encoded with the DBC) and
    collects what the joint answers."""

    def __init__(self, bus: can.BusABC, node: int, timeout_s: float):
        from . import canproto
        self.bus, self.node, self.timeout_s = bus, node, timeout_s
        self.db = canproto.load_db(node)
        self.msg = {n: self.db.get_message_by_name(n)
                    for n in ("SETPOINT", "GAINS", "CTRL_STATE", "TELEM_A", "ACK")}
        self.refused_op = protocol.by_name(protocol.opcodes(), "SETPOINT_REFUSED").code
        self.seq = 0
        self.records: list[Record] = []
        self.on_frame = None        # sees every frame received (hdsense control identify)

    def _send(self, name: str, signals: dict) -> None:
        m = self.msg[name]
        msg = can.Message(arbitration_id=m.frame_id, is_extended_id=True,
                          data=m.encode(signals, strict=True))
        try:
            self.bus.send(msg, timeout=self.timeout_s)
        except can.CanError as exc:
            raise BusError(f"node {self.node}: send failed: {' '.join(str(exc).split())}") \
                from None

    def gains(self, kp: float, kd: float) -> None:
        self._send("GAINS", {"GainKp": kp, "GainKd": kd})

    def setpoint(self, mode: int, torque: float, position: float, velocity: float) -> int:
        self.seq = (self.seq + 1) % 256
        self._send("SETPOINT", {"SpMode": mode, "SpSeq": self.seq, "SpTorque": torque,
                                "SpPosition": position, "SpVelocity": velocity})
        return self.seq

    def listen(self, until: float) -> None:
        """Takes frames until the monotonic time `until`."""
        while (left := until - time.monotonic()) > 0:
            try:
                msg = self.bus.recv(timeout=left)
            except can.CanError as exc:
                raise BusError(f"receive failed: {' '.join(str(exc).split())}") from None
            if msg is None:
                return
            if self.on_frame is not None:
                self.on_frame(msg)
            if (msg.is_extended_id and not msg.is_error_frame and not msg.is_remote_frame
                    and not msg.is_fd and len(msg.data) == 8):
                self._take(msg)

    def _take(self, msg: can.Message) -> None:
        ident, data = msg.arbitration_id, bytes(msg.data)
        if ident == self.msg["CTRL_STATE"].frame_id:
            d = self.msg["CTRL_STATE"].decode(data, decode_choices=False)
            self.records.append(Record(msg.timestamp, state=d))
        elif ident == self.msg["TELEM_A"].frame_id:
            d = self.msg["TELEM_A"].decode(data, decode_choices=False)
            from .canproto import torque_valid
            ok = torque_valid(d)
            self.records.append(Record(msg.timestamp,
                                       torque_filtered_nm=d["TorqueFiltered"] if ok else math.nan,
                                       torque_raw_nm=d["TorqueRaw"] if ok else math.nan))
        elif ident == self.msg["ACK"].frame_id:
            d = self.msg["ACK"].decode(data, decode_choices=False)
            if d["AckOpcode"] == self.refused_op:
                what = "GAINS" if d["AckAux"] == 1 else f"SETPOINT seq {d['AckToken']}"
                result = protocol.name_of(protocol.results(), d["AckResult"])
                raise Refused(f"node {self.node}: {what} refused ({result})")

    def stream(self, sp: tuple, seconds: float, rate_hz: float) -> int:
        """Sends sp every 1 / rate_hz for `seconds` (at least once); returns
        the last sequence number sent."""
        period = 1.0 / rate_hz
        start = time.monotonic()
        n = 0
        while True:
            seq = self.setpoint(*sp)
            n += 1
            due = start + n * period
            if n * period >= seconds:
                self.listen(due)
                return seq
            self.listen(due)

    def wait_state(self, seq: int) -> Record:
        """The first CTRL_STATE carrying seq (NoAnswer after the timeout)."""
        deadline = time.monotonic() + self.timeout_s
        while True:
            for r in reversed(self.records):
                if r.state is not None and int(r.state["CtrlSeq"]) == seq:
                    return r
            if time.monotonic() >= deadline:
                raise NoAnswer(f"node {self.node}: no CTRL_STATE within {self.timeout_s:g} s "
                               "(is a joint with a drive on this bus, with this node id?)")
            self.listen(min(deadline, time.monotonic() + 0.01))


# -------------------------------------------------------- step metrics
def _mean_tail(t: list[float], y: list[float], t_from: float, t_to: float) -> float:
    vals = [v for tt, v in zip(t, y) if t_from <= tt <= t_to and math.isfinite(v)]
    return sum(vals) / len(vals) if vals else math.nan


def step_metrics(t: list[float], y: list[float], t0: float, t_end: float, before_s: float,
                 band: float | None) -> dict[str, float | None]:
    """The step response of y(t) (a step at t0, recorded until t_end):
    initial and final values (means over the last fifth of each phase),
    rise time 10-90 %, overshoot beyond the final value in % of the step,
    settling time within band (None: 2 % of the step) of the final value
    (None if it never stays there)."""
    after_s = t_end - t0
    y0 = _mean_tail(t, y, t0 - 0.2 * before_s, t0)
    y1 = _mean_tail(t, y, t_end - 0.2 * after_s, t_end)
    step = y1 - y0
    if not (math.isfinite(step) and step != 0.0):
        raise Refused("no step in the recorded torque (no telemetry, or the joint did not "
                      "follow)")
    band = abs(step) * 0.02 if band is None else band
    after = [(tt - t0, v) for tt, v in zip(t, y) if tt >= t0 and math.isfinite(v)]
    t10 = next((tt for tt, v in after if (v - y0) / step >= 0.1), None)
    t90 = next((tt for tt, v in after if (v - y0) / step >= 0.9), None)
    peak = max(((v - y0) / step for _, v in after), default=math.nan)
    settle: float | None = 0.0
    for i, (tt, v) in enumerate(after):
        if abs(v - y1) > band:     # settled from the next sample on, if any
            settle = after[i + 1][0] if i + 1 < len(after) else None
    if settle is not None and settle >= 0.8 * after_s:
        settle = None              # still leaving the band in the final-value window
    return {"initial_nm": y0, "final_nm": y1,
            "rise_time_s": t90 - t10 if t10 is not None and t90 is not None else None,
            "overshoot_pct": max(0.0, (peak - 1.0) * 100.0), "settling_time_s": settle,
            "band_nm": band}


# ------------------------------------------------------------- commands
def _ranged(lo: float, hi: float, what: str):
    def parse(text: str) -> float:
        v = _finite(text)
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{what} must be {lo:g}..{hi:g}, got {v:g}")
        return v
    return parse


def _mode(text: str) -> int:
    name = text.upper().replace("-", "_")
    if name not in MODES:
        raise argparse.ArgumentTypeError(
            f"unknown mode {text!r} ({', '.join(m.lower() for m in MODES)})")
    return MODES.index(name)


def check_ranges(args, db) -> None:
    """Every value within its frame field's range (the DBC's), before any
    bus is opened."""
    sigs = {s.name: s for m in ("SETPOINT", "GAINS") for s in db.get_message_by_name(m).signals}
    for opt, sig in SIGNAL_OF.items():
        for attr in (opt, f"{opt}_from", f"{opt}_to"):
            v = getattr(args, attr, None)
            if v is None:
                continue
            lo, hi = sigs[sig].minimum, sigs[sig].maximum
            if not lo <= v <= hi:
                flag = "--" + attr.replace("_", "-").replace("torque-", "")
                raise UsageError(f"{flag} {v:g} outside the frame's range {lo:g}..{hi:g} "
                                 f"({sigs[sig].unit or 'no unit'})")


def mode_name(code) -> str:
    return MODES[int(code)] if 0 <= int(code) < len(MODES) else str(int(code))


def _state_lines(r: Record, torque: Record | None) -> list[str]:
    st = r.state
    lines = [f"mode_asked = {mode_name(st['CtrlModeAsked'])}",
             f"mode_run = {mode_name(st['CtrlModeRun'])}",
             f"limits = {bit_names(int(st['CtrlLimits']), CTRL_LIMITS)}",
             f"flags = {bit_names(int(st['CtrlFlags']), CTRL_FLAGS)}",
             f"torque_ref_nm = {st['CtrlTorqueRef']:.2f}",
             f"current_a = {st['CtrlCurrent']:.3f}"]
    if torque is not None:
        lines.append(f"torque_filtered_nm = {torque.torque_filtered_nm:.3f}")
    return lines


def _last_torque(records: list[Record]) -> Record | None:
    return next((r for r in reversed(records) if r.state is None), None)


def _open(args) -> tuple[can.BusABC, Controller]:
    bus = open_bus(args.interface, args.channel, args.bitrate)
    return bus, Controller(bus, args.node, args.timeout)


def cmd_set(args) -> list[str]:
    from . import canproto
    check_ranges(args, canproto.load_db(args.node))
    bus, c = _open(args)
    try:
        if args.kp is not None or args.kd is not None:
            c.gains(args.kp or 0.0, args.kd or 0.0)
        sp = (args.mode, args.torque or 0.0, args.position or 0.0, args.velocity or 0.0)
        seq = c.stream(sp, args.hold, args.rate)
        r = c.wait_state(seq)
        c.listen(time.monotonic() + 0.005)   # the telemetry of that tick, refusals
        return ([f"setpoint = {MODES[args.mode]} torque {sp[1]:g} N m, position {sp[2]:g} rad, "
                 f"velocity {sp[3]:g} rad/s (last seq {seq})"] +
                _state_lines(r, _last_torque(c.records)))
    finally:
        bus.shutdown()


def cmd_step(args) -> list[str]:
    from . import canproto
    if MODES[args.mode] not in ("TORQUE", "IMPEDANCE"):
        raise UsageError(f"step --mode {MODES[args.mode].lower()}: a torque step needs torque "
                         "or impedance")
    check_ranges(args, canproto.load_db(args.node))
    band = args.band
    bus, c = _open(args)
    try:
        if args.kp is not None or args.kd is not None:   # else the joint's latched gains
            c.gains(args.kp or 0.0, args.kd or 0.0)
        before = (args.mode, args.torque_from, args.position, 0.0)
        after = (args.mode, args.torque_to, args.position, 0.0)
        last_before = c.stream(before, args.before, args.rate)
        c.wait_state(last_before)
        mark = len(c.records)
        t_end = c.wait_state(c.stream(after, args.after, args.rate)).t_s
    finally:
        bus.shutdown()
    # the step took effect at the first CTRL_STATE echoing another sequence
    t0 = next(r.t_s for r in c.records[mark:]
              if r.state is not None and int(r.state["CtrlSeq"]) != last_before)
    rows, t, y = [], [], []
    sp = args.torque_from
    state = None
    for r in c.records:
        if r.state is not None:
            state = r.state
            sp = args.torque_to if r.t_s >= t0 else args.torque_from
            continue
        if state is None:
            continue
        t.append(r.t_s - t0)
        y.append(r.torque_filtered_nm)
        rows.append((r.t_s - t0, sp, state["CtrlTorqueRef"], state["CtrlCurrent"],
                     mode_name(state["CtrlModeRun"]), int(state["CtrlLimits"]),
                     r.torque_filtered_nm, r.torque_raw_nm))
    m = step_metrics(t, y, 0.0, t_end - t0, args.before, band)
    if args.csv:
        text = ",".join(CSV_COLUMNS) + "\n" + "".join(
            f"{row[0]:.6f},{row[1]:.4f},{row[2]:.3f},{row[3]:.4f},{row[4]},{row[5]},"
            f"{row[6]:.4f},{row[7]:.4f}\n" for row in rows)
        with safeio.Outputs() as out:
            out.write_text(args.csv, text)
            out.commit()
    fmt = lambda v, f: "none" if v is None else format(v, f)  # noqa: E731
    last_state = next(r.state for r in reversed(c.records) if r.state is not None)
    return [f"step = {MODES[args.mode]} {args.torque_from:g} -> {args.torque_to:g} N m "
            f"({args.before:g} s + {args.after:g} s at {args.rate:g} Hz)",
            f"samples = {len(t)}",
            f"initial_nm = {m['initial_nm']:.3f}",
            f"final_nm = {m['final_nm']:.3f}",
            f"final_error_nm = {m['final_nm'] - args.torque_to:.3f}",
            f"rise_time_s = {fmt(m['rise_time_s'], '.4f')}",
            f"overshoot_pct = {m['overshoot_pct']:.1f}",
            f"settling_time_s = {fmt(m['settling_time_s'], '.4f')}",
            f"band_nm = {m['band_nm']:.3f}",
            f"torque_ref_nm = {last_state['CtrlTorqueRef']:.2f}",
            f"current_a = {last_state['CtrlCurrent']:.3f}"] + (
            [f"csv = {args.csv}"] if args.csv else [])


def cmd_identify(args) -> list[str]:
    """An identification run in one condition (hdtools.cmd_tune, which
    says what it measures); the measurement to --out."""
    import json
    from . import canproto, cmd_tune
    db = canproto.load_db(args.node)
    sig = {s.name: s for s in db.get_message_by_name("CMD").signals}
    for name, v, flag in (("IdentRms", args.rms, "--rms"),
                          ("IdentPeriods", args.periods, "--periods")):
        if not sig[name].minimum <= v <= sig[name].maximum:
            raise UsageError(f"{flag} {v:g} outside {sig[name].minimum:g}..{sig[name].maximum:g}")
    check_ranges(args, db)
    bus, c = _open(args)
    try:
        result, rows = cmd_tune.measure(c, Joint(bus, args.node, args.timeout), args.condition,
                                        args.torque, args.rms, args.periods, args.settle,
                                        args.rate)
        c.stream((MODES.index("STOP"), 0.0, 0.0, 0.0), 0.0, args.rate)   # the run is over
    finally:
        bus.shutdown()
    with safeio.Outputs() as out:
        out.write_text(args.out, json.dumps(result, indent=1) + "\n")
        out.commit()
    return [f"condition = {args.condition} ({result['mode']}, {result['torque_nm']:g} N m)",
            f"ticks = {len(rows)}",
            f"excitation = {args.rms:g} A rms, {result['peak_a']:.3f} A peak",
            "gains = kp {kp:.3g}, ki {ki_per_s:.3g}/s, kd {kd_s:.3g} s, ff {ff:.3g}".format(
                **result["joint"]),
            f"margins = {cmd_tune.margin_text(result['margins'])}",
            f"out = {args.out}"]


def run(args) -> int:
    act = {"set": cmd_set, "step": cmd_step, "identify": cmd_identify}[args.action]
    lines = act(args)
    print("\n".join(lines))
    return 0


def register(subparsers) -> None:
    from .cli import version
    p = subparsers.add_parser("control", help="one-off setpoints and a step test (a joint "
                              "with a drive)", description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"hdsense control {version()}")
    add_bus_arguments(p)
    p.add_argument("--node", type=_node, default=1, help="node id (default 1)")
    p.add_argument("--timeout", type=_ranged(0.01, 60.0, "--timeout"), default=0.5, metavar="S",
                   help="wait this long for the joint's CTRL_STATE (default 0.5 s)")
    p.add_argument("--rate", type=_ranged(20.0, 1000.0, "--rate"), default=200.0, metavar="HZ",
                   help="setpoints per second while streaming (20..1000, default 200)")
    acts = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    s = acts.add_parser("set", help="one setpoint (streamed for --hold seconds)")
    s.add_argument("mode", type=_mode, help=", ".join(m.lower() for m in MODES))
    s.add_argument("--torque", type=_finite, help="N m (TORQUE; IMPEDANCE feed-forward)")
    s.add_argument("--position", type=_finite, help="rad (IMPEDANCE)")
    s.add_argument("--velocity", type=_finite, help="rad/s (IMPEDANCE)")
    s.add_argument("--kp", type=_finite, help="N m/rad (IMPEDANCE; sends GAINS)")
    s.add_argument("--kd", type=_finite, help="N m s/rad (IMPEDANCE; sends GAINS)")
    s.add_argument("--hold", type=_ranged(0.0, 600.0, "--hold"), default=0.0, metavar="S",
                   help="stream it this long (default 0: once)")
    st = acts.add_parser("step", help="a torque step: rise, overshoot, settling")
    st.add_argument("--mode", type=_mode, default=MODES.index("TORQUE"),
                    help="torque (default) or impedance (the step is its feed-forward)")
    st.add_argument("--from", dest="torque_from", type=_finite, default=0.0, metavar="NM",
                    help="torque before the step (default 0)")
    st.add_argument("--to", dest="torque_to", type=_finite, required=True, metavar="NM",
                    help="torque after the step")
    st.add_argument("--position", type=_finite, default=0.0, help="rad (IMPEDANCE)")
    st.add_argument("--kp", type=_finite, help="N m/rad (IMPEDANCE)")
    st.add_argument("--kd", type=_finite, help="N m s/rad (IMPEDANCE)")
    st.add_argument("--before", type=_ranged(0.05, 60.0, "--before"), default=0.3, metavar="S",
                    help="seconds at --from (default 0.3)")
    st.add_argument("--after", type=_ranged(0.05, 60.0, "--after"), default=0.7, metavar="S",
                    help="seconds at --to (default 0.7)")
    st.add_argument("--band", type=_ranged(1e-6, 1e3, "--band"), metavar="NM",
                    help="settling band (default 2 %% of the step)")
    st.add_argument("--csv", metavar="FILE", help="write the record")
    from .cmd_tune import CONDITIONS
    from .torque_loop import MS_RMS_A
    i = acts.add_parser("identify", help="measure the torque loop in one condition (an "
                        "identification run; `hdsense tune --help`)")
    i.add_argument("--condition", required=True, choices=sorted(CONDITIONS),
                   help="how the output is held: clamped, against a stiff wall, free")
    i.add_argument("--torque", type=_finite, default=10.0, metavar="NM",
                   help="TORQUE setpoint while clamped or on the wall (default 10)")
    i.add_argument("--rms", type=_finite, default=MS_RMS_A, metavar="A",
                   help=f"the excitation's rms current (default {MS_RMS_A:g})")
    i.add_argument("--periods", type=int, default=3, help="periods of 2 s measured (default 3)")
    i.add_argument("--settle", type=_ranged(0.0, 60.0, "--settle"), default=1.0, metavar="S",
                   help="seconds held before the run (default 1)")
    i.add_argument("--out", required=True, metavar="FILE", help="the measurement (JSON)")
    p.set_defaults(func=run)
