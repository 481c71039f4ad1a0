"""A simulated fleet: joints that run the same short health-check motion once
or more a day, some of them wearing (docs/results/fleet.md, "Simulated fleet").

Each log is one hdsim run of a scenario written here from the joint's base
parameters, the day's wear and the log's own scatter (temperature,
lubrication: amplitude, friction and gain vary from log to log on healthy
joints too, so a detector that flags any change flags them all).  The truth
(truth.json) says which joints wear, how, and from when.

Wear laws (t = days since onset, 0 before it):
  meshing   motor-order-2 line amplitude x (1 + MESH_PER_DAY t)
  friction  viscous and Coulomb friction x (1 + FRICTION_PER_DAY t)
  gain      gauge sensitivity x (1 + GAIN_PER_DAY t) (the calibration stays)
  tooth     a motor-order-1 line of TOOTH_NM appears at the onset (a
            damaged tooth / wave-generator defect: a sudden change)

Files: ROOT/<joint>/<YYYY-MM-DDTHH-MM-SS>.csv (the path convention of
docs/results/fleet.md), ROOT/truth.json."""
from __future__ import annotations

import hashlib
import json
import subprocess
from dataclasses import asdict, dataclass
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

from ..safeio import Outputs

WEAR_KINDS = ("meshing", "friction", "gain", "tooth")
MESH_PER_DAY = 0.10
FRICTION_PER_DAY = 0.15
GAIN_PER_DAY = 0.005
TOOTH_NM = 0.15
# Log-to-log scatter on every joint (1 sigma, relative).
SCATTER = {"line": 0.03, "friction": 0.05, "gain": 0.001}
START_UTC = datetime(2026, 1, 5, 8, 0, 0, tzinfo=timezone.utc)
GAUGE_FACTOR = 2.0          # hdsim's default K
NOMINAL_GAIN_NM_PER_V = 6.6  # hdsim's nominal gain with its default bridge (--nominal)
TS_S = 0.005                 # 200 Hz logs
ONSET_MARGIN_DAYS = 4.0      # wear starts after the baseline and this long before the end


@dataclass
class Joint:
    joint: str
    wear: str               # "none" or one of WEAR_KINDS
    onset_day: float | None
    motor2_nm: float
    motor4_nm: float
    output1_nm: float
    phases_rad: tuple
    viscous_nm_s_rad: float
    coulomb_nm: float
    payload_nm: float
    payload_period_s: float
    speed_profile: str
    gear_ratio: float = 100.0


def _speed_profile(rng, log_s):
    """The joint's health-check motion: motor speeds 50-130 rad/s with a
    reversal every 5-10 s (the same motion every day); longer logs reverse
    less often (hdsim takes 64 profile points)."""
    t, pts, sign = 0.0, [], 1.0
    step_s = max(5.0, log_s / 60.0)
    while t < log_s:
        pts.append(f"{t:.3f}:{sign * rng.uniform(50, 130):.2f}")
        t += rng.uniform(step_s, 2 * step_s)
        sign = -sign
    pts.append(f"{log_s:.3f}:{sign * 60:.2f}")
    return ", ".join(pts)


def plan(n_joints, days, seed, log_s, baseline_days):
    """The joints of fleet `seed`: one of each wear kind (as far as there are
    joints), the rest healthy, in a seeded order, onsets after the baseline."""
    rng = np.random.default_rng(seed)
    kinds = list(WEAR_KINDS[:n_joints]) + ["none"] * max(0, n_joints - len(WEAR_KINDS))
    kinds = [kinds[i] for i in rng.permutation(n_joints)]
    lo, hi = baseline_days + 0.5, max(baseline_days + 0.5, days - ONSET_MARGIN_DAYS)
    joints = []
    for i, kind in enumerate(kinds):
        joints.append(Joint(
            joint=f"j{i:03d}", wear=kind,
            onset_day=None if kind == "none" else round(float(rng.uniform(lo, hi)), 3),
            motor2_nm=float(rng.uniform(0.6, 1.2)), motor4_nm=float(rng.uniform(0.2, 0.5)),
            output1_nm=float(rng.uniform(0.2, 0.6)),
            phases_rad=tuple(float(x) for x in rng.uniform(-3, 3, 4)),
            viscous_nm_s_rad=float(rng.uniform(0.5, 1.5)), coulomb_nm=float(rng.uniform(0.5, 1.5)),
            payload_nm=float(rng.uniform(2, 5)), payload_period_s=float(rng.uniform(8, 16)),
            speed_profile=_speed_profile(rng, log_s)))
    return joints


def _worn(joint, day):
    return 0.0 if joint.onset_day is None else max(0.0, day - joint.onset_day)


