"""The real KUKA iiwa logs (/work/shared/data/real, 200 Hz, output angle
only, no ground truth).  Residual-based metrics only:

* the amplitude of the lines at wave-generator orders 1, 2 and 4 in the
  torque, before and after each method, by least squares against the
  wave-generator angle ASSUMED to be GEAR_RATIO x output angle (the source
  does not state the ratio; 160 is an assumption), with a cubic in the
  output angle and the direction sign as nuisance regressors (gravity and
  friction);
* the RMS of what each method removed, and the low-frequency part of it
  (zero-phase 1 Hz low-pass): removing torque below 1 Hz is distortion,
  not ripple cancellation.

Each segment is split in halves: the Fourier table is fitted on the first
half and every method is scored on the second half only.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
from scipy import signal

from hdtools.analysis import cfilter
from . import accuracy, metrics, peers

DATA_DIR = Path("/work/shared/data/real")
GEAR_RATIO = 160.0          # assumption (not in the source data)
LINE_ORDERS = (1, 2, 4)     # wave-generator orders scored
DISTORTION_LP_HZ = 1.0
TRACK_BANDWIDTH_HZ = 10.0  # the 20 Hz default is too fast for 200 Hz sampling


def load(path: Path) -> dict:
    with open(path) as f:
        rows = list(csv.reader(f))
    head, rows = rows[0], rows[1:]
    seg = np.array([r[head.index("segment")] for r in rows])
    num = np.array([[float(r[head.index(c)]) for c in
                     ("t_s", "output_angle_rad", "output_velocity_rad_s", "torque_nm")]
                    for r in rows])
    out = {}
    for s in dict.fromkeys(seg):
        m = seg == s
        out[s] = {"t_s": num[m, 0], "output_rad": num[m, 1], "vel": num[m, 2],
                  "torque_nm": num[m, 3]}
    return out


def line_amps(x, out_rad, vel):
    wg = GEAR_RATIO * out_rad
    cols = [np.ones(len(x)), out_rad, out_rad ** 2, out_rad ** 3, np.sign(vel)]
    for o in LINE_ORDERS:
        cols += [np.cos(o * wg), np.sin(o * wg)]
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), x, rcond=None)
    return {f"wg {o}": float(np.hypot(coef[5 + 2 * i], coef[6 + 2 * i]))
            for i, o in enumerate(LINE_ORDERS)}


def noise_estimate_nm(x) -> float:
    """White-noise level from second differences (insensitive to slow torque)."""
    return float(np.std(np.diff(x, 2)) / math.sqrt(6.0))


def methods_for(seg, ts, residual_model):
    x, out_rad = seg["torque_nm"], seg["output_rad"]
    d_out = np.concatenate([[0.0], np.diff(out_rad)])
    d_wg = GEAR_RATIO * d_out
    wg = GEAR_RATIO * out_rad
    half = len(x) // 2
    speed_wg = float(np.median(np.abs(seg["vel"]))) * GEAR_RATIO
    line2_hz = 2.0 * speed_wg / (2.0 * math.pi)
    fc = min(peers.butterworth_cutoff_for(line2_hz, 20.0), 0.45 / ts)
    noise = max(noise_estimate_nm(x), 1e-3)
    ex = cfilter.ExpectedConfig()

    def kf(config, **kw):
        import ctypes
        buf = ctypes.create_string_buffer(accuracy._OPAQUE_BYTES)
        if config == "recommended":
            accuracy._lib().hd_kf_config_recommended(buf, ts, noise, accuracy.RIPPLE_SETTLE_S,
                                                     accuracy.OFFSET_SETTLE_S)
        else:
            accuracy._lib().hd_kf_config_paper(buf, ts, True)
        return accuracy._run_opaque(buf, ex, x, d_wg, d_out,
                                    track_bandwidth_hz=TRACK_BANDWIDTH_HZ)

    # Calibration on the first half, with gravity/friction nuisance columns
    # (a cubic in the output angle and the direction sign).
    nuis = np.column_stack([out_rad, out_rad ** 2, out_rad ** 3, np.sign(seg["vel"])])
    table = peers.FourierTable(range(1, 9), ()).fit(x[:half], wg[:half], out_rad[:half],
                                                    nuisance=nuis[:half])
    out = {
        "kf_recommended": kf("recommended"),
        "kf_paper6": kf("paper"),
        "butter_20db": peers.butterworth(x, ts, fc),
        "order_notch": peers.order_notch(x, wg, (2, 4), q=2.0),
        "fourier_table": table.apply(x, wg, out_rad),
        "raw": x.copy(),
    }
    if residual_model is not None:
        # The model `hdsense analyze` ends up with on this log (its own gear
        # ratio and expected torque).
        try:
            n = float(residual_model.get("gear_ratio", GEAR_RATIO))
            cfg, rex, bw = accuracy.residual_config(residual_model, ts)
            out["kf_residual"] = cfilter.run(cfg, rex, x, n * d_out, d_out,
                                             track_bandwidth_hz=bw)[
                "torque_filtered_nm"].astype(float)
        except Exception as exc:  # reported, not fatal
            out["kf_residual_error"] = str(exc)
    return out, {"noise_nm": noise, "butter_fc_hz": fc, "wg_speed_rad_s": speed_wg}


def run(use_analyze: bool = True, max_segments: int | None = None, files=None) -> dict:
    import tempfile
    res = {"gear_ratio_assumed": GEAR_RATIO, "files": {}}
    paths = files or sorted(DATA_DIR.glob("*.csv"))
    for path in paths:
        segs = load(Path(path))
        residual_model, note = None, "not run"
        if use_analyze:
            with tempfile.TemporaryDirectory() as tmp:
                residual_model, note = accuracy.analyze(Path(path), Path(tmp))
        per = []
        for name, seg in list(segs.items())[:max_segments]:
            ts = float(np.median(np.diff(seg["t_s"])))
            ys, info = methods_for(seg, ts, residual_model)
            half = len(seg["torque_nm"]) // 2
            sl = slice(half, None)
            b, a = signal.butter(2, DISTORTION_LP_HZ, fs=1.0 / ts)
            row = {"segment": name, **info, "methods": {}}
            for key, y in ys.items():
                if isinstance(y, str):
                    continue
                removed = seg["torque_nm"] - y
                row["methods"][key] = {
                    "line_amplitude_nm": line_amps(y[sl], seg["output_rad"][sl], seg["vel"][sl]),
                    "removed_rms_nm": metrics.rms(removed[sl]),
                    "removed_below_1hz_rms_nm": metrics.rms(signal.filtfilt(b, a, removed)[sl]),
                }
            per.append(row)
        # Summary per file: median over segments.
        keys = per[0]["methods"].keys() if per else []
        summary = {}
        for k in keys:
            summary[k] = {
                "line_amplitude_nm": {ln: float(np.median([p["methods"][k]["line_amplitude_nm"][ln]
                                                           for p in per]))
                                      for ln in per[0]["methods"][k]["line_amplitude_nm"]},
                "removed_rms_nm": float(np.median([p["methods"][k]["removed_rms_nm"] for p in per])),
                "removed_below_1hz_rms_nm": float(np.median(
                    [p["methods"][k]["removed_below_1hz_rms_nm"] for p in per])),
            }
        res["files"][Path(path).name] = {"segments": per, "median": summary,
                                         "residual_model": residual_model,
                                         "residual_note": note}
    return res
