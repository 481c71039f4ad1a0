"""Current-to-torque parameters of a joint from a log (docs/design/slow-torque.md,
"Motor current").  The firmware's model (filter/hd_expected.h):

    u = k_i i - J_r a - b_r w - Fc_r sgn(w)
    T = u                  where u goes with the motion (the motor drives)
    T = (k_b / k_i) u      where it opposes it (the load drives the motor)
                                                   (+ a constant: the sensor zero)

with i the motor current, w and a the output velocity and acceleration, k_i
= N eta kt the output torque per amp, k_b = N kt / eta_b its value when the
gear passes power backwards, J_r, b_r, Fc_r what the drive between the
current and the sensor absorbs, referred to the output.  For a given k_b / k_i
the model is linear in the rest, and for given rest linear in k_b / k_i:
the fit alternates the two least-squares problems (the direction of each
sample from the sign of u w) and takes the standard errors from the joint
Jacobian at the solution.  Least squares
on the measured torque against i, a, w and sgn(w), all low-passed alike (the
fast ripple and the sensor noise are not part of the slow relation) and
decimated to about two samples per filter time constant, so that the
residuals are nearly independent and the textbook standard errors hold.
What passes the low-pass but is not load: output-locked lines (slow at any
speed) are either subtracted (a stored profile, `--profile`: on an arm the
gravity torque is itself an output-order-1 function and nuisance columns
would take it) or fitted alongside as nuisance columns (orders
1..OUTPUT_ORDERS), and samples where the motor turns so slowly that its
lines pass too (below SLOW_MOTOR_RAD_S) are left out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

from .safeio import UsageError

CUTOFF_HZ = 5.0          # low-pass of every column before the fit
DECIMATE_HZ = 10.0       # fit samples per second (about 2 per time constant)
MIN_FIT_SAMPLES = 100    # 10 s of motion at DECIMATE_HZ
MIN_REVERSAL_SHARE = 0.1  # each direction at least this share of the moving samples
MOVING_RAD_S = 0.02      # |w| above this is motion
MAX_REL_ERR_GAIN = 0.05  # k_i must be known to 5 % (1 sigma)
SIGNIFICANT = 2.0        # a friction/inertia term below 2 sigma is written as 0
OUTPUT_ORDERS = 3        # output-locked nuisance lines
# motor order 2 at 3 x the cutoff: its line is 38 dB down after the
# two-pass filter; below that (and at standstill, where a motor line is a
# constant of the posture) the samples are left out
SLOW_MOTOR_RAD_S = 3 * 2 * math.pi * CUTOFF_HZ / 2

ALTERNATIONS = 50         # alternating least squares: at most this many rounds
CONVERGED = 1e-9          # ... until k_b / k_i changes by less than this

NAMES = ("current_nm_per_a", "current_inertia_kgm2", "current_viscous_nm_s_rad",
         "current_coulomb_nm", "zero_nm", "current_backdrive_nm_per_a")
UNITS = ("N m/A", "kg m^2", "N m s/rad", "N m", "N m", "N m/A")
DRIVE_TERMS = 4           # k_i, J_r, b_r, Fc_r: the columns scaled by k_b / k_i


@dataclass
class Fit:
    value: dict
    sigma: dict
    written: dict            # what goes into the firmware configuration
    notes: list
    residual_rms_nm: float
    samples: int             # decimated samples in the fit
    seconds: float


def _lowpass(x, ts_s):
    b, a = signal.butter(2, CUTOFF_HZ, fs=1.0 / ts_s)
    return signal.filtfilt(b, a, x)


def profile_torque(piece, lines) -> np.ndarray:
    """The ripple a profile (lines of profile.json: lock, order, a_nm, b_nm)
    predicts at the piece's absolute angles."""
    r = np.zeros(len(piece))
    for ln in lines:
        ang = piece.motor_angle_rad if ln["lock"] == "motor" else piece.output_angle_rad
        if ang is None:
            raise UsageError(f"the profile has a {ln['lock']}-locked line and the log no "
                             f"{ln['lock']}_angle_rad column")
        k = float(ln["order"]) * np.asarray(ang, float)
        r += ln["a_nm"] * np.cos(k) + ln["b_nm"] * np.sin(k)
    return r


