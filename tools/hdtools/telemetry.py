"""Time and angle from the device for decoded telemetry (docs/reference/protocol.md,
"Time from the device").

A host's time stamps are not the sample clock: a USB adapter delivers
frames in batches (4 ms is common), a busy host adds jitter.  The joint
numbers its telemetry (the 8-bit sequence of TELEM_A/B) and sends it every
`divider` ticks of its 1 kHz clock, so sample k is at k x period exactly.
Host time stamps are used only to unwrap the sequence across gaps (how
many times 256 samples were lost) and, when nothing else tells, to
estimate the period.

The period comes from, in this order: --rate; the log's own answers to
GET_PARAM / SET_PARAM of telemetry_rate_hz (the one in force at each
sample, in log order; `hdsense monitor --log` asks at its start); a robust
estimate from the host time stamps (median over long windows, snapped to
whole ticks).

Angles: TELEM_C carries the raw motor counts (u32) and the low 23 bits of
the output counts with every Nth telemetry sample (angle_telemetry_every).
They are unwrapped and scaled by motor_cpr / output_cpr (--cpr or the log's
GET_PARAM answers).  Between two TELEM_C samples the motor angle follows
the integral of MotorVelocity with the mismatch at the next TELEM_C spread
linearly (exact at every TELEM_C sample); the output angle is interpolated
linearly in time.
"""
from __future__ import annotations

import math

import numpy as np

from . import protocol

TICK_HZ = 1000                   # HD_FW_TS_US = 1000 (firmware/hd_fw_config.h; a test checks)
TICK_S = 1.0 / TICK_HZ
_TELEM_C = {s.name: s for s in protocol.frame_signals("TELEM_C")}
SEQ_MOD = 1 << _TELEM_C["SeqC"].bits
MOTOR_COUNTS_MOD = 1 << _TELEM_C["MotorCounts"].bits
OUTPUT_COUNTS_MOD = 1 << _TELEM_C["OutputCounts"].bits   # the low bits TELEM_C carries
SNAP_TOLERANCE = 0.02            # an estimate within 2 % of whole ticks is snapped


