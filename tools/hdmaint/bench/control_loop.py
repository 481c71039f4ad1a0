"""The torque loop broken in the simulation: loop transfer and margins.

hdctrl-bench (firmware/host/hd_ctrl_bench.c) runs the firmware's torque loop
on the dynamic joint; a current `inject_a` is added to what the firmware
commands (`cmd_a`) before the drive sees it.  With x = cmd + inject the
current the drive receives, the loop seen from that break point is

    L(jw) = -CMD(jw) / X(jw)

measured at the frequencies of a periodic multisine injection (Schroeder
phases, an integer number of periods after a settling period: no leakage
of the excited lines).  The same run gives the plant seen by the controller,
P(jw) = FB(jw) / X(jw) / (N kt) (the feedback torque per drive current), so
that the loop of any other PI is C(jw) P(jw) with the law's C in closed
form (`pi_response`): the tuning (control_tune.py) searches gains on P and
then measures the chosen loop again.

Margins (`margins`): phase margin = the least 180 deg + angle L over every
gain crossover |L| = 1; gain margin = the least -20 log10 |L| over every
phase crossover angle L = -180 deg (both interpolated in log frequency);
the crossover frequency is the highest gain crossover.
"""
from __future__ import annotations

import math
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hdtools.safeio import HdError

TS_S = 1e-3
GEAR_RATIO = 100.0      # the law's defaults (control/hd_ctrl.c): what the firmware is told
KT_NM_PER_A = 0.06
MS_PERIOD = 2000        # multisine period [ticks]: 0.5 Hz lines
MS_F_LO_HZ, MS_F_HI_HZ = 1.0, 450.0
MS_LINES = 48
MS_RMS_A = 0.4          # injection rms (2.4 N m at the output)
RIPPLE_GUARD_HZ = 1.5
PREROLL_SPEED_RAD_S, PREROLL_RAMP_S, PREROLL_RUN_S, PREROLL_HOLD_S = 3.0, 0.5, 1.5, 0.5


class BenchError(HdError):
    """A run of the runner failed (its one-line message; the CLI's exit 1)."""


def runner() -> Path:
    from hdtools import native
    return native.executable("hdctrl-bench")


@dataclass
class Variant:
    """A feedback of the torque loop and its gains (the runner's options)."""
    key: str
    feedback: str                      # filtered | raw | lowpass | none | narrow
    kp: float = 1.0
    ki: float = 30.0
    ff: float = 1.0
    kd: float = 0.0
    ilim: float = 480.0
    lowpass_hz: float = 50.0
    lowpass_order: int = 1
    notch_mask: int = 0
    notch_width_hz: float = 10.0
    artifact_hz: float | None = None   # narrow: the phasors' corner (None: the law's default)
    friction_rest_nm: float = 0.0      # the law's friction compensation at rest
    sensor: str = "gauge"              # gauge | ideal (hdctrl-bench --sensor: bench-only)
    plant: tuple = ()                  # hdctrl-bench's plant options (("--stiffness-nm-rad",
                                       # "9000"), ...): another simulated joint (control_random);
                                       # () the default one.  Not the firmware's: it is told nothing

    def options(self) -> list[str]:
        return [x for kv in self.plant for x in kv] + ["--sensor", self.sensor, "--feedback", self.feedback, "--kp", f"{self.kp:.6g}", "--ki", f"{self.ki:.6g}",
                "--ff", f"{self.ff:.6g}", "--kd", f"{self.kd:.6g}", "--ilim", f"{self.ilim:.6g}", "--lowpass-hz", f"{self.lowpass_hz:.6g}",
                "--lowpass-order", str(self.lowpass_order), "--notch-mask",
                str(self.notch_mask), "--notch-width-hz", f"{self.notch_width_hz:.6g}",
                "--friction-rest-nm", f"{self.friction_rest_nm:.6g}"] + (
                    [] if self.artifact_hz is None else ["--artifact-hz", f"{self.artifact_hz:.6g}"])


@dataclass
class Scene:
    """The output's load and the mode (the runner's options)."""
    speed_rad_s: float = 0.0
    mode: str = "torque"
    load: str = "dyno"
    extra: list = field(default_factory=list)

    def options(self) -> list[str]:
        return ["--mode", self.mode, "--load", self.load] + [str(x) for x in self.extra]


def torque_scene(speed_rad_s: float) -> Scene:
    """The torque-tracking load: the dynamometer (a PI velocity servo on
    the output, stiff enough at 0 rad/s to hold it like a fixture)."""
    return Scene(speed_rad_s)


WALL_STIFFNESS_NM_RAD = 2e4


def contact_scene() -> Scene:
    """The output pressed (TORQUE) against a stiff wall where it rests."""
    return Scene(0.0, load="wall", extra=["--wall-rad", "0", "--wall-stiffness",
                                          f"{WALL_STIFFNESS_NM_RAD:g}"])


