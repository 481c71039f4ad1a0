"""Control benchmark (issue 23, docs/results/control.md): the firmware's torque loop
on the dynamic joint, judged on the simulation's true output torque.

Feedback variants, each tuned by control_tune (same margins, measured by
breaking the loop in the simulation): the filtered torque, the raw gauge
torque, the best Butterworth low-pass of the raw torque and the order notch
(notches at 2x and 4x the motor angle, tracking the speed); the open-loop
current (no feedback) is the baseline of the same run.  The ideal sensor
(IDEAL_KEY) is a diagnostic bound, not a product variant: the raw feedback
on a simulated gauge whose sensing artifact and noise are switched off
(hdctrl-bench --sensor ideal), i.e. the loop fed the simulation's true output
torque, tuned and measured like every other variant; what no torque sensor
or filter could exceed on this plant with this tuning method.  It is never
the best low-pass and nothing the firmware's defaults come from.  A Butterworth must
do the filter's job: attenuate the gauge's 2x line by BUTTER_ATTEN_DB at the
slowest benchmarked speed (one filter for all speeds, as the firmware would
run it); the best order is the one with the most bandwidth at the worst
speed.  Nothing here is told the simulated joint's parameters: the runner
boots the firmware with its defaults, and the gains come from the tuning.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import signal

from . import control_loop as cl
from . import control_tune as ct

SPEEDS_RAD_S = (0.0, 0.5, 3.0)
CONDITIONS = tuple(str(s) for s in SPEEDS_RAD_S) + ("wall", "free")   # of the tuning
TRANSPARENCY_SPEEDS_RAD_S = (0.2, 0.5, 1.0, 3.0)
SETPOINT_NM = 10.0
CHIRP_AMP_NM, CHIRP_F0_HZ, CHIRP_F1_HZ, CHIRP_S = 2.0, 0.5, 200.0, 10.0
CHIRP_SEGMENT = 1000     # Welch segment [ticks]: the response's bins are 1 / (this TS) apart
STEP_FROM_NM = 5.0
BUTTER_ATTEN_DB = 20.0
BUTTER_ORDERS = (1, 2, 4)
NOTCH_MASK = (1 << 1) | (1 << 3)   # orders 2 and 4 of the motor angle
NOTCH_WIDTH_HZ = 10.0
IMPEDANCE_KP = (100.0, 500.0)
IMPEDANCE_KD = (1.0, 5.0)
WALL = {"kp": 500.0, "kds": (2.0, 10.0), "q_d": 0.05, "wall_rad": 0.02,
        "stiffness": cl.WALL_STIFFNESS_NM_RAD}
STIFFNESS_GOAL_PCT = 5.0
INTEGRAL_MARGIN = 1.25   # the integral bound over the measured drive-train friction
TS = cl.TS_S
IDEAL_KEY = "ideal"
IDEAL_LABEL = "ideal sensor (simulation truth, a bound, not a product variant)"
BANDWIDTH_GOAL_X = 2.0   # the product feedback against the best low-pass
PRODUCT_KEY = "narrow"   # the product feedback: the law's default ctrl_feedback (4) and
                         # gains (hd_ctrl_config_default); the goals compare it
COMPARE_KEY = "filtered"   # the filter's torque, kept in the goals for comparison


def butterworth_cutoff_hz(order: int, line_hz: float, atten_db: float) -> float:
    """|H|^2 = 1 / (1 + (f / fc)^(2 n)) attenuates line_hz by atten_db."""
    return line_hz / (10.0 ** (atten_db / 10.0) - 1.0) ** (1.0 / (2 * order))


def variants() -> list[cl.Variant]:
    slow = min(s for s in SPEEDS_RAD_S if s > 0)
    line_hz = 2 * cl.GEAR_RATIO * slow / (2 * math.pi)
    # narrow: the raw torque minus the filter's artifact estimate held to the
    # motor angle (ctrl_feedback 4, at the law's ctrl_artifact_hz)
    out = [cl.Variant("filtered", "filtered"), cl.Variant("narrow", "narrow"),
           cl.Variant("raw", "raw")]
    for n in BUTTER_ORDERS:
        fc = butterworth_cutoff_hz(n, line_hz, BUTTER_ATTEN_DB)
        out.append(cl.Variant(f"butter{n}", "lowpass", lowpass_hz=round(fc, 2), lowpass_order=n))
    out.append(cl.Variant("order_notch", "raw", notch_mask=NOTCH_MASK,
                          notch_width_hz=NOTCH_WIDTH_HZ))
    out.append(cl.Variant("open_loop", "none"))
    out.append(cl.Variant(IDEAL_KEY, "raw", sensor="ideal"))   # the bound, last
    return out


def _harmonics_removed(y, motor_angle, frm: int) -> np.ndarray:
    """y minus its least-squares 2x and 4x motor-angle lines (fitted from
    tick frm on): the step response without the ripple, which is reported
    on its own.  Unchanged when the motor turns less than two revolutions
    there (the lines are then a constant, not a ripple)."""
    if abs(motor_angle[-1] - motor_angle[frm]) < 4 * math.pi:
        return np.asarray(y, dtype=float)
    cols = [np.ones_like(y)]
    for k in (2, 4):
        cols += [np.sin(k * motor_angle), np.cos(k * motor_angle)]
    a = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(a[frm:], y[frm:], rcond=None)
    return y - a[:, 1:] @ coef[1:]


def chirp_response(v: cl.Variant, speed: float, seconds: float = CHIRP_S) -> dict:
    settle = 1000
    t = np.arange(int(seconds / TS)) * TS
    sweep = CHIRP_AMP_NM * signal.chirp(t, CHIRP_F0_HZ, seconds, CHIRP_F1_HZ, method="logarithmic",
                                        phi=-90)
    sp = np.concatenate([np.full(settle, SETPOINT_NM), SETPOINT_NM + sweep])
    d = cl.simulate(v, cl.torque_scene(speed), sp)
    x, y = sp[settle:] - SETPOINT_NM, d["true_torque_nm"][settle:]
    f, pxy = signal.csd(x, y - y.mean(), fs=1 / TS, nperseg=CHIRP_SEGMENT)
    _, pxx = signal.welch(x, fs=1 / TS, nperseg=CHIRP_SEGMENT)
    band = (f >= 1.0) & (f <= CHIRP_F1_HZ)
    h = pxy[band] / pxx[band]
    bw = ct.bandwidth_hz(f[band], h)
    above = bw == math.inf   # never below -3 dB up to the chirp's end
    return {"bandwidth_hz": CHIRP_F1_HZ if above else bw, "above_band": above,
            "peak_db": float(20 * np.log10(np.abs(h).max()))}


def step_response(v: cl.Variant, speed: float) -> dict:
    at, n = 1000, 2000
    sp = np.where(np.arange(n) < at, STEP_FROM_NM, SETPOINT_NM)
    d = cl.simulate(v, cl.torque_scene(speed), sp)
    y = _harmonics_removed(d["true_torque_nm"], d["motor_angle_rad"], at + 50)
    y = np.convolve(y, np.ones(5) / 5, mode="full")[:n]   # 5 ticks: the gauge noise
    span = SETPOINT_NM - STEP_FROM_NM
    x = (y[at:] - STEP_FROM_NM) / span
    outside = np.flatnonzero(np.abs(x - 1.0) > 0.05)
    t10 = np.flatnonzero(x >= 0.1)
    t90 = np.flatnonzero(x >= 0.9)
    return {"overshoot_pct": float(100 * max(0.0, x.max() - 1.0)),
            "settle_ms": float((outside[-1] + 1) * TS * 1e3) if len(outside) else 0.0,
            "rise_ms": float((t90[0] - t10[0]) * TS * 1e3) if len(t10) and len(t90) else None,
            "final_error_nm": float(np.mean(y[-300:]) - SETPOINT_NM)}


def line_amplitude(y, angle, order: int = 2) -> float:
    a = np.column_stack([np.ones_like(y), np.sin(order * angle), np.cos(order * angle)])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    return float(math.hypot(coef[1], coef[2]))


def ripple(v: cl.Variant, speed: float) -> dict | None:
    """The 2x line and the rms of the true torque at a constant setpoint
    (None at standstill: no ripple)."""
    if speed == 0.0:
        return None
    n, frm = 3000, 1000
    d = cl.simulate(v, cl.torque_scene(speed), np.full(n, SETPOINT_NM))
    y, th = d["true_torque_nm"][frm:], d["motor_angle_rad"][frm:]
    return {"line2_nm": line_amplitude(y, th, 2), "rms_nm": float(np.std(y)),
            "mean_nm": float(np.mean(y))}


def back_drive_nm(v: cl.Variant, speed: float) -> float:
    """The mean torque the dynamometer needs to drive the output at speed
    in ZERO_TORQUE."""
    d = cl.simulate(v, cl.Scene(speed, mode="zero_torque"), np.zeros(3000))
    return float(np.mean(d["person_nm"][1000:]))


def impedance(v: cl.Variant) -> dict:
    rows = []
    push = 10.0
    for kp in IMPEDANCE_KP:
        sc = cl.Scene(0.0, mode="impedance", load="free",
                      extra=["--imp-kp", kp, "--imp-kd", 2.0, "--person-nm", push])
        d = cl.simulate(v, sc, np.zeros(3000))
        tail = d["output_angle_rad"][2000:]
        q = float(np.mean(tail))
        rows.append({"kind": "stiffness", "commanded": kp, "rendered": push / q,
                     "error_pct": 100 * (push / q / kp - 1),
                     "p2p_pct": float(100 * (tail.max() - tail.min()) / q)})
    for kd in IMPEDANCE_KD:
        torques = []
        for s in (0.5, 1.0):
            sc = cl.Scene(s, mode="impedance", extra=["--imp-kp", 0.0, "--imp-kd", kd])
            d = cl.simulate(v, sc, np.zeros(3000))
            torques.append(float(np.mean(d["person_nm"][1000:])))
        rendered = (torques[1] - torques[0]) / 0.5
        rows.append({"kind": "damping", "commanded": kd, "rendered": rendered,
                     "error_pct": 100 * (rendered / kd - 1)})
    return {"rows": rows, "worst_stiffness_error_pct":
            max(abs(r["error_pct"]) for r in rows if r["kind"] == "stiffness"),
            "worst_damping_error_pct":
            max(abs(r["error_pct"]) for r in rows if r["kind"] == "damping")}


CONTACT_SEEN = 0.05   # measured wall contact: in contact while the filtered torque
                      # is above this fraction of its last second's mean


def wall_contact(v: cl.Variant, kd: float, measured: bool = False) -> dict:
    """IMPEDANCE kp 500 N m/rad toward 0.05 rad, a wall of 2e4 N m/rad at
    0.02 rad: the last second's true torque (mean, peak to peak) and the
    contact losses after the first 0.5 s of contact; a limit cycle is a
    loss or a peak to peak above 10 % of the mean.  measured: judged as a
    test on the joint itself sees it, on the firmware's filtered torque
    (contact: above CONTACT_SEEN of its mean), not the simulation's truth."""
    w = WALL
    sc = cl.Scene(0.0, mode="impedance", load="wall",
                  extra=["--imp-kp", w["kp"], "--imp-kd", kd, "--imp-q", w["q_d"],
                         "--wall-rad", w["wall_rad"], "--wall-stiffness", w["stiffness"]])
    d = cl.simulate(v, sc, np.zeros(3000))
    torque, env = d["true_torque_nm"], d["env_nm"]
    if measured:   # the gauge's view: in contact while its torque is clearly above zero
        torque = np.nan_to_num(d["filtered_nm"])
        env = torque - CONTACT_SEEN * float(np.mean(torque[-1000:]))
    touched = np.flatnonzero(env > 0)
    first = int(touched[0]) if len(touched) else len(env)
    late = env[first + 500:] if first + 500 < len(env) else env[-1:]
    force = torque[-1000:]
    p2p = float(force.max() - force.min())
    losses = int(np.sum((late[1:] <= 0) & (late[:-1] > 0)))
    return {"kp_nm_rad": w["kp"], "kd_nm_s_rad": kd, "torque_ki_per_s": v.ki,
            "mean_nm": float(force.mean()),
            "commanded_nm": float(np.mean(d["torque_ref_nm"][-1000:])),
            "filtered_error_nm": float(np.nanmean(d["filtered_nm"][-1000:] - force)),
            "invalid_ticks": int(np.sum(~np.isfinite(d["filtered_nm"][-1000:]))),
            "p2p_nm": p2p, "contact_losses": losses,
            "limit_cycle": bool(losses > 0 or p2p > 0.1 * abs(float(force.mean())))}


