"""The demo's closed-loop part (tools/demo 4/4): the firmware's control
stage on the dynamic joint with a drive (the emulator of hd_emu.c, driven
tick by tick with the frames a host would send), judged by the simulation's
truth.

  1. the output free, a person moving it back and forth (a stiff velocity
     servo on the output: the torque it needs is the person's) with the
     drive off (STOP): the baseline, what the person pays for the drive
     train without the loop (and the motion the filter learns the gauge's
     ripple lines from);
  2. the same back-driving with the joint in ZERO_TORQUE: the back-driven
     zero-torque stretch;
  3. a torque step: TORQUE 0 -> STEP_NM against a spring (a joint pressing
     on a compliant environment), the output at rest before it.

The firmware is told its own defaults and the gauge's nominal calibration,
never the plant.  Writes DIR/control_samples.csv, DIR/control.png,
DIR/control_summary.txt (key = value) and DIR/control.json (the same, with
the tool's name), all or none.

  python -m hdtools.demo_control OUT_DIR
"""
from __future__ import annotations

import argparse
import json
import math
import sys

import can

from . import canproto, emu, safeio
from .cmd_control import MODES, step_metrics

STEP_NM = 10.0
SPRING_NM_RAD, SPRING_DAMPING_NM_S_RAD = 300.0, 5.0
PERSON_GAIN_NM_S_RAD = 50.0      # the person's servo on the output speed
PERSON_SPEED_RAD_S = 1.0         # amplitude of the back-and-forth
PERSON_PERIOD_S = 2.0
# phases [s]: (name, start, end)
PHASES = (("stop", 0.0, 4.0), ("zero_torque", 4.0, 8.0), ("rest", 8.0, 8.5),
          ("step", 8.5, 10.0))
SETTLE_S = 0.5                   # each back-driven phase: the first 0.5 s are not scored
COLUMNS = ("t_s", "phase", "mode_run", "torque_cmd_nm", "torque_true_nm", "torque_filtered_nm",
           "person_torque_nm", "output_velocity_rad_s")


def _phase(t: float) -> str:
    return next(name for name, a, b in PHASES if a <= t < b)


def run() -> list[tuple]:
    """One sample per tick: the COLUMNS."""
    db = canproto.load_db(1)
    sp_msg = db.get_message_by_name("SETPOINT")
    state_id = db.get_message_by_name("CTRL_STATE").frame_id
    telem_id = db.get_message_by_name("TELEM_A").frame_id
    state_msg, telem_msg = db.get_message_by_name("CTRL_STATE"), db.get_message_by_name("TELEM_A")
    rows = []
    end_s = PHASES[-1][2]
    with emu.Emulator(dynamic=True) as joint:
        cmd, filtered, mode = 0.0, math.nan, "STOP"
        for k in range(int(round(end_s * 1000))):
            t = k * 1e-3
            phase = _phase(t)
            back_driven = phase in ("zero_torque", "stop")
            if back_driven:
                v_goal = PERSON_SPEED_RAD_S * math.sin(2 * math.pi * t / PERSON_PERIOD_S)
                truth = joint.truth()
                person = PERSON_GAIN_NM_S_RAD * (v_goal - truth.output_velocity_rad_s)
                joint.set_environment(0.0, 0.0, person)
            else:
                joint.set_environment(SPRING_NM_RAD, SPRING_DAMPING_NM_S_RAD, 0.0)
            sp_mode = {"rest": "TORQUE", "step": "TORQUE", "zero_torque": "ZERO_TORQUE",
                       "stop": "STOP"}[phase]
            torque = STEP_NM if phase == "step" else 0.0
            data = sp_msg.encode({"SpMode": MODES.index(sp_mode), "SpSeq": k % 256,
                                  "SpTorque": torque, "SpPosition": 0.0, "SpVelocity": 0.0})
            joint.push(can.Message(arbitration_id=sp_msg.frame_id, is_extended_id=True,
                                   data=data))
            joint.tick(1)
            for m in joint.pop_all():
                if m.arbitration_id == state_id:
                    st = state_msg.decode(bytes(m.data), decode_choices=False)
                    cmd = st["CtrlTorqueRef"]
                    mode = MODES[st["CtrlModeRun"]]
                elif m.arbitration_id == telem_id:
                    d = telem_msg.decode(bytes(m.data), decode_choices=False)
                    filtered = d["TorqueFiltered"] if canproto.torque_valid(d) else math.nan
            tr = joint.truth()
            rows.append((t + 1e-3, phase, mode, cmd, tr.output_torque_nm, filtered,
                         tr.person_torque_nm, tr.output_velocity_rad_s))
    return rows


def _rms(xs: list[float]) -> float:
    return math.sqrt(sum(x * x for x in xs) / len(xs))


