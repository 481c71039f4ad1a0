"""The simulated joint and the firmware on it, shared by the accuracy and the
slow-torque benchmarks: hdsim runs and the angles the encoders give,
hdjoint-host runs (a configuration text, a profile record or an NVM image),
and the firmware's own commissioning of a joint (learning_mode 2, then
PROFILE_SAVE: the NVM image an operating run boots from).

Nothing here hands the firmware the simulated joint's parameters: the
configuration is what the caller composes (defaults or what the tools
identified from another run), the calibration is the scenario's nominal one.
"""
from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np

from hdtools import canproto, native, summary

ROOT = Path(__file__).resolve().parents[3]
HDSENSE = ROOT / "tools" / "hdsense"
# The motion of a scenario file (what a commissioning run replaces); every
# other key describes the joint itself.
MOTION_KEYS = ("duration_s", "seed", "motor_speed_profile", "load_torque_profile",
               "load_sine", "gravity_profile", "gravity_phase_rad")


# ----------------------------------------------------------------- hdsim

def hdsim() -> Path:
    return native.find_file("hdsim", target="hdsim_cli")


def nominal(ini: Path) -> dict:
    out = subprocess.run([str(hdsim()), str(ini), "--nominal"], check=True,
                         capture_output=True, text=True).stdout
    return {k: float(v) for k, v in (ln.split("=", 1) for ln in out.split())}


def simulate(ini: Path, csv: Path, extra=(), duration_s: float | None = None) -> dict:
    cmd = [str(hdsim()), str(ini), "--csv", str(csv), *extra]
    if duration_s is not None and "--duration" not in extra:
        cmd += ["--duration", str(duration_s)]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return load_csv(csv)


def load_csv(path: Path) -> dict:
    with open(path) as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {n: data[:, i] for i, n in enumerate(names)}


def _increments(counts, cpr: float):
    """(first angle, increments from sample 0) [rad] of a free-running
    32-bit counter, the first reading taken as absolute."""
    c = counts.astype(np.int64)
    dc = (np.diff(c) + 2 ** 31) % 2 ** 32 - 2 ** 31
    lsb = 2.0 * math.pi / cpr
    return c[0] * lsb, np.concatenate([[0.0], dc * lsb])


def encoder_angles(d: dict, nom: dict):
    """Motor angle from the encoder counts (what the firmware sees), its
    increments, and the output angle = motor / N."""
    first, d_motor = _increments(d["motor_counts"], nom["motor_cpr"])
    motor = first + np.cumsum(d_motor)
    n = nom["gear_ratio"]
    return motor, motor / n, d_motor, d_motor / n


def output_angle(d: dict, nom: dict):
    """Output angle from the output encoder's counts (what the firmware sees)."""
    first, d_out = _increments(d["output_counts"], nom["output_cpr"])
    return first + np.cumsum(d_out)


# ----------------------------------------------------------------- scenario files

def cfg_lines(text: str) -> list[tuple[str, str]]:
    """(key, value) of a `key = value` text (scenario or firmware configuration)."""
    out = []
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if line:
            key, _, value = line.partition("=")
            out.append((key.strip(), value.strip()))
    return out


def compose_config(base: str, overrides: dict) -> str:
    """base configuration text with keys replaced (block lines kept)."""
    kept = [f"{k} = {v}" for k, v in cfg_lines(base) if k not in overrides]
    return "\n".join(kept + [f"{k} = {v}" for k, v in overrides.items()]) + "\n"


def ini_value(ini: Path, key: str) -> str:
    for k, v in cfg_lines(ini.read_text()):
        if k == key:
            return v
    raise KeyError(key)


def _is_motion(key: str) -> bool:
    return key in MOTION_KEYS or key.startswith("feedforward")


def joint_key(ini: Path) -> tuple:
    """What identifies the joint of a scenario file (its motion left out):
    two files with the same key are the same joint."""
    return tuple(sorted((k, v) for k, v in cfg_lines(ini.read_text()) if not _is_motion(k)))