def wall_check(kds=WALL["kds"], measured: bool = False):
    """The tuning's contact condition (control_tune.tune's `contact`): the
    benchmark's wall contact (wall_contact: the same wall, impedance and
    limit-cycle criterion as the goals' rows) at every impedance kd of kds,
    with the candidate's torque-loop gains (measured: judged on the
    filtered torque)."""
    return lambda v: [wall_contact(v, kd, measured) for kd in kds]


def tracking_rate(seconds: float = CHIRP_S):
    """The tuning's measure of the tracking (control_tune.tune's `rate`):
    the mean log -3 dB bandwidth of the true torque's chirp response over
    the benchmark's speeds, what the goal compares (a response below -3 dB
    from the start counts as 0.5 Hz, as in the ranking), and its resolution:
    one bin of the response at each speed, as the same mean (bin / bw)."""
    bin_hz = 1.0 / (CHIRP_SEGMENT * TS)

    def rate(v: cl.Variant) -> tuple[float, float]:
        bws = np.array([chirp_response(v, s, seconds)["bandwidth_hz"] or 0.5
                        for s in SPEEDS_RAD_S])
        return float(np.mean(np.log(bws))), float(np.mean(bin_hz / bws))
    return rate


def integral_limit_nm(drive_friction_nm: float) -> float:
    """The torque loop's integral bound: what the integral is for (the drive
    train's friction between the current and the flexspline, measured open
    loop) with a margin, rounded as the law's defaults hold it.  Bounded,
    the integral cannot wind up on what it is not for: the torque that
    accelerates a free output before an impact, or the feedback's drift while
    a stiff contact holds the motor still (both end in a limit cycle)."""
    return float(f"{INTEGRAL_MARGIN * drive_friction_nm:.3g}")


