"""What the analysis concludes about its lines besides keeping or dropping
them (hdtools.analysis.pipeline): the one-speed ambiguity of a kept line,
the firmware's correction envelope, the table of every line's amplitude
before and after, and a kept change in a few words."""
from __future__ import annotations

import numpy as np

from . import augment


ONE_SPEED_BAND = 0.03       # |motor speed| within 3 % of its median ...
ONE_SPEED_SHARE = 0.9       # ... over 90 % of the moving samples: one speed


def one_speed_hz(data, gear_ratio):
    """The motor's turning rate [rev/s] when the log holds (almost) one
    |speed| (a commissioning run), else None: there a line at f Hz is a
    motor order f / rate as well, and the log cannot tell which."""
    w = []
    for p in data.pieces:
        th = p.motor_angle_rad if data.has_motor else (
            None if p.output_angle_rad is None else p.output_angle_rad * gear_ratio)
        if th is not None and len(th) > 2:
            w.append(np.abs(np.diff(np.asarray(th, float))) / data.ts_s)
    if not w:
        return None
    w = np.concatenate(w)
    moving = w[w > 0.05 * w.max()] if w.max() > 0 else w[:0]
    if len(moving) < 100:
        return None
    med = float(np.median(moving))
    share = float(np.mean(np.abs(moving - med) <= ONE_SPEED_BAND * med))
    return med / (2 * np.pi) if share >= ONE_SPEED_SHARE else None


def note_fixed_ambiguity(effects, data, gear_ratio, log):
    """A kept motor-order or fixed line on a one-speed log: which of the
    two it is, the log cannot say; the report says so (and what would)."""
    rate = one_speed_hz(data, gear_ratio)
    if rate is None:
        return
    for e in effects:
        if not e.get("added") or e["kind"] not in ("motor_order", "fixed_frequency"):
            continue
        f = (e.get("order_per_motor_rev") or 0.0) * rate if e["kind"] == "motor_order" else (
            e.get("frequency_hz") or 0.0)
        e["ambiguous"] = (f"the log turns at one speed ({rate:.4g} rev/s at the motor): a line at "
                          f"{f:.4g} Hz is also motor order {f / rate:.4g}; a log whose speed "
                          "varies tells a fixed-frequency line from a motor-locked one")
        log(f"note: {e['ambiguous']}")


ENVELOPE_MARGIN = 1.5
ENVELOPE_NOISE_SIGMAS = 10.0


def correction_envelope(lines, noise_nm):
    """The firmware's correction_max_nm for this joint: ENVELOPE_MARGIN x the
    sum of its lines' amplitudes in the raw torque (every line of the
    reference and final models: the most the correction can ever need to
    be) plus ENVELOPE_NOISE_SIGMAS x the noise."""
    total = sum(max(0.0, float(ln.get("raw_amplitude_nm") or 0.0)) for ln in lines)
    return float(f"{ENVELOPE_MARGIN * total + ENVELOPE_NOISE_SIGMAS * noise_nm:.4g}")


def lines_table(m_ref, m1, vr, vb, va):
    """Every line of the reference and final models: amplitude in the raw
    torque and in the filtered torque of the reference, starting and final
    models."""
    kinds = {"motor": "motor_order", "output": "output_order", "fixed": "fixed_frequency"}
    seen, out = set(), []
    entries = [(b.lock, b.order, b.label()) for b in m_ref.blocks + m1.blocks] + [
        (p.lock, p.order, f"{p.lock} {p.order:g}/rev (profile)") for p in m1.profile]
    for lock, order, label in entries:
        if (lock, round(order, 4)) in seen:
            continue
        seen.add((lock, round(order, 4)))
        k = kinds[lock]
        out.append({"block": label, "kind": k, "order": order,
                    "raw_amplitude_nm": augment.line_amplitude(vb, k, order, True),
                    "filtered_amplitude_reference_nm": augment.line_amplitude(vr, k, order),
                    "filtered_amplitude_before_nm": augment.line_amplitude(vb, k, order),
                    "filtered_amplitude_after_nm": augment.line_amplitude(va, k, order),
                    "spectral_raw_amplitude_nm": augment.spectral_line_amplitude(vb, k, order, True),
                    "spectral_filtered_before_nm": augment.spectral_line_amplitude(vb, k, order),
                    "spectral_filtered_after_nm": augment.spectral_line_amplitude(va, k, order)})
    return out


def label(e):
    """A kept change in a few words (the summary line, fleet records)."""
    if e["kind"] == "motor_order":
        return f"motor order {e['order_per_motor_rev']:.4g}"
    if e["kind"] == "output_order":
        return f"output order {e['order_per_output_rev']:.4g} (profile)"
    if e["kind"] == "fixed_frequency":
        return f"{e['frequency_hz']:.4g} Hz line"
    if e["kind"] == "offset_drift":
        return "offset drift"
    return e["kind"] + " (" + ", ".join(f"{k} {v:+.3g}" for k, v in e.get("parameters", {}).items()) + ")"
