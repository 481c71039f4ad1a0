"""Accuracy benchmark on the simulated joint.

Every scenario in tests/bench/scenarios/ is the same joint (the paper demo's
ripple, noise and friction) under different motion and load.  Each is run
through hdsim, then every method filters the same measured torque, and the
metrics compare the result with the simulator's ripple-free truth.

Our filter runs in C (libhdfilter.so through hdtools.analysis.cfilter); the
peers are the independent numpy/scipy methods of peers.py.  The product row
(`fw_commissioned`) runs the firmware itself (hdjoint-host on the simulated
joint) as a joint is used: commissioned once by its own learning_mode 2 and
PROFILE_SAVE on a separate run of the same joint (the motion of
tests/bench/scenarios/slow/commission.ini, no load, its own seed), then
operated with its defaults from that stored profile.
"""
from __future__ import annotations

import ctypes
import json
import math
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hdtools.analysis import cfilter
from . import metrics, peers
from .joint import (encoder_angles, firmware_commissioning, ini_value, joint_key, nominal,
                    run_firmware, simulate, with_motion, compose_config)

ROOT = Path(__file__).resolve().parents[3]
SCENARIO_DIR = ROOT / "tests" / "bench" / "scenarios"
# The commissioning motion of every firmware row (docs/design/slow-torque.md,
# "Commissioning motion"): no load, both directions, 30 s.
COMMISSION_MOTION = SCENARIO_DIR / "slow" / "commission.ini"
# What the product row is told: the firmware defaults in operating mode,
# booted from the profile it saved itself on a commissioning run.
OPERATING_CONFIG = {"learning_mode": "1"}
COMMISSIONED_PROFILE = (f"the firmware's own PROFILE_SAVE at the end of a commissioning run "
                        f"(learning_mode 2, defaults) of the scenario's joint with "
                        f"{COMMISSION_MOTION.name}'s motion and seed, no load")

PAPER_SPEED_RAD_S = 156.0
NOISE_SPEC_NM = 0.02          # the sensor's noise spec, told to the recommended tuning
RIPPLE_SETTLE_S = 0.05        # hd_kf_config_recommended "typical" values
OFFSET_SETTLE_S = 0.02
STEP_SETTLE_FRACTION = 0.02   # settled: 20 ms moving RMS error < own pre-step peak + 2 % of step
RECOVERY_FACTOR = 2.0         # recovered: moving RMS < 2 x steady RMS + 10 mN m
RECOVERY_FLOOR_NM = 0.01
CALIBRATION_OVERRIDES = ["--seed", "9999", "--duration", "8",
                         "--set", "motor_speed_profile=0:0, 0.5:156",
                         "--set", "load_torque_profile=0:3"]
CALIBRATION_FROM_S = 1.0      # table fitted on the constant-speed part


@dataclass
class Scenario:
    name: str
    what: str
    eval_s: tuple            # RMS window
    lines: bool = False      # line attenuation over eval_s
    steps: list = field(default_factory=list)      # (t_step, t_end)
    recoveries: list = field(default_factory=list)  # (label, t_event, t_end, baseline (t0, t1))
    windows: list = field(default_factory=list)    # (label, t0, t1) extra RMS windows
    calibrate_on: str = ""   # scenario whose joint the Fourier table is fitted on (default: own)


SCENARIOS = [
    Scenario("const156", "156 rad/s, 3 N m", (2.0, 8.0), lines=True),
    Scenario("ripple_drift", "156 rad/s, ripple changed since calibration", (2.0, 8.0),
             lines=True, calibrate_on="const156"),
    Scenario("ramp", "0 -> 300 -> 40 rad/s ramps", (1.0, 10.0), lines=True),
    Scenario("speed_step", "156 -> 260 rad/s in 50 ms", (1.0, 7.0),
             recoveries=[("speed_change", 4.05, 7.0, (2.5, 3.95))]),
    Scenario("reversal", "+100 -> -100 rad/s", (1.5, 8.0),
             recoveries=[("reversal", 4.5, 8.0, (2.0, 3.4))],
             windows=[("through_zero", 3.5, 4.5)]),
    Scenario("torque_step", "1 -> 11 -> 1 N m at 156 rad/s", (1.5, 9.0),
             steps=[(3.0, 6.0), (6.0, 9.0)]),
    Scenario("torque_step_slow", "1 -> 11 -> 1 N m at 30 rad/s", (1.5, 9.0),
             steps=[(3.0, 6.0), (6.0, 9.0)]),
    Scenario("slow_load", "load 0 -> 8 -> 0 N m over 10 s", (1.5, 12.0)),
    Scenario("slow_load_sync", "0..8 N m at the output-line frequency", (1.5, 9.0)),
    Scenario("load_ripple", "load 0 -> 20 N m, ripple x1 -> x2", (1.5, 9.0)),
    Scenario("standstill", "stop, 3 -> 8 N m step while stopped, restart", (1.5, 9.0),
             steps=[(4.0, 6.0)],
             recoveries=[("restart", 6.5, 9.0, (1.5, 2.0))],
             windows=[("stopped", 3.0, 6.0)]),
]


