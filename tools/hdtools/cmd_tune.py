"""`hdsense control identify` and `hdsense tune`: the torque loop's
tuning method (docs/results/control.md, "Tuning") on a joint itself, over
its bus (docs/how-to/tune-torque-loop.md).

  hdsense control can0 identify --condition clamped --out clamped.json
  hdsense control can0 identify --condition wall --out wall.json
  hdsense control can0 identify --condition free --out free.json
  hdsense tune clamped.json wall.json free.json

identify: holds the joint in TORQUE at --torque (clamped, wall) or in
ZERO_TORQUE (free), streaming setpoints at --rate, lets it settle, starts an
identification run (IDENT_START: the firmware adds a periodic multisine of
--rms amperes to the law's current command for --periods periods after one
to settle) and records every tick's IDENT frame.  From them
(hdtools.torque_loop): the loop broken at the drive's input, L = -CMD / X,
its phase and gain margins, and the plant the law sees, P = FB / X / (N kt),
with the gains, gear ratio and torque constant the joint reports.  The
condition is the user's to make: the output clamped to the frame, pressed
against a stiff stop, or free to turn; the tool cannot see which.  A joint that turns during the run (its mean
motor speed from the telemetry) has the excited lines near its ripple
orders dropped, as the benchmark does.  --out
writes the measurement (JSON), whole or not at all.

tune: the method's search (predicted margins >= 45 deg and 6 dB and a
tracking peak <= 10 dB in every condition given; the free output on the
margins alone) over the plants of the files, ranked by crossover; prints
the best gains, as the parameter table holds them, with their predicted
margins, and the next --next candidates of the ranking; --config FILE
writes the gains as configuration text for `hdsense send`.  What it cannot do from files: measure the chosen loop again and
run the wall contact (the method's step 4); run identify again with the new
gains for the measured margins.

Exit status: 0 done; 1 the joint refused the run or a setpoint, the run
stopped early (a mode change, the current limit) or frames were lost, no
gains on the grid meet the margins; 2 bad command line or input file; 3 an
output could not be written; 5 the CAN interface cannot be used or the
joint did not answer.
"""
from __future__ import annotations

import json
import math
import time

import numpy as np

from . import protocol, safeio, torque_loop as tl
from .joint import Joint
from .monitor_state import CTRL_MODE_NAMES as MODES
from .safeio import HdError, UsageError

CONDITIONS = {"clamped": "TORQUE", "wall": "TORQUE", "free": "ZERO_TORQUE"}
STATUS = {1: "done", 2: "stopped: the mode changed (a fault reaction, the watchdog) or the "
          "drive is off", 3: "stopped: the excitation would have crossed ctrl_current_limit_a "
          "(lower --rms or --torque)"}
PARAMS = {"kp": "ctrl_torque_kp", "ki_per_s": "ctrl_torque_ki_per_s", "kd_s": "ctrl_torque_kd_s",
          "ff": "ctrl_torque_ff", "kt_nm_per_a": "ctrl_kt_nm_per_a", "gear_ratio": "gear_ratio"}
FORMAT = "hdsense-identify-1"


class RunFailed(HdError):
    code = 1


# ------------------------------------------------------------ identify
class _Record:
    """The IDENT frames of one run, in order (every frame seen on the bus
    goes through take)."""

    def __init__(self, db):
        self.msg = db.get_message_by_name("IDENT")
        self.telem_b = db.get_message_by_name("TELEM_B")
        self.rows: list[tuple[float, float, float, int]] = []
        self.motor_speeds: list[float] = []     # TELEM_B's, during the run
        self.status = 0

    def take(self, msg) -> None:
        if len(msg.data) != 8 or self.status:
            return
        if msg.arbitration_id == self.telem_b.frame_id and self.rows:
            self.motor_speeds.append(float(self.telem_b.decode(
                bytes(msg.data), decode_choices=False)["MotorVelocity"]))
            return
        if msg.arbitration_id != self.msg.frame_id:
            return
        d = self.msg.decode(bytes(msg.data), decode_choices=False)
        self.rows.append((d["IdentCmd"], d["IdentDrive"], d["IdentFeedback"],
                          int(d["IdentTick"])))
        self.status = int(d["IdentStatus"])