def telemetry_period_s(rate_hz: float) -> float:
    """The firmware's telemetry period for a rate (hd_fw_derive: the
    period is rounded to whole ticks, divider = (1000 + rate/2) / rate)."""
    rate = int(round(rate_hz))
    if rate <= 0 or rate > TICK_HZ:
        raise ValueError(f"telemetry_rate_hz {rate_hz:g} outside 1..{TICK_HZ}")
    return ((TICK_HZ + rate // 2) // rate) * TICK_S


def estimate_period_s(host_t, seq) -> tuple[float | None, str]:
    """The telemetry period from host time stamps, robust to jitter and
    batching: the median of (t[i+L] - t[i]) / steps over windows of L
    samples (L a tenth of the log, at least 1), snapped to whole ticks when
    within SNAP_TOLERANCE.  (None, why) with fewer than 3 samples."""
    t = np.asarray(host_t, float)
    s = np.asarray(seq, np.int64)
    if len(t) < 3:
        return None, "too few samples to estimate the period"
    steps = np.concatenate([[0], np.cumsum(np.mod(np.diff(s), SEQ_MOD))])
    lag = max(1, len(t) // 10)
    dn = steps[lag:] - steps[:-lag]
    dt = t[lag:] - t[:-lag]
    ok = dn > 0
    if not ok.any():
        return None, "no sequence steps"
    period = float(np.median(dt[ok] / dn[ok]))
    if not period > 0:
        return None, "host time stamps do not advance"
    ticks = round(period / TICK_S)
    if ticks >= 1 and abs(period / (ticks * TICK_S) - 1.0) <= SNAP_TOLERANCE:
        return ticks * TICK_S, f"estimated from host time stamps ({period * 1e3:.4f} ms, " \
                               f"snapped to {ticks} tick(s))"
    return period, f"estimated from host time stamps ({period * 1e3:.4f} ms, not whole ticks)"


def place(rows: list[dict], rate_hz: float | None = None) -> dict:
    """Device time for decoded telemetry rows, in place.

    Each row needs "t_host_s", "SeqA", "segment" (0, 1, ... : a BOOT
    frame starts a new one) and "rate_hz" (the telemetry_rate_hz answer in
    force, None if none yet).  Sets "t_s" (device time, seconds from the
    first row) and "step" (unwrapped sequence); repeated samples (no
    sequence step) are removed.  Returns {"period_s", "period_source",
    "lost"}: period_s is None when it changes within the log."""
    if not rows:
        return {"period_s": None, "period_source": "no telemetry", "lost": 0}
    first_segment = rows[0]["segment"]      # a BOOT before the first sample starts nothing
    for r in rows:
        r["segment"] -= first_segment
    sources = set()
    if rate_hz is not None:
        periods = [telemetry_period_s(rate_hz)] * len(rows)
        sources.add(f"--rate {rate_hz:g} Hz")
    else:
        periods = [telemetry_period_s(r["rate_hz"]) if r.get("rate_hz") else None
                   for r in rows]
        if any(p is None for p in periods):
            # before the first answer: a GET_PARAM answer told the rate in
            # force all along; after a SET_PARAM (or with none) estimate it
            first = next((r for r in rows if r.get("rate_hz")), None)
            head = [r for r, p in zip(rows, periods) if p is None]
            guess, why = estimate_period_s([r["t_host_s"] for r in head],
                                           [r["SeqA"] for r in head])
            if first is not None and (first.get("rate_kind") == "GET" or guess is None):
                guess = telemetry_period_s(first["rate_hz"])
                why = "the log's first telemetry_rate_hz answer"
            if guess is None:
                raise ValueError(f"cannot tell the telemetry period: {why}; give --rate")
            periods = [guess if p is None else p for p in periods]
            sources.add(why)
        if any(r.get("rate_hz") for r in rows):
            sources.add("the log's telemetry_rate_hz answers")
    kept, lost = [], 0
    prev_row = None
    t_epoch = n_epoch = 0.0
    step = 0
    for row, period in zip(rows, periods):
        if prev_row is None:
            row["step"], row["t_s"] = 0, 0.0
            t_epoch, n_epoch, p_epoch = 0.0, 0, period
        else:
            dt = row["t_host_s"] - prev_row["t_host_s"]
            if row["segment"] != prev_row["segment"]:
                # a reboot: the sequence restarts; continue on the host's clock
                whole = max(1, round(dt / period)) if dt == dt else 1
                step += whole
                t_epoch, n_epoch, p_epoch = prev_row["t_s"] + whole * period, step, period
            else:
                d = (row["SeqA"] - prev_row["SeqA"]) % SEQ_MOD
                wraps = round((dt / period - d) / SEQ_MOD) if math.isfinite(dt) else 0
                steps = d + SEQ_MOD * max(0, wraps)
                if steps == 0:
                    continue            # the same sample again
                lost += steps - 1
                step += steps
                if period != p_epoch:
                    t_epoch = prev_row["t_s"] + steps * period
                    n_epoch, p_epoch = step, period
            row["step"] = step
            row["t_s"] = t_epoch + (step - n_epoch) * p_epoch
        kept.append(row)
        prev_row = row
    rows[:] = kept
    single = len(set(periods)) == 1
    return {"period_s": periods[0] if single else None,
            "period_source": "; ".join(sorted(sources)), "lost": lost}


def _unwrap_counts(counts, modulus: int) -> np.ndarray:
    c = np.asarray(counts, np.int64)
    d = np.mod(np.diff(c) + modulus // 2, modulus) - modulus // 2
    return c[0] + np.concatenate([[0], np.cumsum(d)])


def angles(t_s, velocity_rad_s, anchor_idx, motor_counts, motor_cpr: float,
           output_counts=None, output_cpr: float | None = None) -> dict:
    """Motor (and output) angle at every sample from the TELEM_C samples at
    anchor_idx (see the module doc).  Returns {"motor_angle_rad", and
    "output_angle_rad" when output counts and output_cpr are given}."""
    t = np.asarray(t_s, float)
    v = np.asarray(velocity_rad_s, float)
    a = np.asarray(anchor_idx, int)
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    th_a = _unwrap_counts(motor_counts, MOTOR_COUNTS_MOD) * (2 * math.pi / motor_cpr)
    # previous anchor of every sample (samples before the first: the first)
    k = np.clip(np.searchsorted(a, np.arange(len(t)), side="right") - 1, 0, len(a) - 1)
    nxt = np.minimum(k + 1, len(a) - 1)
    ia, ib = a[k], a[nxt]
    mismatch = (th_a[nxt] - th_a[k]) - (integral[ib] - integral[ia])
    span = t[ib] - t[ia]
    frac = np.where(span > 0, (t - t[ia]) / np.where(span > 0, span, 1.0), 0.0)
    frac = np.clip(frac, 0.0, 1.0)
    out = {"motor_angle_rad": th_a[k] + (integral - integral[ia]) + frac * mismatch}
    if output_counts is not None and output_cpr:
        th_o = _unwrap_counts(output_counts, OUTPUT_COUNTS_MOD) * (2 * math.pi / output_cpr)
        if len(a) >= 2:
            lo = th_o[0] + (t - t[a[0]]) * (th_o[1] - th_o[0]) / (t[a[1]] - t[a[0]])
            hi = th_o[-1] + (t - t[a[-1]]) * (th_o[-1] - th_o[-2]) / (t[a[-1]] - t[a[-2]])
            mid = np.interp(t, t[a], th_o)
            out["output_angle_rad"] = np.where(t < t[a[0]], lo, np.where(t > t[a[-1]], hi, mid))
        else:
            out["output_angle_rad"] = np.full(len(t), th_o[0])
    return out


def columns(res: dict, motor_cpr: float | None = None,
            output_cpr: float | None = None) -> tuple[dict, list[str]]:
    """The decoded telemetry of canproto.decode_log as CSV columns for
    `hdsense analyze` (docs/design/analyze.md, "Input"): t_s (device time),
    torque_nm (TorqueRaw; NaN when not available), motor_angle_rad and,
    with an output encoder, output_angle_rad, plus the other signals.
    motor_cpr / output_cpr default to the log's GET_PARAM answers.  Returns
    (columns, notes) where notes say where the angles came from."""
    rows = res["telemetry"]
    params = res.get("params", {})
    motor_cpr = motor_cpr or params.get("motor_cpr")
    output_cpr = output_cpr or params.get("output_cpr")
    n = len(rows)
    col = {
        "t_s": np.array([r["t_s"] for r in rows], float),
        "torque_nm": np.array([r["TorqueRaw"] if r["valid"] else np.nan for r in rows], float),
        "torque_filtered_nm": np.array([r["TorqueFiltered"] if r["valid"] else np.nan
                                        for r in rows], float),
        "ripple_nm": np.array([r["Ripple"] for r in rows], float),
        "motor_velocity_rad_s": np.array([r["MotorVelocity"] for r in rows], float),
        "motor_angle_rad": np.full(n, np.nan),
        "output_angle_rad": np.full(n, np.nan),
        "angle_measured": np.array([int("MotorCounts" in r) for r in rows]),
        "seq": np.array([r["SeqA"] for r in rows]),
        "segment": np.array([r["segment"] for r in rows]),
        "faults": np.array([int(r["Faults"]) for r in rows]),
        "kf_status": np.array([int(r["KfStatus"]) for r in rows]),
        "t_host_s": np.array([r["t_host_s"] for r in rows], float),
    }
    notes = []
    has_output = False
    for seg in sorted(set(col["segment"].tolist())):
        idx = np.flatnonzero(col["segment"] == seg)
        t, vel = col["t_s"][idx], col["motor_velocity_rad_s"][idx]
        anchors = [i for i, k in enumerate(idx) if "MotorCounts" in rows[k]]
        if anchors and motor_cpr:
            out_c = [int(rows[idx[i]]["OutputCounts"]) for i in anchors]
            present = all(int(rows[idx[i]]["OutputPresent"]) for i in anchors)
            got = angles(t, vel, anchors, [int(rows[idx[i]]["MotorCounts"]) for i in anchors],
                         motor_cpr, out_c if present and output_cpr else None, output_cpr)
            col["motor_angle_rad"][idx] = got["motor_angle_rad"]
            if "output_angle_rad" in got:
                col["output_angle_rad"][idx] = got["output_angle_rad"]
                has_output = True
            src = (f"angles from TELEM_C counts ({len(anchors)} of {len(idx)} samples; "
                   f"motor_cpr {motor_cpr:g}" +
                   (f", output_cpr {output_cpr:g}" if "output_angle_rad" in got else "") + ")")
        else:
            integral = np.concatenate([[0.0], np.cumsum(0.5 * (vel[1:] + vel[:-1]) *
                                                        np.diff(t))])
            col["motor_angle_rad"][idx] = integral
            src = ("motor angle = integral of MotorVelocity (" +
                   ("no TELEM_C in the log" if not anchors else
                    "motor_cpr unknown: give --cpr or log a GET_PARAM answer") + ")")
        notes.append(f"segment {seg}: {src}" if col["segment"][-1] > 0 else src)
    if not has_output:
        del col["output_angle_rad"]
    return col, notes