@dataclass
class Method:
    key: str
    label: str
    kind: str                 # kf | fw | butter | notch | table | paper | raw | ideal
    params: dict = field(default_factory=dict)


def methods(residual_model: dict | None) -> list[Method]:
    line2_hz = 2.0 * PAPER_SPEED_RAD_S / (2.0 * math.pi)
    fc20 = peers.butterworth_cutoff_for(line2_hz, 20.0)
    fc40 = peers.butterworth_cutoff_for(line2_hz, 40.0)
    out = [
        Method("kf_recommended", "this filter, recommended tuning (7 states), T_exp = 0", "kf",
               {"config": "recommended"}),
        Method("fw_commissioned", "the firmware, defaults in operating mode, booted from "
               "its own commissioning profile (PROFILE_SAVE after a separate run)", "fw"),
        Method("kf_residual", "this filter, model from `hdsense analyze`", "kf",
               {"config": "residual", "model": residual_model}),
        Method("kf_paper4", "paper tuning Q=1e3 I, R=1, 4th order", "kf",
               {"config": "paper", "misalignment": False}),
        Method("kf_paper6", "paper tuning Q=1e3 I, R=1, 6th order", "kf",
               {"config": "paper", "misalignment": True}),
        Method("butter_20db", f"Butterworth 2nd order, fc {fc20:.1f} Hz (-20 dB at 2x)",
               "butter", {"cutoff_hz": fc20}),
        Method("butter_40db", f"Butterworth 2nd order, fc {fc40:.1f} Hz (-40 dB at 2x)",
               "butter", {"cutoff_hz": fc40}),
        Method("kf_paper6_oracle", "paper 6th order given the TRUE torque as T_exp (oracle)",
               "kf", {"config": "paper", "misalignment": True, "oracle": True}),
        Method("order_notch", "order tracking + notch, motor orders 2, 4 (Q 2)", "notch",
               {"output": False}),
        Method("order_notch_out", "order tracking + notch, + output order 1 (Q 3)", "notch",
               {"output": True}),
        Method("fourier_table", "Fourier table vs WG angle (+ output 1), fitted offline",
               "table", {}),
        Method("raw", "unfiltered measurement", "raw", {}),
        Method("ideal", "noise floor: measured minus the true ripple", "ideal", {}),
    ]
    return out


# --------------------------------------------------------------------------
# Our filter (C, through ctypes)

# The C library fills the configuration itself (hd_kf_config_recommended /
# hd_kf_config_paper) into an opaque buffer, and the pipeline state is an
# opaque buffer too, so these rows do not depend on a Python mirror of
# hd_kf_config_t / hd_pipeline_t (only on hd_pipeline_io_t, via cfilter).
_OPAQUE_BYTES = 1 << 16  # far larger than hd_pipeline_t (~1.4 KB)


def _lib():
    L = cfilter.lib()
    L.hd_kf_config_paper.argtypes = [ctypes.c_void_p, ctypes.c_float, ctypes.c_bool]
    L.hd_kf_config_paper.restype = None
    L.hd_kf_config_recommended.argtypes = [ctypes.c_void_p] + [ctypes.c_float] * 4
    L.hd_kf_config_recommended.restype = None
    L.hd_pipeline_init.argtypes = [ctypes.c_void_p, ctypes.c_void_p,
                                   ctypes.POINTER(cfilter.ExpectedConfig), ctypes.c_float]
    L.hd_pipeline_init.restype = ctypes.c_int
    L.hd_pipeline_run.argtypes = [ctypes.c_void_p, ctypes.POINTER(cfilter.PipelineIO)]
    L.hd_pipeline_run.restype = None
    L.hd_kf_config_check.argtypes = [ctypes.c_void_p]
    L.hd_kf_config_check.restype = ctypes.c_int
    return L


