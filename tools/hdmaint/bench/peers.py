"""Peer methods the filter is compared with.  Independent implementations in
numpy/scipy; none of them uses the project's filter.  All are causal (each
output sample uses only samples up to and including its own), as they would
be in a controller.
"""
from __future__ import annotations

import numpy as np
from scipy import signal


def butterworth(torque_nm: np.ndarray, ts_s: float, cutoff_hz: float) -> np.ndarray:
    """2nd-order Butterworth low-pass, causal, started at rest on the first
    sample (no start-up transient)."""
    b, a = signal.butter(2, cutoff_hz, fs=1.0 / ts_s)
    zi = signal.lfilter_zi(b, a) * torque_nm[0]
    return signal.lfilter(b, a, torque_nm, zi=zi)[0]


def butterworth_cutoff_for(line_hz: float, attenuation_db: float) -> float:
    """Cutoff of a 2nd-order Butterworth that attenuates line_hz by
    attenuation_db: |H|^2 = 1 / (1 + (f/fc)^4)."""
    return line_hz / (10.0 ** (attenuation_db / 10.0) - 1.0) ** 0.25


def order_notch(torque_nm: np.ndarray, angle_rad: np.ndarray, orders, per_rev: int = 512,
                q: float = 2.0) -> np.ndarray:
    """Order tracking plus notch (the angle-domain approach of IEEE/ASME
    TMech 22(4), 2017): resample the torque on a uniform grid of travelled
    angle, notch the given orders (cycles per rev of that angle) there, and
    map the removed part back to time.

    * Travelled angle s = cumulative |d angle|, so reversals and standstill
      are handled (s is non-decreasing; order-o ripple stays order o in s).
    * Grid point s_j = j * 2 pi / per_rev is linearly interpolated from the
      two time samples around it; it exists once a time sample reaches s_j.
    * Notches: scipy.signal.iirnotch per order, bandwidth order / q, run
      causally along the grid.
    * Back to time: ripple(s_k) is linearly extrapolated from the last two
      grid points at or before s_k (causal), and filtered = torque - ripple.
      At standstill no new grid points arrive: the ripple estimate is held
      and the torque itself still passes through.
    """
    x = np.asarray(torque_nm, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(angle_rad)))])
    step = 2.0 * np.pi / per_rev
    n_grid = int(np.floor(s[-1] / step)) + 1
    if n_grid < 4:
        return x.copy()  # never moved: nothing to resample
    # Strictly increasing knots for interpolation (drop stalled samples).
    keep = np.concatenate([[True], np.diff(s) > 0.0])
    sg = np.arange(n_grid) * step
    xg = np.interp(sg, s[keep], x[keep])
    yg = xg.copy()
    for order in orders:
        b, a = signal.iirnotch(order, q, fs=per_rev)
        zi = signal.lfilter_zi(b, a) * yg[0]
        yg = signal.lfilter(b, a, yg, zi=zi)[0]
    rg = xg - yg
    j = np.minimum(np.floor(s / step).astype(int), n_grid - 1)
    jm = np.maximum(j - 1, 0)
    frac = (s - sg[j]) / step
    ripple = rg[j] + (rg[j] - rg[jm]) * frac
    return x - ripple


class FourierTable:
    """Angle-indexed Fourier compensation table (the Godler / lookup-table
    family): ripple(theta_m, theta_o) = sum over motor (wave-generator)
    harmonics 1..motor_max and output harmonics, fitted offline by linear
    least squares on a calibration run at constant speed and load, then
    subtracted unchanged from every later run."""

    def __init__(self, motor_orders=range(1, 9), output_orders=(1,)):
        self.motor_orders = list(motor_orders)
        self.output_orders = list(output_orders)
        self.coef = None

    def _basis(self, motor_rad, output_rad):
        cols = []
        for o in self.motor_orders:
            cols += [np.cos(o * motor_rad), np.sin(o * motor_rad)]
        for o in self.output_orders:
            cols += [np.cos(o * output_rad), np.sin(o * output_rad)]
        return np.column_stack(cols)

    def fit(self, torque_nm, motor_rad, output_rad, nuisance=None):
        """Fits torque = constant (+ nuisance columns, e.g. a gravity model)
        + ripple; only the ripple part goes into the table."""
        basis = self._basis(motor_rad, output_rad)
        extra = [np.ones(len(torque_nm))]
        if nuisance is not None:
            extra += list(np.asarray(nuisance, dtype=float).reshape(len(torque_nm), -1).T)
        a = np.column_stack(extra + [basis])
        coef, *_ = np.linalg.lstsq(a, torque_nm, rcond=None)
        self.coef = coef[len(extra):]
        return self

    def ripple(self, motor_rad, output_rad):
        return self._basis(motor_rad, output_rad) @ self.coef

    def apply(self, torque_nm, motor_rad, output_rad):
        return torque_nm - self.ripple(motor_rad, output_rad)