def summarize(rows: list[tuple]) -> dict[str, str]:
    t = [r[0] for r in rows]
    true = [r[4] for r in rows]
    step = next(p for p in PHASES if p[0] == "step")
    rest = next(p for p in PHASES if p[0] == "rest")
    sel = [i for i, r in enumerate(rows) if r[1] in ("rest", "step")]
    m = step_metrics([t[i] for i in sel], [true[i] for i in sel], step[1], step[2],
                     rest[2] - rest[1], None)

    def scored(phase: str, col: int) -> list[float]:
        start = next(p[1] for p in PHASES if p[0] == phase) + SETTLE_S
        return [r[col] for r in rows if r[1] == phase and r[0] >= start]

    zt_true, zt_person = scored("zero_torque", 4), scored("zero_torque", 6)
    stop_person = scored("stop", 6)
    fmt = lambda v, f: "none" if v is None else format(v, f)  # noqa: E731
    return {
        "step_nm": f"{STEP_NM:g}",
        "step_environment": f"spring {SPRING_NM_RAD:g} N m/rad, {SPRING_DAMPING_NM_S_RAD:g} "
                            "N m s/rad",
        "step_true_final_nm": f"{m['final_nm']:.3f}",
        "step_true_rise_time_s": fmt(m["rise_time_s"], ".4f"),
        "step_true_overshoot_pct": f"{m['overshoot_pct']:.1f}",
        "step_true_settling_time_s": fmt(m["settling_time_s"], ".4f"),
        "back_driving": f"+-{PERSON_SPEED_RAD_S:g} rad/s, period {PERSON_PERIOD_S:g} s",
        "zero_torque_true_rms_nm": f"{_rms(zt_true):.3f}",
        "zero_torque_true_max_nm": f"{max(abs(x) for x in zt_true):.3f}",
        "zero_torque_person_rms_nm": f"{_rms(zt_person):.3f}",
        "stop_person_rms_nm": f"{_rms(stop_person):.3f}",
        "person_rms_zero_torque_over_stop": f"{_rms(zt_person) / _rms(stop_person):.3f}",
    }


def plot(rows: list[tuple], summary: dict[str, str], png: str, out: safeio.Outputs) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = [r[0] for r in rows]
    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    ax = axes[0]
    ax.plot(t, [r[4] for r in rows], lw=0.8, color="C3", label="true output torque")
    ax.plot(t, [r[3] for r in rows], lw=1.2, color="k", ls="--",
            label="commanded (the loop's torque reference)")
    ax.set_ylabel("torque [N m]")
    ax.set_title("Closed loop on the dynamic joint: back-driven with the drive off (STOP) "
                 "and in ZERO_TORQUE,\nthen a torque step against a spring")
    ax2 = axes[1]
    ax2.plot(t, [r[6] for r in rows], lw=0.8, color="C0", label="the person's torque")
    ax2.plot(t, [r[7] for r in rows], lw=0.8, color="C2", label="output speed [rad/s]")
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("N m, rad/s")
    for a in axes:
        for name, start, _ in PHASES:
            if start > 0.0:
                a.axvline(start, color="0.7", lw=0.8)
            if a is ax:
                a.text(start + 0.05, 0.97, name, transform=a.get_xaxis_transform(),
                       va="top", fontsize=8, color="0.4")
        a.grid(alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.64, 1.0), fontsize=8)
    ax2.legend(loc="upper right", fontsize=8)
    ax2.text(0.99, 0.04, f"person's torque RMS: ZERO_TORQUE {summary['zero_torque_person_rms_nm']}"
             f" N m, STOP {summary['stop_person_rms_nm']} N m", transform=ax2.transAxes,
             fontsize=8, ha="right")
    fig.tight_layout()
    with out.path(png) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out_dir")
    a = ap.parse_args(argv)
    try:
        rows = run()
        summary = summarize(rows)
        with safeio.Outputs() as out:
            out.write_text(f"{a.out_dir}/control_samples.csv", ",".join(COLUMNS) + "\n" + "".join(
                f"{r[0]:.3f},{r[1]},{r[2]},{r[3]:.3f},{r[4]:.4f},{r[5]:.4f},{r[6]:.4f},"
                f"{r[7]:.4f}\n" for r in rows))
            out.write_text(f"{a.out_dir}/control_summary.txt",
                           "".join(f"{k} = {v}\n" for k, v in summary.items()))
            out.write_text(f"{a.out_dir}/control.json", json.dumps(
                {"tool": "tools/demo (hdtools.demo_control)", **summary}, indent=1) + "\n")
            plot(rows, summary, f"{a.out_dir}/control.png", out)
            out.commit()
    except (safeio.HdError, ValueError, OSError) as exc:
        print(f"demo_control: {exc}", file=sys.stderr)
        return 3 if isinstance(exc, (OSError, safeio.OutputError)) else 1
    print("".join(f"{k} = {v}\n" for k, v in summary.items()), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
