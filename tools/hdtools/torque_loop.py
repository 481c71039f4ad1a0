"""The torque loop broken at the drive's input: the excitation, the loop
and plant it measures, margins, the law's PI in closed form, and the
tuning method's search over gains (docs/results/control.md, "Tuning").

One implementation for both places the loop is measured: the control
benchmark in the simulation (hdmaint.bench.control_loop, control_tune) and
a joint on its bus (`hdsense control identify` / `tune`,
hdtools.cmd_tune), where the firmware plays the same multisine
(control/hd_excite.h; tests/device/test_identify.py holds the two equal).

With x = cmd + excitation the current the drive receives,

    L(jw) = -CMD(jw) / X(jw),     P(jw) = FB(jw) / X(jw) / (N kt)

at the excited lines (a periodic excitation, an integer number of periods
after one to settle: no leakage).  P is the plant the law sees (feedback
torque per drive current), so the loop of any other PI is C(jw) P(jw) with
the law's C in closed form (`pi_response`).

Margins (`margins`): phase margin = the least 180 deg + angle L over every
gain crossover |L| = 1; gain margin = the least -20 log10 |L| over every
phase crossover angle L = -180 deg (both interpolated in log frequency);
the crossover frequency is the highest gain crossover.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

TS_S = 1e-3
MS_PERIOD = 2000        # multisine period [ticks]: 0.5 Hz lines (HD_EXCITE_PERIOD_TICKS)
MS_F_LO_HZ, MS_F_HI_HZ = 1.0, 450.0
MS_LINES = 48
MS_RMS_A = 0.4          # injection rms (2.4 N m at the output)
RIPPLE_ORDERS = (2, 4)  # the wave generator's motor orders: the gear's ripple lines
RIPPLE_GUARD_HZ = 1.5

# The tuning method's goals and grid (docs/results/control.md, "Tuning").
PM_DEG, GM_DB = 45.0, 6.0
PEAK_DB = 10.0
KP_GRID = np.geomspace(0.05, 40.0, 48)
WI_GRID_RAD_S = 2 * math.pi * np.array([1.0, 2.0, 5.0, 10.0, 20.0, 40.0])  # ki / kp
KD_GRID_S = (0.0, 5e-4, 1e-3, 1.5e-3, 2e-3, 3e-3, 4e-3)   # the feedback's rate term
MARGINS_ONLY = ("free",)   # conditions judged on the margins alone


def multisine(period: int = MS_PERIOD, f_lo: float = MS_F_LO_HZ, f_hi: float = MS_F_HI_HZ,
              lines: int = MS_LINES, rms: float = MS_RMS_A) -> tuple[np.ndarray, np.ndarray]:
    """One period of a Schroeder-phased multisine on log-spaced FFT bins:
    (signal, the excited bins)."""
    df = 1.0 / (period * TS_S)
    bins = np.unique(np.round(np.geomspace(f_lo, f_hi, lines) / df).astype(int))
    k = np.arange(len(bins))
    phase = -math.pi * k * (k + 1) / len(bins)
    t = np.arange(period)
    x = np.sum(np.cos(2 * math.pi * np.outer(bins, t) / period + phase[:, None]), axis=0)
    return x * rms / np.sqrt(np.mean(x ** 2)), bins


def line_spectrum(x: np.ndarray, period: int, bins: np.ndarray, skip: int = 1) -> np.ndarray:
    """Complex amplitude at `bins`, averaged over the whole periods after
    the first `skip` ones."""
    n = (len(x) // period - skip) * period
    seg = np.asarray(x[skip * period: skip * period + n], dtype=float)
    seg = seg.reshape(-1, period) - seg.mean()
    return np.fft.rfft(seg, axis=1)[:, bins].mean(axis=0)


def off_the_ripple(freq_hz, motor_speed_rad_s: float) -> np.ndarray:
    """The excited lines to keep on a turning joint: those farther than
    RIPPLE_GUARD_HZ from the RIPPLE_ORDERS motor lines at this speed (the
    ripple, not the excitation, moves the lines near them)."""
    f = np.asarray(freq_hz, dtype=float)
    keep = np.ones(len(f), dtype=bool)
    for order in RIPPLE_ORDERS:
        keep &= np.abs(f - order * abs(motor_speed_rad_s) / (2 * math.pi)) > RIPPLE_GUARD_HZ
    return keep


def loop_response(cmd_a, drive_a, fb_nm, nkt: float, bins=None, period: int = MS_PERIOD,
                  skip: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(freq_hz, L, P) from per-tick records of a periodic excitation: the
    law's current, the drive's (law + excitation) and the feedback torque,
    over the whole periods after `skip`; bins: the excited ones (None:
    multisine()'s)."""
    if bins is None:
        bins = multisine()[1]
    spec_x = line_spectrum(drive_a, period, bins, skip)
    loop = -line_spectrum(cmd_a, period, bins, skip) / spec_x
    plant = line_spectrum(fb_nm, period, bins, skip) / spec_x / nkt
    return bins / (period * TS_S), loop, plant


