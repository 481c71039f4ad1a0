"""The torque loop broken in the simulation.

hdctrl-bench (firmware/host/hd_ctrl_bench.c) runs the firmware's torque loop
on the dynamic joint; a current `inject_a` (the multisine) is added to what
the firmware commands (`cmd_a`) before the drive sees it, so the loop is
broken at the drive's input as on a joint (hdtools.torque_loop: L, P, the
margins, the law's PI in closed form; its docstring has the definitions).
The tuning (control_tune.py) searches gains on P and then measures the
chosen loop again.
"""
from __future__ import annotations

import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hdtools.safeio import HdError
from hdtools.torque_loop import (  # noqa: F401 - the benchmark's names for them
    MS_PERIOD, MS_RMS_A, RIPPLE_GUARD_HZ, TS_S, Response, line_spectrum, loop_response, margins,
    meets, multisine, off_the_ripple, pi_response)

GEAR_RATIO = 100.0      # the law's defaults (control/hd_ctrl.c): what the firmware is told
KT_NM_PER_A = 0.06
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


def measure_loop(variant: Variant, scene: Scene, setpoint_nm: float = 10.0, periods: int = 3,
                 seed: int = 0x5EED) -> Response:
    """L and P of `variant` at `scene`, by injection at the plant input.
    Lines within RIPPLE_GUARD_HZ of the 2x and 4x motor orders at the
    scene's speed are dropped: the ripple, not the injection, moves them."""
    one, bins = multisine()
    inj = np.tile(one, periods + 1)
    d = simulate(variant, scene, np.full(len(inj), setpoint_nm), inj, seed=seed)
    x = d["cmd_a"] + d["inject_a"]
    nkt = GEAR_RATIO * KT_NM_PER_A
    f, loop, plant = loop_response(d["cmd_a"], x, d["fb_nm"], nkt, bins)
    true_plant = line_spectrum(d["true_torque_nm"], MS_PERIOD, bins) / \
        line_spectrum(x, MS_PERIOD, bins) / nkt
    keep = off_the_ripple(f, GEAR_RATIO * scene.speed_rad_s)
    return Response(f[keep], loop[keep], plant[keep], true_plant[keep])