def free_scene() -> Scene:
    """The output free (nothing on it) in ZERO_TORQUE: the plant the torque
    loop sees off contact in IMPEDANCE or ZERO_TORQUE, whose flexspline mode
    (the motor's reflected inertia against the output's) is neither the
    held output's nor the wall's."""
    return Scene(0.0, mode="zero_torque", load="free")


def scene_of(condition: str) -> Scene:
    """A tuning condition: "wall" (contact_scene), "free" (free_scene) or
    a speed in rad/s."""
    if condition == "wall":
        return contact_scene()
    return free_scene() if condition == "free" else torque_scene(float(condition))


def preroll(scene: Scene) -> np.ndarray:
    """The dynamometer's speed while the runner's pre-roll back-drives the
    joint in ZERO_TORQUE (so the filter has seen it move: at a standstill
    from boot its ripple and offset are one constant): up to
    PREROLL_SPEED_RAD_S and then to the scene's speed; without the
    dynamometer, down and up again and back to rest where it started."""
    v, r = PREROLL_SPEED_RAD_S, int(PREROLL_RAMP_S / TS_S)
    hold = int(PREROLL_RUN_S / TS_S)
    if scene.load == "dyno":
        parts = [np.linspace(0, v, r), np.full(hold, v), np.linspace(v, scene.speed_rad_s, r)]
    else:
        parts = [np.linspace(0, -v, r), np.full(hold // 2, -v), np.linspace(-v, v, 2 * r),
                 np.full(hold // 2, v), np.linspace(v, 0, r)]
    return np.concatenate(parts)


def simulate(variant: Variant, scene: Scene, setpoint_nm, inject_a=None,
             seed: int = 0x5EED) -> dict[str, np.ndarray]:
    """One run: the pre-roll, PREROLL_HOLD_S in the scene at its first
    setpoint with no injection, then the arrays given; per-tick columns of
    the runner's CSV from there on."""
    sp = np.asarray(setpoint_nm, dtype=float)
    inj = np.zeros_like(sp) if inject_a is None else np.asarray(inject_a, dtype=float)
    pre = preroll(scene)
    cut = len(pre) + int(PREROLL_HOLD_S / TS_S)
    speed = np.concatenate([pre, np.full(cut - len(pre) + len(sp), scene.speed_rad_s)])
    sp = np.concatenate([np.full(cut, sp[0]), sp])
    inj = np.concatenate([np.zeros(cut), inj])
    with tempfile.TemporaryDirectory() as tmp:
        inp, out = Path(tmp) / "in.txt", Path(tmp) / "out.csv"
        np.savetxt(inp, np.column_stack([sp, inj, speed]), fmt="%.6g")
        cmd = [str(runner()), "--input", str(inp), "--out", str(out), "--seed", str(seed),
               "--preroll", str(len(pre))]
        cmd += variant.options() + scene.options()
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            msg = (r.stderr.strip().splitlines() or ["no message"])[-1]
            raise BenchError(f"hdctrl-bench ({variant.key}): {msg}")
        data = np.genfromtxt(out, delimiter=",", names=True)
    return {name: np.asarray(data[name][cut:]) for name in data.dtype.names}


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


def measure_loop(variant: Variant, scene: Scene, setpoint_nm: float = 10.0, periods: int = 3,
                 seed: int = 0x5EED) -> Response:
    """L and P of `variant` at `scene`, by injection at the plant input.
    Lines within RIPPLE_GUARD_HZ of the 2x and 4x motor orders at the
    scene's speed are dropped: the ripple, not the injection, moves them."""
    one, bins = multisine()
    inj = np.tile(one, periods + 1)
    d = simulate(variant, scene, np.full(len(inj), setpoint_nm), inj, seed=seed)
    x = d["cmd_a"] + d["inject_a"]
    spec_x = line_spectrum(x, MS_PERIOD, bins)
    loop = -line_spectrum(d["cmd_a"], MS_PERIOD, bins) / spec_x
    nkt = GEAR_RATIO * KT_NM_PER_A
    plant = line_spectrum(d["fb_nm"], MS_PERIOD, bins) / spec_x / nkt
    true_plant = line_spectrum(d["true_torque_nm"], MS_PERIOD, bins) / spec_x / nkt
    f = bins / (MS_PERIOD * TS_S)
    keep = np.ones(len(f), dtype=bool)
    for order in (2, 4):
        line_hz = order * GEAR_RATIO * abs(scene.speed_rad_s) / (2 * math.pi)
        keep &= np.abs(f - line_hz) > RIPPLE_GUARD_HZ
    return Response(f[keep], loop[keep], plant[keep], true_plant[keep])


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