def friction_rest_nm(open_nm: dict) -> float:
    """The law's friction compensation at rest (ctrl_friction_rest_nm): the
    open-loop drive train's back-drive torque at the slowest speed measured
    (its Coulomb part: the least of the rows, which grow with the speed),
    rounded as the law's parameters hold it.  At rest the motor moves only by
    the flexspline's windup and this friction holds it (docs/decisions/
    control-bandwidth.md); measured, not told: the breakaway above it is
    not compensated."""
    slowest = min(open_nm, key=float)
    return float(f"{abs(open_nm[slowest]):.3g}")


def run(quick: bool = False, log=lambda s: None) -> dict:
    vs = variants()
    if quick:
        vs = [x for x in vs if x.key in (PRODUCT_KEY, COMPARE_KEY, "butter2", "open_loop")]
    opn = next(v for v in vs if v.key == "open_loop")
    speeds_t = TRANSPARENCY_SPEEDS_RAD_S[::3] if quick else TRANSPARENCY_SPEEDS_RAD_S
    log("measuring the open-loop drive train...")
    open_nm = {str(s): back_drive_nm(opn, s) for s in speeds_t}
    ilim = integral_limit_nm(max(abs(x) for x in open_nm.values()))
    f_rest = friction_rest_nm(open_nm)
    for v in vs:   # every feedback alike
        v.ilim = ilim
        v.friction_rest_nm = f_rest
    tuning = {}
    for v in vs:
        log(f"tuning {v.key}...")
        tuning[v.key] = ct.tune(v, CONDITIONS, log=log,
                                contact=wall_check(WALL["kds"][:1 if quick else None]),
                                rate=tracking_rate(4.0 if quick else CHIRP_S))
    # the best low-pass is compared at equal margins: among the orders whose tuning met them
    butters = [v for v in vs if v.key.startswith("butter")]
    butters = [v for v in butters if tuning[v.key].get("met")] or butters
    rows = {}
    for v in vs:
        log(f"measuring {v.key}...")
        r = {"config": {k: getattr(v, k) for k in ("feedback", "kp", "ki", "kd", "ff", "ilim",
                                                     "lowpass_hz", "lowpass_order", "notch_mask",
                                                     "notch_width_hz", "artifact_hz",
                                                     "friction_rest_nm", "sensor")},
             "speeds": {}}
        for s in SPEEDS_RAD_S:
            r["speeds"][str(s)] = {"chirp": chirp_response(v, s, 4.0 if quick else CHIRP_S),
                                   "step": step_response(v, s), "ripple": ripple(v, s)}
        rows[v.key] = r
    best = max(butters, key=lambda v: min(_bw(rows[v.key], s) for s in SPEEDS_RAD_S))
    prod = next(v for v in vs if v.key == PRODUCT_KEY)   # what the firmware runs
    transp = {str(s): {"zero_torque_nm": back_drive_nm(prod, s), "open_loop_nm": open_nm[str(s)]}
              for s in speeds_t}
    for t in transp.values():
        t["ratio"] = abs(t["zero_torque_nm"]) / abs(t["open_loop_nm"])
    imp = impedance(prod)
    wall = [wall_contact(prod, kd) for kd in WALL["kds"][:1 if quick else None]]
    if not quick:   # the same loop without its integral: what the contact's cycle needs
        wall.append(wall_contact(dataclasses.replace(prod, ki=0.0), WALL["kds"][0]))
    return {"speeds_rad_s": list(SPEEDS_RAD_S), "product": PRODUCT_KEY, "margins": {"pm_deg": ct.PM_DEG, "gm_db": ct.GM_DB},
            "integral_limit_nm": ilim, "friction_rest_nm": f_rest,
            "tuning": tuning, "rows": rows, "best_butterworth": best.key,
            "transparency": transp, "impedance": imp, "wall": wall,
            "goals": goals(rows, best.key, transp, imp, wall, tuning), "quick": quick}


