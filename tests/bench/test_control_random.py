"""The random-joint control bench (tools/hdmaint/bench/control_random.py) and
hdctrl-bench's plant options, on three fixed joints (the default one, kt
error +10 %, twice the motor inertia) and the first report joint:

  * a torque-constant error scales the measured plant (true torque per
    drive current, at 3 rad/s where friction is past its break-away and the
    plant is linear) by exactly its factor at every line;
  * twice the motor inertia moves the measured plant as a linear two-mass
    model of the joint says (the motor's reflected inertia and the output's
    on the flexspline's K and D, the dynamometer's PI as a spring and damper
    on the output, the drive's first-order current lag), written out here
    from the runner's defaults: each measurement within 15 % of its own
    model below 100 Hz, the default model off the doubled one's measurement
    by far more, and the resonance down by about 1/sqrt(2);
  * the product row is the firmware as flashed: its options given back to
    the runner run byte for byte what no option runs;
  * a plant option out of its range, or not a number, is one line and exit 2;
  * the first report joint measures as docs/results/control-random.json
    says (the stored results are of today's firmware and runner)."""
import dataclasses
import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]

from hdmaint.bench import control_loop as cl  # noqa: E402
from hdmaint.bench import control_random as cr  # noqa: E402

RESULTS = json.loads((ROOT / "docs" / "results" / "control-random.json").read_text())
SPEED = "3.0"
DYNO = (("--dyno-kv", "50"), ("--dyno-ki", "5000"))   # told to the runner and the model
F_MAX_HZ = 100.0


def _plant(*options) -> cl.Response:
    v = cr.product_variant()
    v.plant = DYNO + tuple(options)
    return cl.measure_loop(v, cl.scene_of(SPEED))


def _two_mass(f, d: dict, motor_inertia: float) -> np.ndarray:
    """|true torque / (N kt x)| of the linear joint: output-referred motor
    inertia N^2 Jm and viscous N^2 bm driven by N T_m, the flexspline K + D s,
    the output Jo with its bearing and the dynamometer (kv s + ki on the
    output angle), T_m = kt (1 + error) times the current lag."""
    n = cl.GEAR_RATIO
    s = 2j * math.pi * np.asarray(f)
    k = float(d["--stiffness-nm-rad"]) + float(d["--damping-nm-s-rad"]) * s
    a11 = n * n * (motor_inertia * s * s + float(d["--motor-viscous-nm-s-rad"]) * s) + k
    kv, ki = (float(x) for _, x in DYNO)
    a22 = (float(d["--output-inertia-kgm2"]) * s * s
           + (float(d["--output-viscous-nm-s-rad"]) + kv) * s + ki + k)
    twist = (a22 - k) / (a11 * a22 - k * k)          # q_m - q_o per unit N T_m
    lag = 1.0 / (1.0 + s / (2 * math.pi * float(d["--current-bandwidth-hz"])))
    return np.abs(k * twist * (1.0 + float(d["--kt-error"])) * lag)


def test_kt_error_scales_the_plant_by_its_factor():
    base, more = _plant(), _plant(("--kt-error", "0.1"))
    assert np.array_equal(base.freq_hz, more.freq_hz)
    ratio = np.abs(more.true_plant / base.true_plant)
    assert np.all(np.abs(ratio - 1.1) < 0.005), ratio


def test_doubled_motor_inertia_moves_the_plant_as_the_two_mass_model():
    d = cr.defaults()
    jm = float(d["--motor-inertia-kgm2"])
    base, heavy = _plant(), _plant(("--motor-inertia-kgm2", f"{2 * jm:.9g}"))
    low = base.freq_hz <= F_MAX_HZ
    f = base.freq_hz[low]
    for r, j in ((base, jm), (heavy, 2 * jm)):
        fit = np.abs(r.true_plant[low]) / _two_mass(f, d, j)
        assert np.all(np.abs(fit - 1.0) < 0.15), (j, fit.round(3))
    wrong = np.abs(heavy.true_plant[low]) / _two_mass(f, d, jm)
    assert np.max(np.abs(wrong - 1.0)) > 0.4        # the model can tell them apart
    dense = np.geomspace(1.0, F_MAX_HZ, 4000)
    peak = [dense[np.argmax(_two_mass(dense, d, j))] for j in (jm, 2 * jm)]
    measured = [f[np.argmax(np.abs(r.true_plant[low]))] for r in (base, heavy)]
    assert measured[1] < measured[0]
    assert abs(measured[1] / measured[0] - peak[1] / peak[0]) < 0.1
    assert 0.6 < peak[1] / peak[0] < 1 / math.sqrt(2) + 0.1


class _Bare(cl.Variant):
    """The runner with no option of the law: the firmware's defaults."""

    def options(self) -> list[str]:
        return ["--sensor", self.sensor]