def scenario_text(joint, day, log_s, seed):
    """The hdsim scenario of `joint`'s log at `day` (days since the start)."""
    rng = np.random.default_rng(seed)
    t = _worn(joint, day)
    wear = joint.wear
    scatter = {k: 1 + s * rng.standard_normal() for k, s in SCATTER.items()}
    m2 = joint.motor2_nm * scatter["line"] * (1 + MESH_PER_DAY * t if wear == "meshing" else 1)
    fr = scatter["friction"] * (1 + FRICTION_PER_DAY * t if wear == "friction" else 1)
    gain = scatter["gain"] * (1 + GAIN_PER_DAY * t if wear == "gain" else 1)
    ph = joint.phases_rad
    lines = [f"ripple = motor : 2 : {m2:.6g} : {ph[0]:.4f}",
             f"ripple = motor : 4 : {joint.motor4_nm * scatter['line']:.6g} : {ph[1]:.4f}",
             f"ripple = output : 1 : {joint.output1_nm:.6g} : {ph[2]:.4f}"]
    if wear == "tooth" and day >= joint.onset_day:
        lines.append(f"ripple = motor : 1 : {TOOTH_NM:.6g} : {ph[3]:.4f}")
    return "\n".join([
        f"# fleet joint {joint.joint} ({joint.wear}), day {day:.3f}",
        f"duration_s = {log_s:g}", f"ts_s = {TS_S:g}", f"seed = {seed}",
        f"gear_ratio = {joint.gear_ratio:g}", "output_encoder_cpr = 65536",
        f"motor_speed_profile = {joint.speed_profile}",
        f"load_sine = {joint.payload_nm:.4f} : {joint.payload_period_s:.3f} : 0",
        "load_inertia_kgm2 = 0.1",
        f"viscous_nm_s_rad = {joint.viscous_nm_s_rad * fr:.6g}",
        f"coulomb_nm = {joint.coulomb_nm * fr:.6g}",
        *lines, "noise_nm = 0.02",
        f"bridge.gauge_factor = {GAUGE_FACTOR * gain:.8g}",
        f"calibration.gain_nm_per_v = {NOMINAL_GAIN_NM_PER_V:g}",
        # The controller knows the payload and the inertia, not the friction.
        "feedforward = 1", "feedforward.load_scale = 1", "feedforward.inertia_kgm2 = 0.1",
        ""])


def log_seed(seed, joint, day_index, k):
    h = hashlib.sha256(f"{seed}/{joint}/{day_index}/{k}".encode()).digest()
    return int.from_bytes(h[:6], "little")


def log_time(day_index, k, logs_per_day):
    """Start of log k of a day: 08:00 plus k * 8 h / logs_per_day."""
    return START_UTC + timedelta(days=day_index, hours=8.0 * k / logs_per_day)


def generate(root, hdsim, n_joints=8, days=10, logs_per_day=1, log_s=60.0, seed=1,
             baseline_days=3.0):
    """Writes the fleet's logs and truth.json under root; returns the truth."""
    root = Path(root)
    joints = plan(n_joints, days, seed, log_s, baseline_days)
    scratch = root / ".scenarios"
    scratch.mkdir(parents=True, exist_ok=True)
    for j in joints:
        (root / j.joint).mkdir(exist_ok=True)
        for d in range(days):
            for k in range(logs_per_day):
                start = log_time(d, k, logs_per_day)
                day = (start - START_UTC).total_seconds() / 86400.0
                ini = scratch / f"{j.joint}_{d}_{k}.ini"
                ini.write_text(scenario_text(j, day, log_s, log_seed(seed, j.joint, d, k)))
                csv = root / j.joint / (start.strftime("%Y-%m-%dT%H-%M-%S") + ".csv")
                subprocess.run([str(hdsim), str(ini), "--csv", str(csv)], check=True,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                ini.unlink()
    scratch.rmdir()
    truth = {"seed": seed, "days": days, "logs_per_day": logs_per_day, "log_s": log_s,
             "ts_s": TS_S, "start_utc": START_UTC.isoformat(), "baseline_days": baseline_days,
             "laws": {"meshing_per_day": MESH_PER_DAY, "friction_per_day": FRICTION_PER_DAY,
                      "gain_per_day": GAIN_PER_DAY, "tooth_nm": TOOTH_NM, "scatter": SCATTER},
             "joints": [dict(asdict(j), onset_utc=None if j.onset_day is None else
                             (START_UTC + timedelta(days=j.onset_day)).strftime("%Y-%m-%dT%H:%M:%SZ"))
                        for j in joints]}
    with Outputs() as out:
        out.write_text(root / "truth.json", json.dumps(truth, indent=1) + "\n")
        out.commit()
    return truth


def main(argv=None):
    import argparse
    from .. import native
    p = argparse.ArgumentParser(prog="python -m hdtools.fleet.simfleet",
                                description="write a simulated fleet of logs and its truth")
    p.add_argument("root")
    p.add_argument("--joints", type=int, default=8)
    p.add_argument("--days", type=int, default=10)
    p.add_argument("--logs-per-day", type=int, default=1)
    p.add_argument("--log-s", type=float, default=60.0)
    p.add_argument("--seed", type=int, default=1)
    a = p.parse_args(argv)
    generate(a.root, native.executable("hdsim"), a.joints, a.days, a.logs_per_day, a.log_s, a.seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