def _run_opaque(cfg_buf, ex, torque, d_motor, d_output, feedforward=None,
                track_bandwidth_hz=cfilter.DEFAULT_TRACK_BANDWIDTH_HZ):
    L = _lib()
    pipe = ctypes.create_string_buffer(_OPAQUE_BYTES)
    err = L.hd_pipeline_init(pipe, cfg_buf, ctypes.byref(ex), track_bandwidth_hz)
    if err != 0:
        raise cfilter.FilterError(f"hd_pipeline_init failed ({cfilter.error_name(err)}): "
                                  f"{cfilter.error_text(err)}", cfilter.error_name(err))
    n = len(torque)
    ins = [np.ascontiguousarray(a, dtype=np.float32) for a in (torque, d_motor, d_output)]
    out = np.empty(n, np.float32)
    io = cfilter.PipelineIO()
    io.n = n
    fp = ctypes.POINTER(ctypes.c_float)
    io.torque_meas_nm, io.d_motor_angle_rad, io.d_output_angle_rad = (
        a.ctypes.data_as(fp) for a in ins)
    io.torque_filtered_nm = out.ctypes.data_as(fp)
    if feedforward is not None:
        ff = np.ascontiguousarray(feedforward, dtype=np.float32)
        io.feedforward_nm = ff.ctypes.data_as(fp)
    L.hd_pipeline_run(pipe, ctypes.byref(io))
    return out.astype(float)


def run_kf(params, d, nom, d_motor, d_output):
    ts = nom["ts_s"]
    # No oracle (issue 12): the plant's J, b, Fc are not handed to the
    # filter; T_exp is the firmware default (0) unless a row says otherwise.
    ex = cfilter.ExpectedConfig()
    ff = None
    if params.get("oracle"):
        # The paper assumes a good expected torque; give it the exact one.
        ff = d["torque_true_nm"]
    if params["config"] == "residual":
        # The whole model the tool ends up with, its expected torque included.
        cfg, ex, bw = residual_config(params["model"], ts)
        out = cfilter.run(cfg, ex, d["torque_nm"], d_motor, d_output, track_bandwidth_hz=bw)
        return out["torque_filtered_nm"].astype(float)
    if params["config"] == "paper":
        return paper_filtered(ts, params["misalignment"], d["torque_nm"], d_motor, d_output, ff)
    buf = ctypes.create_string_buffer(_OPAQUE_BYTES)
    _lib().hd_kf_config_recommended(buf, ts, NOISE_SPEC_NM, RIPPLE_SETTLE_S, OFFSET_SETTLE_S)
    return _run_opaque(buf, ex, d["torque_nm"], d_motor, d_output, ff)


def paper_filtered(ts_s, misalignment, torque, d_motor, d_output, feedforward=None):
    """The filtered torque of the paper's tuning (hd_kf_config_paper), T_exp
    = the feed-forward given (0 without one)."""
    buf = ctypes.create_string_buffer(_OPAQUE_BYTES)
    _lib().hd_kf_config_paper(buf, ts_s, misalignment)
    return _run_opaque(buf, cfilter.ExpectedConfig(), torque, d_motor, d_output, feedforward)


def residual_config(model: dict, ts_s: float):
    """(KfConfig, ExpectedConfig, tracker bandwidth) from the model JSON of
    `hdsense analyze` (hdtools.analysis.model)."""
    from hdtools.analysis import model as amodel
    fields = {k: v for k, v in model.items() if k in amodel.Model.__dataclass_fields__}
    fields["blocks"] = [amodel.Block(**b) for b in model.get("blocks", [])]
    m = amodel.Model(**fields)
    cfg = m.kf_config(ts_s)
    cfilter.check(cfg)
    return cfg, m.expected_config(), m.track_bandwidth_hz


# --------------------------------------------------------------------------
# The firmware as a joint is used (commission once, then operate)

def commissioning(joint_ini: Path, wd: Path, nom: dict, duration_scale: float,
                  cache: dict) -> tuple[Path | None, str]:
    """(NVM image with the firmware's own profile, the joint's scenario) or
    (None, why not) of the joint of joint_ini, commissioned once per
    distinct joint (cache)."""
    key = joint_key(joint_ini)
    if key not in cache:
        ini = with_motion(joint_ini, COMMISSION_MOTION, wd / f"commission_{joint_ini.stem}.ini")
        dur = None
        if duration_scale != 1.0:
            dur = round(float(ini_value(COMMISSION_MOTION, "duration_s")) * duration_scale, 3)
        nvm, note = firmware_commissioning(ini, wd, nom, dur, "")
        cache[key] = (nvm, joint_ini.stem if nvm is not None else note)
    return cache[key]