def _columns(piece, ts_s, gear_ratio, lines=None, nuisance=True):
    """([torque, current, w, a, sgn, nuisance...], w) of one piece,
    low-passed and decimated; None if the piece is too short, "angle" if it
    has no way to the output velocity."""
    n = len(piece)
    if n < 64:
        return None
    if piece.output_velocity_rad_s is not None:
        w = np.asarray(piece.output_velocity_rad_s, float)
    elif piece.output_angle_rad is not None:
        w = np.gradient(np.asarray(piece.output_angle_rad, float), ts_s)
    elif piece.motor_angle_rad is not None and gear_ratio:
        w = np.gradient(np.asarray(piece.motor_angle_rad, float), ts_s) / gear_ratio
    else:
        return "angle"
    i = np.asarray(piece.motor_current_a, float)
    ok = np.isfinite(i) & np.isfinite(w) & np.isfinite(piece.torque_nm)
    if not ok.all():
        # a gap in the current column: fill it for the filter, drop it after
        idx = np.arange(n)
        if ok.sum() < 64:
            return None
        i = np.interp(idx, idx[ok], i[ok])
        w = np.interp(idx, idx[ok], w[ok])
    t = np.asarray(piece.torque_nm, float)
    if lines:
        t = t - profile_torque(piece, lines)
    t = np.where(np.isfinite(t), t, np.interp(np.arange(n), np.flatnonzero(np.isfinite(t)),
                                              t[np.isfinite(t)]))
    wl = _lowpass(w, ts_s)
    sg = np.where(np.abs(wl) > MOVING_RAD_S, np.sign(wl), wl / MOVING_RAD_S)
    cols = [_lowpass(t, ts_s), _lowpass(i, ts_s), wl, np.gradient(wl, ts_s), _lowpass(sg, ts_s)]
    theta = (np.asarray(piece.output_angle_rad, float) if piece.output_angle_rad is not None
             else np.cumsum(w) * ts_s)
    for k in range(1, OUTPUT_ORDERS + 1 if nuisance else 1):
        cols += [_lowpass(np.cos(k * theta), ts_s), _lowpass(np.sin(k * theta), ts_s)]
    step = max(1, int(round(1.0 / (DECIMATE_HZ * ts_s))))
    keep = np.zeros(n, bool)
    keep[step // 2::step] = True
    keep &= ok
    if gear_ratio or piece.motor_angle_rad is not None:
        n_ratio = gear_ratio or _ratio(piece)
        keep &= np.abs(wl) * n_ratio > SLOW_MOTOR_RAD_S
    edge = int(round(0.5 / ts_s))    # filter start-up at both ends
    keep[:edge] = keep[n - edge:] = False
    return [c[keep] for c in cols], wl[keep]


def _ratio(piece) -> float:
    """Motor over output travel of a piece (its gear ratio), 1 if unknown."""
    if piece.motor_angle_rad is None or piece.output_angle_rad is None:
        return 1.0
    o = float(np.sum(np.abs(np.diff(piece.output_angle_rad))))
    return float(np.sum(np.abs(np.diff(piece.motor_angle_rad)))) / o if o > 0 else 1.0


def fit(data, gear_ratio: float | None = None, name: str = "log", lines=None) -> Fit:
    """lines: a stored profile's lines to subtract (then no nuisance
    columns)."""
    if not data.has_current:
        raise UsageError(f"{name}: no motor_current_a column: nothing to fit")
    parts, speeds = [], []
    for p in data.pieces:
        c = _columns(p, data.ts_s, gear_ratio, lines, nuisance=not lines)
        if c == "angle":
            raise UsageError(f"{name}: no output_velocity_rad_s or output_angle_rad column "
                             "(with only a motor angle, give --gear-ratio)")
        if c is not None:
            parts.append(c[0])
            speeds.append(c[1])
    if not parts:
        raise UsageError(f"{name}: no stretch long enough to low-pass ({CUTOFF_HZ:g} Hz)")
    T, I, W, A, S = (np.concatenate([p[k] for p in parts]) for k in range(5))
    nuis = [np.concatenate([p[k] for p in parts]) for k in range(5, len(parts[0]))]
    w = np.concatenate(speeds)
    moving = np.abs(w) > MOVING_RAD_S
    if len(T) < MIN_FIT_SAMPLES:
        raise UsageError(f"{name}: {len(T) / DECIMATE_HZ:.0f} s of usable data; the fit needs "
                         f"at least {MIN_FIT_SAMPLES / DECIMATE_HZ:.0f} s")
    fwd, back = (moving & (w > 0)).sum(), (moving & (w < 0)).sum()
    if min(fwd, back) < MIN_REVERSAL_SHARE * max(1, moving.sum()):
        raise UsageError(f"{name}: the joint turns one way only ({fwd} vs {back} fit samples "
                         "forward/backward): Coulomb friction cannot be told from the sensor "
                         "zero; log a run with reversals")
    drive = np.column_stack([I, -A, -W, -S])
    rest = np.column_stack([np.ones(len(T))] + nuis)
    coef, ratio, backdriven, res = _two_efficiencies(T, drive, rest, w, moving)
    u = drive @ coef[:DRIVE_TERMS]
    jac = np.column_stack([drive * (1.0 + backdriven * (ratio - 1.0))[:, None], rest,
                           backdriven * u])
    dof = max(1, len(T) - jac.shape[1])
    s2 = float(res @ res) / dof
    cov = s2 * np.linalg.pinv(jac.T @ jac)
    sig = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    value = dict(zip(NAMES, (float(v) for v in coef[:len(NAMES) - 1])))
    sigma = dict(zip(NAMES, (float(v) for v in sig[:len(NAMES) - 1])))
    ki, ski = value["current_nm_per_a"], sigma["current_nm_per_a"]
    # k_b = ratio k_i: its error from both (first order, with their covariance)
    i_ratio = jac.shape[1] - 1
    kb = ratio * ki
    var_kb = (ki ** 2 * cov[i_ratio, i_ratio] + ratio ** 2 * cov[0, 0] +
              2 * ki * ratio * cov[0, i_ratio])
    value["current_backdrive_nm_per_a"] = float(kb)
    sigma["current_backdrive_nm_per_a"] = float(math.sqrt(max(var_kb, 0.0)))
    sigma_ratio = float(math.sqrt(max(cov[i_ratio, i_ratio], 0.0)))
    if not (ki > 0 and ski < MAX_REL_ERR_GAIN * ki):
        raise UsageError(f"{name}: the torque per amp is not identifiable ({ki:.4g} +- "
                         f"{ski:.2g} N m/A): the current must vary with the load "
                         "(log a run with changing load or acceleration)")
    notes, written = [], {"current_nm_per_a": ki}
    for k in NAMES[1:4]:
        v, sd = value[k], sigma[k]
        if v < 0 and abs(v) > SIGNIFICANT * sd:
            notes.append(f"{k} = {v:.4g} +- {sd:.2g} is negative (the model does not fit: "
                         "direction-dependent efficiency?); written as 0")
            written[k] = 0.0
        elif abs(v) < SIGNIFICANT * sd:
            notes.append(f"{k} = {v:.3g} +- {sd:.2g} is below {SIGNIFICANT:g} sigma; written as 0")
            written[k] = 0.0
        else:
            written[k] = v
    n_back = int((moving & (backdriven > 0.5)).sum())
    if n_back < MIN_REVERSAL_SHARE * max(1, moving.sum()):
        notes.append(f"the load drove the motor in {n_back} fit samples only: one efficiency "
                     "(current_backdrive_nm_per_a written as 0)")
        written["current_backdrive_nm_per_a"] = 0.0
    elif abs(ratio - 1.0) < SIGNIFICANT * sigma_ratio:
        notes.append(f"k_b / k_i = {ratio:.4f} +- {sigma_ratio:.2g} is 1 within "
                     f"{SIGNIFICANT:g} sigma: one efficiency (written as 0)")
        written["current_backdrive_nm_per_a"] = 0.0
    else:
        written["current_backdrive_nm_per_a"] = float(kb)
        notes.append(f"k_b / k_i = {ratio:.4f} +- {sigma_ratio:.2g}: the gear passes power "
                     f"back with 1 / (eta eta_b) = {ratio:.4f} times the gain")
    if gear_ratio:
        notes.append(f"eta kt = k_i / N = {ki / gear_ratio:.5g} +- {ski / gear_ratio:.2g} N m/A "
                     f"at the motor (gear ratio {gear_ratio:g})")
    # what the model misses: the filter is told it as T_cur's variance
    written["current_error_nm"] = float(math.sqrt(s2))
    return Fit(value, sigma, written, notes, float(math.sqrt(s2)), len(T),
               len(T) / DECIMATE_HZ)


def _two_efficiencies(T, drive, rest, w, moving):
    """Alternating least squares for T = m * (drive @ c) + rest @ d with
    m = 1 + backdriven * (ratio - 1), backdriven = 1 where drive @ c opposes
    the motion (u w < 0).  Returns (coefficients c then d, ratio,
    backdriven, residual)."""
    ratio = 1.0
    back = np.zeros(len(T))
    n_drive = drive.shape[1]
    for _ in range(ALTERNATIONS):
        m = 1.0 + back * (ratio - 1.0)
        X = np.column_stack([drive * m[:, None], rest])
        coef, *_ = np.linalg.lstsq(X, T, rcond=None)
        u = drive @ coef[:n_drive]
        back = ((u * w < 0) & moving).astype(float)
        bu = back * u
        left = T - rest @ coef[n_drive:] - u
        new = 1.0 + float(bu @ left) / float(bu @ bu) if float(bu @ bu) > 0 else 1.0
        done = abs(new - ratio) < CONVERGED
        ratio = new
        if done:
            break
    m = 1.0 + back * (ratio - 1.0)
    X = np.column_stack([drive * m[:, None], rest])
    coef, *_ = np.linalg.lstsq(X, T, rcond=None)
    return coef, ratio, back, T - X @ coef


def config_text(f: Fit, source: str) -> str:
    lines = [f"# motor-current model fitted by hdsense current from {source}",
             f"# ({f.samples} fit samples, residual {f.residual_rms_nm:.3g} N m RMS)"]
    lines += [f"{k} = {v:.6g}" for k, v in f.written.items()]
    return "\n".join(lines) + "\n"