def _joint_values(joint: Joint) -> dict:
    out = {}
    for key, name in PARAMS.items():
        ack = joint.get(protocol.param_by_key(name))
        if not ack.ok:
            raise RunFailed(f"node {joint.node}: GET_PARAM {name} refused ({ack.result})")
        out[key] = float(ack.value)
    return out


def _check_record(rec: _Record, expected: int) -> None:
    if rec.status != 1:
        why = STATUS.get(rec.status, "no end of the run within the time it takes")
        raise RunFailed(f"the identification run {why}, after {len(rec.rows)} of "
                        f"{expected} ticks")
    ticks = np.array([r[3] for r in rec.rows])
    gaps = int(np.count_nonzero(np.diff(ticks) % 256 != 1)) + (ticks[0] != 0)
    if len(rec.rows) != expected or gaps:
        raise RunFailed(f"{expected - len(rec.rows)} of {expected} IDENT frames lost on the bus "
                        f"({gaps} gaps): the analysis needs every tick; lower the bus load")


def measure(ctl, joint: Joint, condition: str, torque_nm: float, rms_a: float, periods: int,
            settle_s: float, rate_hz: float) -> tuple[dict, list]:
    """One identification run on the joint (ctl: cmd_control.Controller on
    the same bus): the measurement as --out writes it, and the run's
    (law's current, drive's current, feedback torque, tick) per tick."""
    values = _joint_values(joint)
    mode = MODES.index(CONDITIONS[condition])
    sp = (mode, torque_nm if mode == MODES.index("TORQUE") else 0.0, 0.0, 0.0)
    rec = _Record(joint.db)
    ctl.on_frame = joint.on_frame = rec.take
    ctl.stream(sp, settle_s, rate_hz)
    ack = joint.command("IDENT_START", IdentPeriods=periods, IdentRms=rms_a)
    if not ack.ok:
        raise RunFailed(f"node {joint.node}: IDENT_START refused ({ack.result}; the "
                        f"excitation's peak {ack.value:.3g} A)")
    expected = (periods + 1) * tl.MS_PERIOD
    deadline = time.monotonic() + expected * tl.TS_S * 3 + 2.0   # a slow host's margin
    while not rec.status and time.monotonic() < deadline:
        ctl.stream(sp, 0.05, rate_hz)
    _check_record(rec, expected)
    cmd, drive, fb, _ = (np.array(c) for c in zip(*rec.rows))
    nkt = values["gear_ratio"] * values["kt_nm_per_a"]
    f, loop, plant = tl.loop_response(cmd, drive, fb, nkt)
    # a joint that turns puts its ripple lines on some of the excited ones
    speed = float(np.mean(rec.motor_speeds)) if rec.motor_speeds else 0.0
    keep = tl.off_the_ripple(f, speed)
    f, loop, plant = f[keep], loop[keep], plant[keep]
    m = tl.margins(f, loop)
    return ({"format": FORMAT, "condition": condition, "mode": CONDITIONS[condition],
            "torque_nm": sp[1], "rms_a": rms_a, "peak_a": float(ack.value), "periods": periods,
            "motor_speed_rad_s": speed, "lines_dropped": int(np.count_nonzero(~keep)),
            "joint": values, "freq_hz": f.tolist(),
            "loop": [loop.real.tolist(), loop.imag.tolist()],
            "plant": [plant.real.tolist(), plant.imag.tolist()],
            "margins": {k: (None if v is None or not math.isfinite(v) else v)
                        for k, v in m.items()}}, rec.rows)


def _fmt(v, spec: str, unit: str = "") -> str:
    return "none" if v is None or not math.isfinite(v) else f"{v:{spec}}{unit}"