def run_fw(m: Method, ini: Path, wd: Path, duration_s: float | None,
           commissioned: tuple[Path | None, str], told: dict):
    """The filtered torque of the firmware in operating mode booted from the
    commissioning NVM image (None if there is none), and what it was told
    (told[m.key]: configuration, profiles, each run's summary, pending)."""
    nvm, note = commissioned
    t = told.setdefault(m.key, {"config": "firmware defaults, " + ", ".join(
        f"{k} = {v}" for k, v in OPERATING_CONFIG.items()), "profile": COMMISSIONED_PROFILE,
        "commissioned_joints": [], "summaries": {}})
    if nvm is None:
        t.setdefault("pending", {})[ini.stem] = note
        return None
    if note not in t["commissioned_joints"]:
        t["commissioned_joints"].append(note)
    y, summary = run_firmware(ini, compose_config("", OPERATING_CONFIG), wd,
                              f"{ini.stem}_{m.key}", duration_s, nvm=nvm)
    t["summaries"][ini.stem] = {k: summary.get(k) for k in (
        "profile_status", "profile_imports", "expected_model", "fault_ticks")}
    return y


# --------------------------------------------------------------------------

def apply_method(m: Method, d, nom, ang, table):
    motor, output, d_motor, d_output = ang
    x = d["torque_nm"]
    if m.kind == "kf":
        return run_kf(m.params, d, nom, d_motor, d_output)
    if m.kind == "butter":
        return peers.butterworth(x, nom["ts_s"], m.params["cutoff_hz"])
    if m.kind == "notch":
        y = peers.order_notch(x, motor, (2, 4), q=2.0)
        return peers.order_notch(y, output, (1,), q=3.0) if m.params["output"] else y
    if m.kind == "table":
        return table.apply(x, motor, output)
    if m.kind == "raw":
        return x.copy()
    if m.kind == "ideal":
        return x - d["ripple_true_nm"]
    raise ValueError(m.kind)


def scenario_metrics(sc: Scenario, y, d, ang, ts_s) -> dict:
    t, truth = d["t_s"], d["torque_true_nm"]
    err = y - truth
    r = {"rms_nm": metrics.rms(err[metrics.window(t, *sc.eval_s)])}
    for label, t0, t1 in sc.windows:
        r[f"rms_{label}_nm"] = metrics.rms(err[metrics.window(t, t0, t1)])
    if sc.lines:
        w = metrics.window(t, *sc.eval_s)
        r["line_amplitude_nm"] = metrics.line_amplitudes(err[w], ang[0][w], ang[1][w])
    for i, (t_step, t_end) in enumerate(sc.steps):
        size = abs(truth[metrics.window(t, t_end - 0.2, t_end)].mean() -
                   truth[metrics.window(t, t_step - 0.2, t_step)].mean())
        r[f"step{i}_delay_s"] = metrics.step_delay_s(y, truth, t, t_step, t_end)
        # Settled: back within 2 % of the step above the method's own
        # steady error before the step (so a method that never removes a
        # line is judged on its dynamics, not on that line again).
        base = metrics.moving_rms(err[metrics.window(t, t_step - 1.0, t_step)],
                                  int(round(0.02 / ts_s))).max()
        r[f"step{i}_settle_s"] = metrics.recovery_s(err, t, t_step, t_end,
                                                   STEP_SETTLE_FRACTION * size + base,
                                                   ts_s=ts_s)
    for label, t_event, t_end, (b0, b1) in sc.recoveries:
        base = metrics.rms(err[metrics.window(t, b0, b1)])
        thr = RECOVERY_FACTOR * base + RECOVERY_FLOOR_NM
        r[f"recover_{label}_s"] = metrics.recovery_s(err, t, t_event, t_end, thr, ts_s=ts_s)
    return r


