"""A line's amplitude in the filtered (or raw) torque of replayed runs: the
measure the add-and-verify loop (augment.py) and the analysis report judge
lines by."""
from __future__ import annotations

import math

import numpy as np

from . import detect, spectra

LINE_FIT_MAX_SAMPLES = 150_000


def _signal(runs, raw):
    return [(np.asarray(r.torque_nm, float) if raw else r.filtered)[r.warm:] for r in runs]


def line_amplitude(runs, kind, order, raw=False):
    """Least-squares amplitude of the line in the filtered (or raw) torque
    (slow torque removed first, see spectra.highpass_for_line)."""
    if not runs:
        return float("nan")
    sig = _signal(runs, raw)
    if kind == "motor_order":
        ph = [order * r.motor_angle_rad[r.warm:] for r in runs]
    elif kind == "output_order":
        ph = [order * r.output_angle_rad[r.warm:] for r in runs]
    else:
        ph = [2 * math.pi * order * np.asarray(r.t_s[r.warm:], float) for r in runs]
    ts = float(np.median(np.diff(runs[0].t_s))) if len(runs[0].t_s) > 1 else 1e-3
    sig = spectra.highpass_for_line(sig, ph, ts)
    amp, _, _ = spectra.fit_line(detect._decimated(sig, LINE_FIT_MAX_SAMPLES),
                                 detect._decimated(ph, LINE_FIT_MAX_SAMPLES))
    return amp


def spectral_line_amplitude(runs, kind, order, raw=False):
    """Line amplitude from the averaged order (or time) spectrum: the peak
    within +-2 bins of the line.  Each spectral window has its own phase,
    so this survives a slowly drifting phase (inexact gear ratio, real
    logs) where one global least-squares fit does not; it includes the
    noise floor in that bin."""
    if not runs:
        return float("nan")
    sig = _signal(runs, raw)
    ts = float(np.median(np.diff(runs[0].t_s))) if len(runs[0].t_s) > 1 else 1e-3
    if kind == "fixed_frequency":
        spec = spectra.time_spectrum(sig, ts)
    else:
        ang = [(r.motor_angle_rad if kind == "motor_order" else r.output_angle_rad)[r.warm:]
               for r in runs]
        spec = spectra.order_spectrum(sig, ang)
    if spec is None:
        return float("nan")
    i = int(round((order - spec.axis[0]) / (spec.axis[1] - spec.axis[0])))
    if i < 1 or i >= len(spec.axis) - 2:
        return float("nan")
    return float(np.sqrt(np.max(spec.amp2[max(i - 2, 0):i + 3])))


def lines_left(runs, model):
    """Sum of the averaged-spectrum amplitudes of the model's motor-locked and
    fixed lines in the filtered torque (output-locked lines are left out: at a
    joint's low output orders they may be real torque)."""
    kinds = {"motor": "motor_order", "fixed": "fixed_frequency"}
    amps = [spectral_line_amplitude(runs, kinds[b.lock], b.order)
            for b in model.blocks if b.lock in kinds]
    return float(np.nansum(amps)) if amps else 0.0