@dataclass
class Response:
    freq_hz: np.ndarray
    loop: np.ndarray          # L(jw)
    plant: np.ndarray         # P(jw): feedback torque per drive current / (N kt)
    true_plant: np.ndarray    # the same for the true output torque

    def to_json(self) -> dict:
        return {"freq_hz": self.freq_hz.round(3).tolist(),
                "loop_db": (20 * np.log10(np.abs(self.loop))).round(2).tolist(),
                "loop_phase_deg": np.degrees(np.angle(self.loop)).round(1).tolist()}


def pi_response(freq_hz, kp: float, ki: float, kd: float = 0.0, ts: float = TS_S) -> np.ndarray:
    """The law's PI (hd_ctrl.c: u = kp e + I, I += ki ts e after u) and its
    rate term on the feedback (u -= kd (fb - fb_prev) / ts):
    C(z) = kp + ki ts / (z - 1) + kd (1 - 1/z) / ts, at z = exp(j w ts).
    With kd the feedback's path; the setpoint's is the same with kd = 0."""
    z = np.exp(1j * 2 * math.pi * np.asarray(freq_hz) * ts)
    return kp + ki * ts / (z - 1.0) + kd * (1.0 - 1.0 / z) / ts


def _crossings(f: np.ndarray, y: np.ndarray) -> list[tuple[int, float]]:
    """(i, t): y changes sign between f[i] and f[i+1], at fraction t (linear
    in log f)."""
    out = []
    for i in range(len(y) - 1):
        if y[i] == 0.0 or (y[i] > 0) != (y[i + 1] > 0):
            t = 0.0 if y[i] == y[i + 1] else y[i] / (y[i] - y[i + 1])
            out.append((i, t))
    return out


def _at(f: np.ndarray, i: int, t: float) -> float:
    return float(np.exp(np.log(f[i]) + t * (np.log(f[i + 1]) - np.log(f[i]))))


def margins(freq_hz, loop) -> dict:
    """Phase margin [deg], gain margin [dB], crossover [Hz] of L sampled at
    freq_hz (ascending).  No gain crossover: pm = inf; no phase crossover:
    gm = inf (within the band measured)."""
    f = np.asarray(freq_hz, dtype=float)
    if not np.all(np.abs(loop) > 0):
        return {"pm_deg": math.inf, "gm_db": math.inf, "crossover_hz": None,
                "phase_crossover_hz": None}
    mag_db = 20 * np.log10(np.abs(loop))
    phase = np.unwrap(np.angle(loop))  # rad, continuous from the lowest line's (-pi, pi]
    pm, wc = math.inf, None
    for i, t in _crossings(f, mag_db):
        ph = phase[i] + t * (phase[i + 1] - phase[i])
        deg = math.degrees(ph)
        pm = min(pm, 180.0 + deg - 360.0 * math.ceil(deg / 360.0))  # the angle in (-360, 0]
        wc = _at(f, i, t)
    gm, w180 = math.inf, None
    for m in range(-4, 3):                      # phase crossings of -180 + 360 m
        target = -math.pi + 2 * math.pi * m
        for i, t in _crossings(f, phase - target):
            g = -(mag_db[i] + t * (mag_db[i + 1] - mag_db[i]))
            if g < gm:
                gm, w180 = g, _at(f, i, t)
    return {"pm_deg": pm, "gm_db": gm, "crossover_hz": wc, "phase_crossover_hz": w180}