def run(residual_model: dict | None = None, duration_scale: float = 1.0,
        scenarios: list[str] | None = None, keep_traces: tuple = ("torque_step",),
        workdir: Path | None = None) -> dict:
    """Runs every scenario and method.  duration_scale < 1 shortens the runs
    (smoke test only: the event times then no longer fit)."""
    tmp = tempfile.TemporaryDirectory() if workdir is None else None
    wd = Path(tmp.name) if tmp else Path(workdir)
    wd.mkdir(parents=True, exist_ok=True)
    ms = methods(residual_model)
    if residual_model is None:
        ms = [m for m in ms if m.key != "kf_residual"]
    results = {"methods": {m.key: m.label for m in ms}, "scenarios": {}, "traces": {},
               "told": {}, "pending": {}}
    if residual_model is None:
        results["pending"]["kf_residual"] = "hdsense analyze not available in this tree"
    coms: dict = {}
    for sc in SCENARIOS:
        if scenarios and sc.name not in scenarios:
            continue
        ini = SCENARIO_DIR / f"{sc.name}.ini"
        nom = nominal(ini)
        dur = None
        if duration_scale != 1.0:
            dur = max(1.0, round(sc.eval_s[1] * duration_scale, 3))
        d = simulate(ini, wd / f"{sc.name}.csv", duration_s=dur)
        cal_ini = SCENARIO_DIR / f"{sc.calibrate_on or sc.name}.ini"
        cal = simulate(cal_ini, wd / f"{sc.name}_cal.csv", CALIBRATION_OVERRIDES
                       if dur is None else CALIBRATION_OVERRIDES[:2] + ["--duration", str(dur)]
                       + CALIBRATION_OVERRIDES[4:])
        ang = encoder_angles(d, nom)
        cang = encoder_angles(cal, nom)
        cw = cal["t_s"] >= min(CALIBRATION_FROM_S, cal["t_s"][-1] / 2)
        table = peers.FourierTable().fit(cal["torque_nm"][cw], cang[0][cw], cang[1][cw])
        sres = {"what": sc.what, "eval_s": list(sc.eval_s), "methods": {}}
        if dur is not None:
            sc = Scenario(sc.name, sc.what, (min(sc.eval_s[0], dur / 2), dur),
                          lines=sc.lines)
        for m in ms:
            if m.kind == "fw":
                y = run_fw(m, ini, wd, dur, commissioning(cal_ini, wd, nom, duration_scale, coms),
                           results["told"])
                if y is None:
                    continue
            else:
                y = apply_method(m, d, nom, ang, table)
            sres["methods"][m.key] = scenario_metrics(sc, y, d, ang, nom["ts_s"])
            if sc.name in keep_traces:
                results["traces"].setdefault(sc.name, {"t_s": d["t_s"],
                                                       "truth": d["torque_true_nm"]})
                results["traces"][sc.name][m.key] = y
        floor = sres["methods"]["ideal"]["rms_nm"]
        for r in sres["methods"].values():
            r["x_floor"] = r["rms_nm"] / floor
        if sc.lines:
            metrics.add_line_attenuations(sres["methods"])
        results["scenarios"][sc.name] = sres
    if tmp:
        tmp.cleanup()
    return results


def analyze(csv: Path, workdir: Path, timeout_s: float = 120) -> tuple[dict | None, str]:
    """`hdsense analyze CSV --json` -> (model_after dict, note)."""
    out = workdir / f"{csv.stem}_analyze.json"
    try:
        proc = subprocess.run([str(ROOT / "tools" / "hdsense"), "analyze", str(csv), "--json",
                               str(out)], capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return None, f"hdsense analyze {csv.name}: timed out"
    if proc.returncode != 0 or not out.exists():
        return None, f"hdsense analyze failed: {proc.stderr.strip()[-300:]}"
    j = json.loads(out.read_text())
    model = j.get("model_after") or j.get("model")
    if model is None:
        return None, f"hdsense analyze JSON has no model (keys: {sorted(j)[:10]})"
    return model, f"model_after of hdsense analyze {csv.name}"


def residual_model_from_analyze(workdir: Path) -> tuple[dict | None, str]:
    """Runs `hdsense analyze` on a calibration-style run of the benchmark
    joint and returns (model dict, note).  None if the tool is missing."""
    try:
        import importlib
        importlib.import_module("hdtools.cmd_analyze")
    except ModuleNotFoundError:
        return None, "hdsense analyze not available in this tree"
    csv = workdir / "analyze_input.csv"
    simulate(SCENARIO_DIR / "const156.ini", csv, CALIBRATION_OVERRIDES)
    model, note = analyze(csv, workdir)
    if model is not None:
        note = "model_after of hdsense analyze on a 156 rad/s, 3 N m run of the joint"
    return model, note