def test_product_row_is_the_firmware_as_flashed():
    sp = np.where(np.arange(1500) < 700, 5.0, 10.0)
    got = cl.simulate(cr.product_variant(), cl.torque_scene(0.5), sp)
    bare = cl.simulate(_Bare("bare", "narrow"), cl.torque_scene(0.5), sp)
    assert got.keys() == bare.keys()
    assert all(np.array_equal(got[k], bare[k], equal_nan=True) for k in got)
    # and what the stored results ran is that
    assert RESULTS["rows"][cr.PRODUCT] == json.loads(json.dumps(cr.config(cr.product_variant())))
    assert {p["key"]: p["default"] for p in RESULTS["space"]} == cr.nominal().values


def test_set_writes_the_parameter_tables_field():
    """--set KEY=VALUE goes through the firmware's parameter table: the
    proportional gain set by its key runs byte for byte what --kp runs,
    and differs from the default's run."""
    sp = np.where(np.arange(800) < 400, 5.0, 10.0)
    by_option = cl.simulate(cr.product_variant(), cl.torque_scene(0.5), sp)
    v = dataclasses.replace(cr.product_variant(), kp=0.5)
    by_kp = cl.simulate(v, cl.torque_scene(0.5), sp)
    scene = cl.torque_scene(0.5)
    scene.extra = ["--set", "ctrl_torque_kp=0.5"]
    by_set = cl.simulate(cr.product_variant(), scene, sp)
    assert all(np.array_equal(by_set[k], by_kp[k], equal_nan=True) for k in by_kp)
    assert not np.array_equal(by_set["cmd_a"], by_option["cmd_a"])


@pytest.mark.parametrize("option,value,message", [
    ("--motor-inertia-kgm2", "0", "is outside"), ("--stiffness-nm-rad", "1e9", "is outside"),
    ("--kt-error", "-0.6", "is outside"), ("--noise-nm", "abc", "not a number"),
    ("--current-bandwidth-hz", "nan", "not a number"),
    ("--set", "no_such_parameter=1", "unknown parameter"),
    ("--set", "q_motion_ref_rad=-1", "outside its range"),
    ("--set", "q_motion_ref_rad", "KEY=VALUE")])
def test_runner_rejects_a_bad_plant_option(tmp_path, option, value, message):
    (tmp_path / "in.txt").write_text("10 0 0\n" * 10)
    r = subprocess.run([str(cl.runner()), "--input", str(tmp_path / "in.txt"), "--out",
                        str(tmp_path / "out.csv"), option, value], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and message in r.stderr
    assert option in r.stderr and not (tmp_path / "out.csv").exists()


def _close(a, b, rel: float, absolute: float) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return abs(a - b) <= max(absolute, rel * abs(b))


def test_first_report_joint_measures_as_stored():
    stored = RESULTS["joints"][0]
    assert stored["seed"] == cr.REPORT_SEEDS[0]
    got = json.loads(cr.to_json(cr.run_joint(cr.draw(stored["seed"]), [cr.product_variant()])))
    assert got["factors"] == stored["factors"]
    g, s = got["rows"][cr.PRODUCT], stored["rows"][cr.PRODUCT]
    for c, m in s["margins"].items():
        assert _close(g["margins"][c]["pm_deg"], m["pm_deg"], 0.0, 1.0), c
        assert _close(g["margins"][c]["gm_db"], m["gm_db"], 0.0, 0.3), c
    for sp, m in s["speeds"].items():
        assert _close(g["speeds"][sp]["bandwidth_hz"], m["bandwidth_hz"], 0.03, 0.1), sp
        assert _close(g["speeds"][sp]["overshoot_pct"], m["overshoot_pct"], 0.0, 2.0), sp
    assert [w["limit_cycle"] for w in g["wall"]] == [w["limit_cycle"] for w in s["wall"]]
    assert (g["margins_met"], g["within"]) == (s["margins_met"], s["within"])


def test_autotune_uses_only_what_the_joint_shows(monkeypatch):
    """The per-joint tuning (the autotuned row) sees what a test on the
    joint measures: the true torque's response (NaN here: any use of it
    leaves no candidate) never reaches it, and the wall contact is judged
    on the filtered torque."""
    from hdmaint.bench import control, control_autotune
    f = cl.multisine()[1] / (cl.MS_PERIOD * cl.TS_S)
    z = np.exp(1j * 2 * math.pi * f * cl.TS_S)
    a = math.exp(-cl.TS_S / 0.004)
    p = (1 - a) * z ** -2 / (1 - a / z)

    def measure(v, scene):
        return cl.Response(f, cl.pi_response(f, v.kp, v.ki, v.kd) * p, p,
                           np.full_like(p, np.nan))
    seen = []

    def wall(v, kd, measured=False):
        seen.append(measured)
        return {"limit_cycle": False, "p2p_nm": 0.0}
    monkeypatch.setattr(cl, "measure_loop", measure)
    monkeypatch.setattr(control, "wall_contact", wall)
    v, summary = control_autotune.autotune(cr.product_variant())
    assert summary["met"] and v.key == cr.AUTOTUNED
    assert (v.kp, v.ki, v.kd) == (summary["kp"], summary["ki_per_s"], summary["kd_s"])
    assert seen and all(seen)