def meets(m: dict, pm_deg: float = 45.0, gm_db: float = 6.0) -> bool:
    return m["pm_deg"] >= pm_deg and m["gm_db"] >= gm_db
def bandwidth_hz(freq_hz, h) -> float | None:
    """The lowest frequency where |h| falls below 1/sqrt(2) (log-linear
    interpolation); None if |h| is below it at the lowest line, inf if
    never within the band."""
    f = np.asarray(freq_hz, dtype=float)
    below = np.abs(h) < 1.0 / math.sqrt(2.0)
    if below[0]:
        return None
    idx = np.flatnonzero(below)
    if len(idx) == 0:
        return math.inf
    i = idx[0]
    a0, a1 = 20 * np.log10(np.abs(h[i - 1])), 20 * np.log10(np.abs(h[i]))
    t = (a0 + 3.0103) / (a0 - a1) if a0 != a1 else 0.0
    return float(np.exp(np.log(f[i - 1]) + t * (np.log(f[i]) - np.log(f[i - 1]))))


@dataclass
class PlantAt:
    condition: str
    freq_hz: np.ndarray
    p_fb: np.ndarray
    p_true: np.ndarray


def predict(p: PlantAt, kp: float, ki: float, ff: float,
            kd: float = 0.0) -> tuple[dict, float | None]:
    """Margins of C P_fb and the predicted tracking bandwidth; margins gets
    the tracking peak (peak_db) too.  The rate term acts on the feedback
    only: L = C_fb P_fb, H = P_true (ff + C_ref) / (1 + L)."""
    loop = pi_response(p.freq_hz, kp, ki, kd) * p.p_fb
    h = p.p_true * (ff + pi_response(p.freq_hz, kp, ki)) / (1.0 + loop)
    m = margins(p.freq_hz, loop)
    m["peak_db"] = float(20 * np.log10(np.abs(h).max()))
    return m, bandwidth_hz(p.freq_hz, h)


def acceptable(m: dict, tracking: bool = True) -> bool:
    """The margins, and no tracking peak above PEAK_DB (a loop whose
    feedback lags can meet the margins with a proportional kick that
    overshoots many-fold: the peak rules it out).  A margins-only
    condition (the free output: nothing holds the torque, it tracks no
    setpoint; its "response" is the free flexspline mode) has no peak bound."""
    return meets(m, PM_DEG, GM_DB) and (not tracking or m.get("peak_db", 0.0) <= PEAK_DB)


def _score(bws, crossovers) -> tuple[float, float]:
    """(mean log crossover, mean log predicted bandwidth) over the conditions:
    a crossover or bandwidth below the lowest line counts as 0.5 Hz, a
    bandwidth beyond the band as 500 Hz."""
    w = [0.5 if x is None else x for x in crossovers]
    b = [0.5 if x is None else min(x, 500.0) for x in bws]
    return float(np.mean(np.log(w))), float(np.mean(np.log(b)))


def candidates(plants: list[PlantAt], ff: float) -> list[tuple[float, float, float, dict]]:
    """The grid's gains meeting the margins in every condition, best first:
    (kp, ki, kd, {condition: predicted margins and bandwidth})."""
    scored = []
    tracking = [p.condition not in MARGINS_ONLY for p in plants]
    for kp, wi, kd in itertools.product(KP_GRID, WI_GRID_RAD_S, KD_GRID_S):
        ki = float(kp * wi)
        if ki > 5000.0:
            continue
        preds = [predict(p, float(kp), ki, ff, float(kd)) for p in plants]
        if not all(acceptable(m, t) for (m, _), t in zip(preds, tracking)):
            continue
        score = _score([b for (_, b), t in zip(preds, tracking) if t],
                       [m["crossover_hz"] for m, _ in preds])
        scored.append((score, (float(kp), ki, float(kd),
                               {p.condition: {"margins": m, "bandwidth_hz": b}
                                for p, (m, b) in zip(plants, preds)})))
    scored.sort(key=lambda x: x[0], reverse=True)
    return [c for _, c in scored]