def _bw(row: dict, s: float) -> float:
    """The chirp's bandwidth; below the lowest line (1 Hz) it counts as
    1 Hz, so a ratio against it is a lower bound."""
    b = row["speeds"][str(s)]["chirp"]["bandwidth_hz"]
    return 1.0 if b is None else b


def ideal_bound(rows: dict, best: str, margins_met: bool = True) -> list[dict]:
    """One row per speed: the ideal sensor's bandwidth against the best
    low-pass's.  Not a goal (met is None): below BANDWIDTH_GOAL_X the
    bandwidth goal is out of reach at that speed for ANY feedback signal
    with this plant and this tuning method, the filter's included.  If the
    method found no gains meeting the margins for it, it bounds nothing
    (reachable None)."""
    i, b, f = rows[IDEAL_KEY], rows[best], rows[PRODUCT_KEY]
    out = []
    for s in SPEEDS_RAD_S:
        x = _bw(i, s) / _bw(b, s)
        ok = x >= BANDWIDTH_GOAL_X if margins_met else None
        out.append({"goal": f"{IDEAL_LABEL}: bandwidth / the best low-pass's ({best}), "
                            f"{s} rad/s (the {BANDWIDTH_GOAL_X:g}x goal needs >= "
                            f"{BANDWIDTH_GOAL_X:g})",
                    "kind": "bound", "worst": x, "where":
                    f"bound {_hz(i, s)}, {best} {_hz(b, s)}, {PRODUCT_KEY} {_hz(f, s)} Hz "
                    f"({_bw(f, s) / _bw(i, s):.2f}x the bound)",
                    "met": None, "reachable": ok, "speed_rad_s": s,
                    "bandwidth_hz": i["speeds"][str(s)]["chirp"]["bandwidth_hz"],
                    "status": {True: "2x reachable", False: "2x UNREACHABLE by any feedback",
                               None: "no bound: its margins NOT met"}[ok]})
    return out


