"""Spectra of the residual in three domains and sinusoid fits.

- order spectrum over an angle (motor or output): each monotonic run of the
  angle is resampled uniformly in angle and Welch-averaged; a line locked to
  that angle stays sharp whatever the speed does;
- time spectrum: Welch over time; a fixed-frequency line stays sharp;
- line fits: least squares of sin/cos at phase = order x angle (or 2 pi f t)
  over all pieces at once, amplitude in N m.

Amplitudes are scaled so that a sinusoid of amplitude A shows as A at its
peak (Hann window, amplitude normalisation)."""
from __future__ import annotations

import numpy as np

MAX_NPERSEG = 1 << 17
FLOOR_HALF_WIDTH = 30   # bins each side for the local floor
GUARD_BINS = 3          # bins each side of a peak kept out of its floor


class Spectrum:
    def __init__(self, axis, amp2, unit, resolution, n_windows):
        self.axis = axis            # cycles per rev, or Hz
        self.amp2 = amp2            # mean squared line amplitude per bin [Nm^2]
        self.unit = unit
        self.resolution = resolution
        self.n_windows = n_windows

    def amplitude(self):
        return np.sqrt(self.amp2)


def _welch_uniform(x_list, step, nperseg):
    """Averaged |Hann DFT|^2 amplitude spectrum of uniformly spaced pieces."""
    w = np.hanning(nperseg)
    scale = 2.0 / w.sum()
    acc = np.zeros(nperseg // 2 + 1)
    count = 0
    for x in x_list:
        if len(x) < nperseg:
            continue
        hop = nperseg // 2
        for a in range(0, len(x) - nperseg + 1, hop):
            seg = x[a:a + nperseg]
            # Linear detrend: slow load changes leak less into the floor.
            k = np.arange(nperseg) - (nperseg - 1) / 2
            seg = seg - seg.mean() - k * (k @ seg) / (k @ k)
            acc += np.abs(np.fft.rfft(seg * w) * scale) ** 2
            count += 1
    if count == 0:
        return None, 0
    freqs = np.fft.rfftfreq(nperseg, step)
    return (freqs, acc / count), count


def _choose_nperseg(lengths, target_windows=8, min_len=64):
    longest = max(lengths) if lengths else 0
    total = sum(lengths)
    if longest < min_len:
        return 0
    n = 1 << int(np.floor(np.log2(longest)))
    # Aim for ~target_windows windows in total (resolution vs variance).
    while n > 256 and total / n < target_windows / 2:
        n //= 2
    return min(n, MAX_NPERSEG)


def time_spectrum(signals, ts_s):
    lengths = [len(s) for s in signals]
    nper = _choose_nperseg(lengths)
    if not nper:
        return None
    res, count = _welch_uniform(signals, ts_s, nper)
    if res is None:
        return None
    f, a2 = res
    return Spectrum(f, a2, "Hz", 1.0 / (nper * ts_s), count)


def monotonic_runs(angle, min_len=64, min_speed_frac=0.05):
    """(start, end) index ranges over which the angle moves one way at a
    speed above min_speed_frac of the median moving speed."""
    d = np.diff(angle)
    if len(d) == 0:
        return []
    speed = np.abs(d)
    ref = np.median(speed[speed > 0]) if np.any(speed > 0) else 0.0
    if ref == 0:
        return []
    sign = np.sign(d) * (speed > min_speed_frac * ref)
    runs = []
    start = 0
    for i in np.flatnonzero(np.diff(sign) != 0) + 1:
        if sign[start] != 0 and i - start >= min_len:
            runs.append((start, i + 1))
        start = i
    if sign[start] != 0 and len(d) - start >= min_len:
        runs.append((start, len(d) + 1))
    return runs


def order_spectrum(signals, angles, min_len=64):
    """Order spectrum (cycles per rev of the given angle) of the signals,
    resampled uniformly in angle over monotonic runs."""
    runs = []
    steps = []
    for x, th in zip(signals, angles):
        for a, b in monotonic_runs(th, min_len):
            runs.append((x[a:b], th[a:b]))
            steps.append(np.median(np.abs(np.diff(th[a:b]))))
    if not runs:
        return None
    step = float(np.median(steps))
    resampled = []
    for x, th in runs:
        if th[-1] < th[0]:
            th, x = th[::-1], x[::-1]
        grid = np.arange(th[0], th[-1], step)
        if len(grid) >= min_len:
            resampled.append(np.interp(grid, th, x))
    if not resampled:
        return None
    nper = _choose_nperseg([len(r) for r in resampled])
    if not nper:
        return None
    res, count = _welch_uniform(resampled, step / (2 * np.pi), nper)
    if res is None:
        return None
    o, a2 = res
    return Spectrum(o, a2, "/rev", 1.0 / (nper * step / (2 * np.pi)), count)


def local_floor(amp2):
    """Running median of the power excluding a guard band around each bin."""
    from scipy.ndimage import median_filter
    size = 2 * FLOOR_HALF_WIDTH + 1
    fl = median_filter(amp2, size=size, mode="nearest")
    return np.maximum(fl, np.finfo(float).tiny)


def peak_ratio_at(spec: Spectrum, x, half_bins=2):
    """Peak power near x over the local floor (guard band excluded)."""
    if spec is None or not np.isfinite(x):
        return 0.0, 0.0
    i = int(round((x - spec.axis[0]) / (spec.axis[1] - spec.axis[0])))
    if i < 1 or i >= len(spec.axis) - 1:
        return 0.0, 0.0
    lo, hi = max(i - half_bins, 0), min(i + half_bins + 1, len(spec.axis))
    j = lo + int(np.argmax(spec.amp2[lo:hi]))
    a = max(j - FLOOR_HALF_WIDTH, 0)
    b = min(j + FLOOR_HALF_WIDTH + 1, len(spec.axis))
    neigh = np.r_[spec.amp2[a:max(j - GUARD_BINS, a)], spec.amp2[min(j + GUARD_BINS + 1, b):b]]
    floor = np.median(neigh) if len(neigh) else spec.amp2[j]
    return float(spec.amp2[j] / max(floor, 1e-30)), float(spec.axis[j])


def find_peaks(spec: Spectrum, min_ratio, lo=None, hi=None, max_peaks=20):
    """Local maxima over the local floor by at least min_ratio (power)."""
    if spec is None:
        return []
    a2 = spec.amp2
    fl = local_floor(a2)
    ratio = a2 / fl
    ok = np.zeros(len(a2), bool)
    ok[1:-1] = (a2[1:-1] >= a2[:-2]) & (a2[1:-1] >= a2[2:]) & (ratio[1:-1] >= min_ratio)
    if lo is not None:
        ok &= spec.axis >= lo
    if hi is not None:
        ok &= spec.axis <= hi
    idx = np.flatnonzero(ok)
    idx = idx[np.argsort(ratio[idx])[::-1]][:max_peaks]
    out = []
    for i in idx:
        # Parabolic interpolation of log power for a finer position.
        y0, y1, y2 = np.log(a2[i - 1] + 1e-30), np.log(a2[i] + 1e-30), np.log(a2[i + 1] + 1e-30)
        den = y0 - 2 * y1 + y2
        d = 0.5 * (y0 - y2) / den if den < 0 else 0.0
        x = spec.axis[i] + d * (spec.axis[1] - spec.axis[0])
        out.append({"at": float(x), "ratio": float(ratio[i]), "amplitude_nm": float(np.sqrt(a2[i]))})
    return out


class _Detrender:
    """Removes each piece's mean and slope from concatenated arrays (the
    per-piece nuisance of the line fits), in O(n) numpy."""

    def __init__(self, lengths):
        self.lengths = np.asarray(lengths, int)
        self.starts = np.r_[0, np.cumsum(self.lengths)[:-1]]
        k = np.concatenate([np.arange(n) - (n - 1) / 2.0 for n in self.lengths])
        self.k = k
        self.kk = np.maximum(np.add.reduceat(k * k, self.starts), 1e-12)

    def __call__(self, v):
        means = np.add.reduceat(v, self.starts) / self.lengths
        v = v - np.repeat(means, self.lengths)
        slopes = np.add.reduceat(v * self.k, self.starts) / self.kk
        return v - np.repeat(slopes, self.lengths) * self.k


_DETRENDERS: dict = {}


def _detrender(lengths):
    if lengths not in _DETRENDERS:
        if len(_DETRENDERS) > 8:
            _DETRENDERS.clear()
        _DETRENDERS[lengths] = _Detrender(lengths)
    return _DETRENDERS[lengths]


def fit_line(signals, phases, detrend=True):
    """Least-squares amplitude of a sinusoid with the given phase (one
    common amplitude/phase over all pieces).  Each piece's mean and slope are
    fitted alongside (nuisance).  Returns (amplitude_nm, phase_rad,
    explained_fraction)."""
    keep = [i for i, x in enumerate(signals) if len(x) >= 8]
    if not keep:
        return 0.0, 0.0, 0.0
    x = np.concatenate([np.asarray(signals[i], float) for i in keep])
    ph = np.concatenate([np.asarray(phases[i], float) for i in keep])
    c, s = np.cos(ph), np.sin(ph)
    if detrend:
        d = _detrender(tuple(len(signals[i]) for i in keep))
        x, c, s = d(x), d(c), d(s)
    sxx = np.array([[c @ c, c @ s], [c @ s, s @ s]])
    sxy = np.array([c @ x, s @ x])
    total = float(x @ x)
    if total <= 0 or np.linalg.cond(sxx) > 1e12:
        return 0.0, 0.0, 0.0
    coef = np.linalg.solve(sxx, sxy)
    explained = float(coef @ sxy) / total
    amp = float(np.hypot(*coef))
    phase = float(np.arctan2(-coef[1], coef[0]))
    return amp, phase, explained


def highpass_for_line(signals, phases, ts_s, cycles=3.0, min_s=0.1, max_s=10.0):
    """Removes slow torque (gravity, load) that would leak into a line fit:
    subtracts a centred moving average spanning `cycles` periods of the
    line at its median frequency (window clamped to [min_s, max_s])."""
    steps = np.concatenate([np.abs(np.diff(p)) for p in phases if len(p) > 1])
    moving = steps[steps > 0]
    if len(moving) == 0:
        return [np.asarray(x, float) for x in signals]
    f_hz = float(np.median(moving)) / (2 * np.pi * ts_s)
    w = int(round(min(max(cycles / max(f_hz, 1e-9), min_s), max_s) / ts_s))
    out = []
    for x in signals:
        x = np.asarray(x, float)
        if w < 3 or len(x) < 2 * w:
            out.append(x - x.mean())
            continue
        c = np.cumsum(np.r_[0.0, x])
        ma = (c[w:] - c[:-w]) / w
        pad_l = (w - 1) // 2
        ma = np.r_[np.full(pad_l, ma[0]), ma, np.full(len(x) - len(ma) - pad_l, ma[-1])]
        out.append(x - ma)
    return out