def margin_text(m: dict) -> str:
    return (f"phase margin {_fmt(m['pm_deg'], '.0f', ' deg')}, gain margin "
            f"{_fmt(m['gm_db'], '.1f', ' dB')}, crossover {_fmt(m['crossover_hz'], '.1f', ' Hz')}")


# ----------------------------------------------------------------- tune
def load(path: str) -> dict:
    """A measurement written by identify (UsageError if it is not one)."""
    try:
        d = json.loads(safeio.read_text(path).removeprefix("\ufeff"))     # a BOM is not content
        if d.get("format") != FORMAT or d.get("condition") not in CONDITIONS:
            raise ValueError("not an identify measurement")
        f = np.array(d["freq_hz"], dtype=float)
        p = np.array(d["plant"][0], dtype=float) + 1j * np.array(d["plant"][1], dtype=float)
        if f.ndim != 1 or p.shape != f.shape or len(f) < 4 or not np.all(np.isfinite(p)) \
                or not np.all(np.diff(f) > 0):
            raise ValueError("frequencies and plant do not match")
        ff = float(d["joint"]["ff"])
    except (ValueError, KeyError, TypeError, IndexError) as exc:
        raise UsageError(f"{path}: {' '.join(str(exc).split())}") from None
    return {"condition": d["condition"], "freq_hz": f, "plant": p, "ff": ff}


def cmd_tune(args) -> list[str]:
    ms = [load(p) for p in args.files]
    conds = [m["condition"] for m in ms]
    if len(set(conds)) != len(conds):
        raise UsageError(f"one measurement per condition, got {', '.join(conds)}")
    if len({m["ff"] for m in ms}) != 1:
        raise UsageError("the measurements were made with different ctrl_torque_ff")
    # a test on the joint sees no true torque: the tracking it predicts is
    # of the feedback (hdmaint.bench.control_autotune, the same choice)
    plants = [tl.PlantAt(m["condition"], m["freq_hz"], m["plant"], m["plant"]) for m in ms]
    found = tl.candidates(plants, ms[0]["ff"])
    if not found:
        raise RunFailed("no gains on the grid meet the margins in every condition given")
    kp, ki, kd, pred = found[0]
    lines = [f"conditions = {', '.join(conds)}", f"candidates = {len(found)}",
             f"ctrl_torque_kp = {kp:.3g}", f"ctrl_torque_ki_per_s = {ki:.3g}",
             f"ctrl_torque_kd_s = {kd:.3g}"]
    for c in conds:
        m, bw = pred[c]["margins"], pred[c]["bandwidth_hz"]
        lines.append(f"predicted_{c} = {margin_text(m)}, tracking peak "
                     f"{m['peak_db']:.1f} dB, bandwidth {_fmt(bw, '.1f', ' Hz')}")
    # the next ones down the ranking: step 4 by hand, where the first fails
    lines += [f"next_{i} = kp {c[0]:.3g}, ki {c[1]:.3g}/s, kd {c[2]:.3g} s"
              for i, c in enumerate(found[1:1 + args.next], start=1)]
    if args.config:
        with safeio.Outputs() as out:
            out.write_text(args.config, f"# hdsense tune {' '.join(args.files)}\n"
                           + "".join(f"{ln}\n" for ln in lines[2:5]))
            out.commit()
        lines.append(f"config = {args.config}")
    return lines


def register(sub) -> None:
    import argparse
    p = sub.add_parser("tune", help="the torque loop's gains from `hdsense control identify` "
                       "measurements", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("files", nargs="+", metavar="FILE", help="identify --out files, one per "
                   "condition")
    p.add_argument("--next", type=int, default=3, choices=range(0, 21), metavar="N",
                   help="also print the next N candidates of the ranking (0..20, default 3): "
                   "the ones to try where the first misses a margin when measured")
    p.add_argument("--config", metavar="FILE", help="also write the gains as configuration "
                   "text (`hdsense send IFACE FILE` applies, saves and reads them back)")
    p.set_defaults(func=lambda args: print("\n".join(cmd_tune(args))) or 0)
