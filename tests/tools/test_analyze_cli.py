"""`hdsense analyze` as a command (issue 13, item 4): whole outputs or one
line on stderr with the documented exit status (2 bad input, 3 an output
could not be written), never a traceback; the written model is accepted by
the firmware's host runner; plots readable, reports without `nan`."""
from __future__ import annotations

import json
import os
import struct
import subprocess

import numpy as np
import pytest

from conftest import ROOT, SCENARIOS, analyze, read_csv, write_csv

HDSENSE = str(ROOT / "tools" / "hdsense")
OUT_FILES = {"report.md", "model.cfg", "model.can", "profile.json", "order_spectrum.png",
             "output_spectrum.png", "time_spectrum.png", "torque.png", "profile.png"}


def run(*args, timeout=120):
    """The command in a process of its own."""
    return subprocess.run([HDSENSE, "analyze", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=dict(os.environ))


def run_here(capsys, *args):
    """The command's entry point (hdtools.cli.main) in this process: the
    same parsing, errors and exit status, without a Python start-up."""
    from hdtools import cli
    capsys.readouterr()
    code = cli.main(["analyze", *map(str, args)])
    out = capsys.readouterr()
    return subprocess.CompletedProcess(args, code, out.out, out.err)


def one_line(res, code, match):
    assert res.returncode == code, (res.returncode, res.stderr)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    assert match in lines[0], lines[0]


@pytest.fixture(scope="module")
def cli_run(simulate, tmp_path_factory):
    """One full CLI run on the output3 scenario (a profile is written)."""
    tmp = tmp_path_factory.mktemp("cli")
    rep, out = tmp / "r.json", tmp / "out"
    res = run(simulate("output3"), "--json", rep, "--out", out, "--quiet")
    assert res.returncode == 0, res.stderr
    return json.loads(rep.read_text()), out


def test_report_and_files(cli_run):
    r, out = cli_run
    for k in ("gear_ratio", "model_before", "model_after", "effects", "residual_rms_before_nm",
              "residual_rms_after_nm", "error_rms_before_nm", "error_rms_after_nm",
              "in_sample_residual_rms_after_nm", "out_of_sample_residual_rms_after_nm", "profile"):
        assert k in r
    for e in r["effects"]:
        assert e["kind"] in ("motor_order", "output_order", "fixed_frequency", "velocity",
                             "acceleration", "offset_drift")
        assert isinstance(e["added"], bool) and "evidence" in e and "amplitude_nm" in e
    assert {f.name for f in out.iterdir()} == OUT_FILES
    assert not list(out.glob(".*"))            # no temporary file left


def test_plots_are_readable_and_report_has_no_nan(cli_run):
    # Before: 550 x 370 px and "nan" in report.md.
    _, out = cli_run
    for f in out.glob("*.png"):
        head = f.read_bytes()[:24]
        assert head[:8] == b"\x89PNG\r\n\x1a\n"
        w, h = struct.unpack(">II", head[16:24])
        assert w >= 1000 and h >= 400, (f.name, w, h)
    text = (out / "report.md").read_text()
    assert "nan" not in text.lower().replace("nano", "")
    assert "in-sample" in text and "out-of-sample" in text


def test_profile_json_schema(cli_run):
    r, out = cli_run
    p = json.loads((out / "profile.json").read_text())
    assert p["schema"] == "hdjoint-profile/1"
    assert p["gear_ratio"] == r["gear_ratio"]["value"]
    assert "output angle" in p["angle_convention"]
    outs = {ln["order"]: ln for ln in p["lines"] if ln["lock"] == "output"}
    # output3.ini: 0.5 sin(theta - 0.7) + 0.4 sin(3 theta + phase): the
    # amplitudes of what the simulation adds (truth), within 5 %.
    assert set(outs) == {1.0, 3.0}
    assert abs(complex(outs[1.0]["a_nm"], outs[1.0]["b_nm"])) == pytest.approx(0.5, rel=0.05)
    assert abs(complex(outs[3.0]["a_nm"], outs[3.0]["b_nm"])) == pytest.approx(0.4, rel=0.05)
    for ln in p["lines"]:
        assert set(ln) == {"lock", "order", "a_nm", "b_nm"}


def test_model_is_accepted_by_the_host_runner(cli_run):
    from hdtools import native
    _, out = cli_run
    try:
        host = native.find_file("hdjoint-host", target="hdjoint-host")
    except (FileNotFoundError, subprocess.CalledProcessError):
        pytest.skip("hdjoint-host not built")
    res = subprocess.run([str(host), "--sensors", f"sim:{SCENARIOS / 'motor6.ini'}",
                          "--config", str(out / "model.cfg"), "--duration", "0.2"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    frames = [ln.split()[0] for ln in (out / "model.can").read_text().splitlines()
              if ln.strip() and not ln.startswith("#")]
    cmd = [str(host), "--sensors", f"sim:{SCENARIOS / 'motor6.ini'}", "--duration", "0.1"]
    for f in frames:
        cmd += ["--cmd", f]
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert f"commands = {len(frames)}" in res.stdout + res.stderr
    assert "command_errors = 0" in res.stdout + res.stderr


def test_bad_inputs_are_one_line_exit_2(simulate, tmp_path, capsys):
    # Before: a directory and a BOM gave tracebacks, a FIFO hung.
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    one_line(run(fifo, "--json", tmp_path / "r.json", timeout=30), 2, "is a FIFO")
    good = simulate("motor6")
    short = tmp_path / "short.csv"
    h, a = read_csv(good)
    write_csv(short, h, a[:150])
    cases = [((tmp_path / "nope.csv", "--json", tmp_path / "r.json"), "no such file"),
             ((tmp_path, "--json", tmp_path / "r.json"), "is a directory"),
             ((short, "--out", tmp_path / "o"), "needs at least 4 s"),
             ((good, "--json", tmp_path / "r.json", "--motor-orders", "700"),
              "not representable on CAN"),
             ((good,), "give --json"),
             ((good, "--json", tmp_path / "r.json", "--gear-ratio", "0.5"), "--gear-ratio")]
    for args, match in cases:
        one_line(run_here(capsys, *args), 2, match)
    assert not (tmp_path / "o").exists() and not (tmp_path / "r.json").exists()


def test_unwritable_outputs_are_refused_before_the_analysis(simulate, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    one_line(run_here(capsys, simulate("motor6"), "--out", blocker), 3, "not a directory")
    one_line(run_here(capsys, simulate("motor6"), "--json", tmp_path), 3, "is a directory")
    one_line(run_here(capsys, simulate("motor6"), "--json", blocker / "r.json"), 3,
             "not a directory")


def test_outputs_are_replaced_whole(simulate, tmp_path, monkeypatch):
    """A run that fails while writing leaves the previous outputs as they
    were; a run that succeeds removes the previous run's files it does not
    produce (no mix of old and new)."""
    out, rep = tmp_path / "out", tmp_path / "r.json"
    analyze(simulate("output3"), out_dir=out, json_path=rep)
    before = {f.name: f.read_bytes() for f in out.iterdir()}
    assert "profile.json" in before
    from hdtools.analysis import report

    def broken(*a, **k):
        raise OSError(28, "No space left on device", "report.md")
    monkeypatch.setattr(report, "markdown", broken)
    with pytest.raises(OSError):
        analyze(simulate("motor6"), out_dir=out, json_path=rep)
    assert {f.name: f.read_bytes() for f in out.iterdir()} == before
    monkeypatch.undo()
    # A joint that sweeps less than a turn, output angle only: no line has
    # an absolute, verified angle, so no profile.json (nor profile.png) now.
    h, a = read_csv(simulate("swing"))
    names = ["t_s", "output_angle_rad", "torque_nm"]
    write_csv(tmp_path / "swing.csv", names, a[:25000, [h.index(n) for n in names]])
    r = analyze(tmp_path / "swing.csv", out_dir=out, json_path=rep, gear_ratio=100.0)
    assert not r["profile"]["writable"], r["profile"]
    assert not (out / "profile.json").exists() and not (out / "profile.png").exists()
    assert json.loads(rep.read_text())["input"].endswith("swing.csv")


def test_line_not_representable_on_can_is_not_added(simulate, tmp_path):
    # A 700 Hz pickup at 2 kHz: above what a CAN order field carries
    # (655.35).  Before: found, added and a traceback in can_commands.
    path = simulate("mains", "ts_s=0.0005", "duration_s=10", "ripple=fixed:700:0.2:0")
    r = analyze(path, out_dir=tmp_path / "o")
    f700 = [e for e in r["effects"] if e["kind"] == "fixed_frequency"
            and abs(e["frequency_hz"] - 700) < 1]
    assert f700 and not any(e["added"] for e in f700)
    assert "not representable on CAN" in f700[0]["evidence"]["rejected_because"]
    assert all(b["order"] <= 655.35 for b in r["model_after"]["blocks"])
    assert (tmp_path / "o" / "model.can").stat().st_size > 0


def test_candump_telemetry_input(tmp_path):
    """A candump -l log of the firmware's telemetry (host runner on the
    simulated joint) is decoded through the DBC and analysed: the hidden
    motor order 6 is found from the telemetry alone; there is no absolute
    angle, so no profile is written."""
    from hdtools import native
    from hdtools.analysis.loading import InputError
    try:
        host = native.find_file("hdjoint-host", target="hdjoint-host")
    except (FileNotFoundError, subprocess.CalledProcessError):
        pytest.skip("hdjoint-host not built")
    log = tmp_path / "telem.log"
    subprocess.run([str(host), "--sensors", f"sim:{SCENARIOS / 'motor6.ini'}", "--duration", "20",
                    "--can", f"log:{log}"], check=True, capture_output=True)
    r = analyze(log, gear_ratio=100.0)
    assert r["data"]["source"] == "candump"
    assert any(e["kind"] == "motor_order" and abs(e["order_per_motor_rev"] - 6) < 0.05
               for e in r["effects"] if e["added"])
    assert not r["profile"]["writable"] and "no absolute angle" in r["profile"]["why_not"]
    bad = tmp_path / "bad.log"
    bad.write_text("(0.0) vcan0 7FF#00\n")
    with pytest.raises(InputError, match="telemetry"):
        analyze(bad)


CURRENT_CFG = """# a joint's motor-current term (as `hdsense current --config` writes it)
current_nm_per_a = 10
current_coulomb_nm = 0.25
current_viscous_nm_s_rad = 0.125
current_inertia_kgm2 = 0.0625
current_error_nm = 0.03125
current_filter_hz = 20
"""


def test_config_current_term_is_replayed_and_written(simulate, tmp_path, capsys):
    """--config: the configuration's current keys, as the firmware's parser
    reads them, reach model.cfg (read back by the same parser, independent of
    the model's writer) and the notes say they were replayed; errors in the
    text are one line, exit 2, before the analysis."""
    from hdtools import cfgtext
    h, a = read_csv(simulate("motor6"))
    log = write_csv(tmp_path / "cur.csv", h + ["motor_current_a"],
                    np.column_stack([a, a[:, h.index("torque_nm")] / 10.0]))
    cfg = tmp_path / "joint.cfg"
    cfg.write_text(CURRENT_CFG)
    res = run_here(capsys, log, "--config", cfg, "--json", tmp_path / "r.json",
                   "--out", tmp_path / "o", "--quiet")
    assert res.returncode == 0, res.stderr
    given = {p.key: v for _, p, v in cfgtext.parse(CURRENT_CFG).values}
    written = {p.key: v for _, p, v in cfgtext.parse((tmp_path / "o" / "model.cfg").read_text()
                                                     ).values if p.key.startswith("current_")}
    assert written == given | {"current_backdrive_nm_per_a": 0.0}
    notes = json.loads((tmp_path / "r.json").read_text())["data"]["notes"]
    assert any("motor-current term" in n and "replayed" in n for n in notes), notes
    bad = tmp_path / "bad.cfg"
    bad.write_text("current_nm_per_a = -1\n")
    one_line(run_here(capsys, log, "--config", bad, "--json", tmp_path / "r2.json"), 2,
             "--config: line 1")
    one_line(run_here(capsys, log, "--config", tmp_path / "nope.cfg", "--json",
                      tmp_path / "r2.json"), 2, "--config")
    assert not (tmp_path / "r2.json").exists()