def with_motion(joint_ini: Path, motion_ini: Path, out: Path) -> Path:
    """A scenario file: the joint of joint_ini under the motion (speed, load,
    duration, seed) of motion_ini, e.g. a commissioning run of that joint."""
    joint = [f"{k} = {v}" for k, v in cfg_lines(joint_ini.read_text()) if not _is_motion(k)]
    motion = [f"{k} = {v}" for k, v in cfg_lines(motion_ini.read_text()) if _is_motion(k)]
    out.write_text(f"# {joint_ini.name}'s joint, {motion_ini.name}'s motion (generated)\n"
                   + "\n".join(motion + joint) + "\n")
    return out


# ----------------------------------------------------------------- firmware

def run_tool(cmd, what: str) -> subprocess.CompletedProcess:
    p = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{what}: exit {p.returncode}: {p.stderr.strip()[-400:]}")
    return p


def host() -> Path:
    return native.executable("hdjoint-host")


def run_firmware(ini: Path, config: str, wd: Path, tag: str, duration: float | None = None,
                 profile: Path | None = None, nvm: Path | None = None) -> tuple[np.ndarray, dict]:
    """hdjoint-host on the simulated joint of `ini` with the configuration
    text `config`, booting from a profile record or (a copy of) an NVM
    image; (filtered torque per sample, the run's summary)."""
    cfg = wd / f"{tag}.cfg"
    cfg.write_text(config)
    csv = wd / f"{tag}_fw.csv"
    cmd = [host(), "--sensors", f"sim:{ini}", "--config", cfg, "--csv", csv]
    if duration is not None:
        cmd += ["--duration", duration]
    if profile is not None:
        cmd += ["--profile", profile]
    if nvm is not None:
        image = wd / f"{tag}.nvm"
        image.write_bytes(nvm.read_bytes())
        cmd += ["--nvm", image]
    s = summary.parse(run_tool(cmd, f"hdjoint-host {tag}").stdout)
    return load_csv(csv)["torque_filtered_nm"], s


def profile_save_frame() -> str:
    """PROFILE_SAVE of the running filter to node 1, in `cansend` notation
    (the frame from the protocol definition, firmware/hd_protocol.def)."""
    return canproto.cansend_str(canproto.command(canproto.load_db(1), "PROFILE_SAVE",
                                                 ProfileSaveSource=0))


def firmware_commissioning(ini: Path, wd: Path, nominal: dict, duration: float | None,
                           model_cfg: str) -> tuple[Path | None, str]:
    """The firmware learns on the commissioning run itself (learning_mode
    2, the blocks of model_cfg or the defaults) and saves its profile with
    PROFILE_SAVE at the end: (the NVM image, what it is) or (None, why not)."""
    nvm = wd / f"{ini.stem}.nvm"
    nvm.unlink(missing_ok=True)
    cfg = wd / f"{ini.stem}_commissioning.cfg"
    cfg.write_text(compose_config(model_cfg, {"learning_mode": "2", "inertia_kgm2": "0",
                                              "viscous_nm_s_rad": "0", "coulomb_nm": "0"}))
    end = duration if duration is not None else float(ini_value(ini, "duration_s"))
    try:
        out = run_tool([host(), "--sensors", f"sim:{ini}", "--config", cfg, "--nvm", nvm,
                        "--calib", f"{nominal['gain_nm_per_v']:.9g},{nominal['offset_v']:.9g}",
                        "--cmd-at", f"{end - 0.01:.3f}:{profile_save_frame()}"] +
                       (["--duration", duration] if duration is not None else []),
                       f"hdjoint-host commissioning {ini.name}").stdout
    except RuntimeError as exc:
        return None, str(exc)
    if summary.parse(out).get("profile_status") != "0":
        return None, f"PROFILE_SAVE on {ini.name} did not store a profile"
    return nvm, f"the firmware's own PROFILE_SAVE after {ini.name} in commissioning mode"