def ripple_bound(rows: dict, speed: str) -> dict:
    """The open-loop drive's true 2x ripple over raw feedback's at `speed`:
    what a feedback that leaves the 2x line alone reaches.  The gauge sees
    the real meshing ripple and its own artifact at the same order; a loop
    that acted on the line would turn the artifact into torque (raw), and
    even the ideal sensor's loop, fed the real ripple alone, amplifies it at
    these frequencies (its row); only a cancellation that knew the meshing
    ripple apart (a feed-forward) could go below."""
    line = {k: rows[k]["speeds"][speed]["ripple"]["line2_nm"]
            for k in ("open_loop", PRODUCT_KEY, "raw", IDEAL_KEY) if k in rows}
    x = line["open_loop"] / line["raw"]
    return {"goal": "open-loop ripple (a bound, not a product variant): the open-loop drive's "
                    "true-torque 2x ripple / raw's, where the ripple goal is worst (what a "
                    "feedback that leaves the 2x line alone reaches)",
            "kind": "bound", "worst": x, "met": None, "speed_rad_s": float(speed),
            "where": f"{speed} rad/s: " + ", ".join(f"{k} {v:.3f}" for k, v in line.items())
                     + " N m",
            "status": ("0.5x reachable" if x <= 0.5 else
                       "0.5x UNREACHABLE without cancelling the meshing ripple")}


def _hz(row: dict, s: float) -> str:
    c = row["speeds"][str(s)]["chirp"]
    b = c["bandwidth_hz"]
    return "< 1" if b is None else (f"> {b:g}" if c.get("above_band") else f"{b:.1f}")


def goals(rows: dict, best: str, transp: dict, imp: dict, wall: list,
          tuning: dict | None = None) -> list[dict]:
    """Issue 23's goals against this run's numbers (benchmark numbers, not
    pass/fail tests: a goal not met is reported with its number)."""
    out = []
    f, b = rows[PRODUCT_KEY], rows[best]
    ratios = {str(s): _bw(f, s) / _bw(b, s) for s in SPEEDS_RAD_S}
    worst = min(ratios, key=ratios.get)
    out.append({"goal": f"bandwidth {PRODUCT_KEY} (the product feedback, the law's default) >= "
                        f"{BANDWIDTH_GOAL_X:g}x the best low-pass ({best}) "
                        "at equal margins, every speed", "worst": ratios[worst],
                "where": f"{worst} rad/s", "met": ratios[worst] >= BANDWIDTH_GOAL_X,
                "ratios": ratios})
    if COMPARE_KEY in rows and COMPARE_KEY != PRODUCT_KEY:   # not a goal: for comparison
        c = rows[COMPARE_KEY]
        cr = {str(s): _bw(c, s) / _bw(b, s) for s in SPEEDS_RAD_S}
        cw = min(cr, key=cr.get)
        out.append({"goal": f"comparison (not the product): bandwidth {COMPARE_KEY} / the best "
                            f"low-pass's ({best}), every speed", "kind": "comparison",
                    "worst": cr[cw], "where": f"{cw} rad/s", "met": None, "ratios": cr,
                    "status": ("would be met" if cr[cw] >= BANDWIDTH_GOAL_X
                               else "would NOT be met")})
    if IDEAL_KEY in rows:
        out += ideal_bound(rows, best, (tuning or {}).get(IDEAL_KEY, {}).get("met", True))
    if "raw" in rows:
        rr = {str(s): f["speeds"][str(s)]["ripple"]["line2_nm"]
              / rows["raw"]["speeds"][str(s)]["ripple"]["line2_nm"]
              for s in SPEEDS_RAD_S if s > 0}
        worst = max(rr, key=rr.get)
        out.append({"goal": f"true-torque 2x ripple {PRODUCT_KEY} (the product feedback) "
                            "<= 0.5x raw", "worst": rr[worst],
                    "where": f"{worst} rad/s", "met": rr[worst] <= 0.5, "ratios": rr})
        if "open_loop" in rows:
            out.append(ripple_bound(rows, worst))
    tr = {s: t["ratio"] for s, t in transp.items()}
    worst = max(tr, key=tr.get)
    out.append({"goal": "back-drive in ZERO_TORQUE <= 0.1x the open-loop drive's",
                "worst": tr[worst], "where": f"{worst} rad/s", "met": tr[worst] <= 0.1})
    st = [r for r in imp["rows"] if r["kind"] == "stiffness"]
    w = max(st, key=lambda r: abs(r["error_pct"]))
    out.append({"goal": f"rendered stiffness within {STIFFNESS_GOAL_PCT:g} %",
                "worst": abs(w["error_pct"]), "where": f"kp {w['commanded']:g} N m/rad",
                "met": abs(w["error_pct"]) <= STIFFNESS_GOAL_PCT})
    wall = [c for c in wall if c["torque_ki_per_s"] > 0]   # the tuned loop's
    bad = [c for c in wall if c["limit_cycle"]]
    out.append({"goal": "stiff-wall contact without a limit cycle",
                "worst": max(c["p2p_nm"] for c in wall),
                "where": ", ".join(f"kd {c['kd_nm_s_rad']:g}" for c in (bad or wall)),
                "met": not bad})
    return out
