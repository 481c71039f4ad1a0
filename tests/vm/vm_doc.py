#!/usr/bin/env python3
"""The "Measured" tables of docs/how-to/socketcan.md, written by running the VM tests.

  tests/vm/vm_doc.py --build BUILD [--runs 3]

Boots the VM `--runs` times with each of the command lines CTest has for
vm_socketcan and vm_monitor (into scratch folders, not the fixtures'),
runs vm_socketcan_failure_modes once, reads each run's serial log, wall
time, image and (vm_monitor) the files the guest wrote, and writes the
blocks `socketcan-vm` and `socketcan-vm-monitor` of docs/how-to/socketcan.md with
the date and the machine.  The numbers are wall times under QEMU's TCG on
a shared host: they vary from run to run, so the blocks are never checked.
"""
from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "reliability"))
from gendoc import ROOT, GenDocError, command_of, ctest_commands, machine, run, update_doc  # noqa: E402

sys.path.insert(0, str(ROOT / "tools"))
from hdtools import protocol, summary as key_values  # noqa: E402

DOC = ROOT / "docs" / "how-to" / "socketcan.md"
CAPTURE_LINE = re.compile(r"^\(\d+\.\d+\) \w+ ([0-9A-F]{3,8})#")


def sections(text: str) -> dict[str, list[str]]:
    """The HDVM-BEGIN NAME / HDVM-END NAME blocks of a serial log."""
    out: dict[str, list[str]] = {}
    name = None
    for line in text.replace("\r", "").splitlines():
        if line.startswith("HDVM-BEGIN "):
            name = line.split(" ", 1)[1]
            out[name] = []
        elif line.startswith("HDVM-END "):
            name = None
        elif name is not None:
            out[name].append(line)
    return out


def _match(text: str, pattern: str) -> str:
    m = re.search(pattern, text)
    if not m:
        raise GenDocError(f"serial log has no line matching {pattern!r}")
    return m.group(1)


def _number(text: str, pattern: str) -> float:
    return float(_match(text, pattern))


def frame_counts(capture: list[str], node: int = 1) -> dict[str, int]:
    """Captured frames by name (hdtools.protocol's frame table)."""
    by_id = {f.can_id(node): f.name for f in protocol.frames()}
    counts: dict[str, int] = {}
    for line in capture:
        m = CAPTURE_LINE.match(line)
        if m:
            name = by_id.get(int(m.group(1), 16), "other ids")
            counts[name] = counts.get(name, 0) + 1
    return counts


def parse_log(text: str) -> dict:
    """The numbers of one VM run from its serial log."""
    if "HDVM: VERDICT PASS" not in text:
        raise GenDocError("the VM run has no PASS verdict")
    sec = sections(text)
    summary = key_values.parse("\n".join(sec.get("host-summary", [])))
    lines = text.replace("\r", "").splitlines()
    e2e_start = next((i for i, l in enumerate(lines) if l.startswith("HDVM: --- end to end")),
                     len(lines))
    ok = [i for i, l in enumerate(lines) if l.startswith("HDVM: ok  ")]
    test_s = _number(text, r"HDVM: test time in the VM ([\d.]+) s")
    return {
        "kernel": _match(text, r"HDVM: booted kernel ([^\s,]+)"),
        "boot_s": _number(text, r"guest uptime ([\d.]+) s"),
        "runner_s": _number(text, r"HDVM: runner wall time ([\d.]+) s"),
        "dump_s": _number(text, r"HDVM: test \+ console dump time in the VM ([\d.]+) s") - test_s,
        "checks_self": sum(i < e2e_start for i in ok),
        "checks_e2e": sum(i >= e2e_start for i in ok),
        "frames": frame_counts(sec.get("capture", [])),
        "summary": summary,
        "log_bytes": len(text.encode()),
    }


def parse_monitor_run(outdir: Path) -> dict:
    """The numbers of one vm_monitor run: its serial log and what the guest
    wrote to OUTDIR/share (tests/vm/guest_monitor.py)."""
    text = (outdir / "serial.log").read_text(errors="replace")
    if "HDVM: VERDICT PASS" not in text:
        raise GenDocError(f"{outdir}: the VM run has no PASS verdict")
    share = outdir / "share"
    try:
        result = json.loads((share / "result.json").read_text())
        summary = key_values.parse((share / "monitor.out").read_text())
    except (OSError, ValueError) as exc:
        raise GenDocError(f"{share}: {exc}") from None
    t = result["times_s"]
    return {
        "kernel": _match(text, r"HDVM: booted kernel ([^\s,]+)"),
        "boot_s": _number(text, r"guest uptime ([\d.]+) s"),
        "python_start_s": _number(text, r"guest_monitor.py starts at guest uptime ([\d.]+) s")
        - _number(text, r"HDVM: host root on /host, guest uptime ([\d.]+) s"),
        "imports_s": t["imports_s"],
        "monitor_start_s": t["monitor_ready_s"] - t["imports_s"],
        "device_s": {name: float(s) for name, s in
                     re.findall(r"HDVM: ok   hdsense device vcan0 (\w+).* in ([\d.]+) s", text)},
        "runner_s": t["runner_end_s"] - t["runner_start_s"],
        "drain_s": t["monitor_drained_s"] - t["runner_end_s"],
        "summary": summary,
    }


def measure_run(cmd: list[str], outdir: Path) -> dict:
    """One boot with CTest's vm_socketcan or vm_monitor command, its OUTDIR
    replaced."""
    at = 2 if cmd[1] == "--share-host" else 1
    t0 = time.monotonic()
    run(cmd[:at] + [str(outdir)] + cmd[at + 1:], 600)
    ctest_s = time.monotonic() - t0
    if at == 2:
        r = parse_monitor_run(outdir)
    else:
        r = parse_log((outdir / "serial.log").read_text(errors="replace"))
        r["initrd_bytes"] = (outdir / "initrd.cpio.gz").stat().st_size
    r["wall_s"] = float((outdir / "wall_time_s").read_text())
    r["ctest_s"] = ctest_s
    return r


def span(values: list[float], fmt: str = ".1f") -> str:
    lo, hi = min(values), max(values)
    return f"{lo:{fmt}}" if f"{lo:{fmt}}" == f"{hi:{fmt}}" else f"{lo:{fmt}}-{hi:{fmt}}"


def table(runs: list[dict], where: str, rows: list[list[str]]) -> str:
    """A generated block: the runs' line, then the Quantity | Value rows."""
    head = (f"_{len(runs)} runs of `tests/vm/vm_doc.py`, {where}; kernel {runs[0]['kernel']}, "
            "TCG; wall times vary with the host's load: not checked_")
    body = ["| Quantity | Value |", "|---|---|"] + [f"| {a} | {b} |" for a, b in rows]
    return head + "\n\n" + "\n".join(body)


def render(runs: list[dict], failure_modes_s: float, where: str) -> str:
    s = [r["summary"] for r in runs]
    first = runs[0]
    frames = ", ".join(f"{name} {span([r['frames'].get(name, 0) for r in runs], 'd')}"
                       for name in sorted({k for r in runs for k in r["frames"]}))
    samples = s[0]["samples"]
    rows = [
        ["QEMU wall time, boot + test + console dump (`OUTDIR/wall_time_s`)",
         ", ".join(f"{r['wall_s']:.1f}" for r in runs) + " s"],
        ["`vm_socketcan` as CTest runs it (image build with the kernel cached + boot)",
         span([r["ctest_s"] for r in runs]) + " s"],
        ["guest uptime when `/init` starts (kernel boot)", span([r["boot_s"] for r in runs]) + " s"],
        [f"runner wall time in the guest ({samples} samples, `--realtime`)",
         span([r["runner_s"] for r in runs]) + " s"],
        ["console dump (capture + CSV)",
         f"{span([r['dump_s'] for r in runs])} s, serial log {first['log_bytes'] // 1024} KiB"],
        ["`vm_socketcan_failure_modes` (8 cases: 4 short boots, one of 1 s)",
         f"{failure_modes_s:.1f} s"],
        ["initramfs (gzip -1)", f"{first['initrd_bytes'] / 2**20:.1f} MiB"],
        ["in-guest checks",
         f"{first['checks_self'] + first['checks_e2e']} (self-test {first['checks_self']}, "
         f"end to end {first['checks_e2e']})"],
        ["frames captured per run", frames],
        ["runner's own count", f"`can_tx_ok` {span([int(x['can_tx_ok']) for x in s], 'd')}, "
                               f"`can_tx_dropped` {span([int(x['can_tx_dropped']) for x in s], 'd')}"],
        ["runner under TCG",
         f"ISR mean {span([float(x['isr_mean_us']) / 1000 for x in s], '.2f')} ms, max "
         f"{span([float(x['isr_max_us']) / 1000 for x in s], '.0f')} ms; "
         f"{span([int(x['overruns']) for x in s], 'd')} overruns per {samples} ticks "
         "(flagged DEADLINE_MISS in the telemetry, equal to the CSV)"],
    ]
    return table(runs, where, rows)


def render_monitor(runs: list[dict], where: str) -> str:
    s = [r["summary"] for r in runs]
    steps = sorted({k for r in runs for k in r["device_s"]})
    rows = [
        ["QEMU wall time, boot + test (`OUTDIR/wall_time_s`)",
         ", ".join(f"{r['wall_s']:.1f}" for r in runs) + " s"],
        ["`vm_monitor` as CTest runs it (image build with the kernel cached + boot)",
         span([r["ctest_s"] for r in runs]) + " s"],
        ["kernel boot; Python interpreter start in the chroot (9p)",
         f"{span([r['boot_s'] for r in runs])} s; {span([r['python_start_s'] for r in runs])} s"],
        ["imports of hdtools and every hdsense subcommand (once, before forking)",
         span([r["imports_s"] for r in runs]) + " s"],
        ["`hdsense monitor` forked to its first line (socket bound)",
         span([r["monitor_start_s"] for r in runs]) + " s"],
        ["`hdsense device` each (fork, parser, DBC, answers)",
         ", ".join(f"{k} {span([r['device_s'][k] for r in runs])} s" for k in steps)],
        ["telemetry run (2000 samples, `--realtime`); the monitor done reading",
         f"{span([r['runner_s'] for r in runs])} s; "
         f"{span([r['drain_s'] for r in runs])} s after the runner's end"],
        ["monitor summary: frames, telemetry pairs, lost",
         f"{span([int(x['frames']) for x in s], 'd')}, "
         f"{span([int(x['telemetry_pairs']) for x in s], 'd')}, "
         f"{span([int(x['lost_telemetry']) for x in s], 'd')}"],
        ["monitor summary: foreign, malformed, error frames (injected)",
         f"{span([int(x['foreign_frames']) for x in s], 'd')}, "
         f"{span([int(x['malformed_frames']) for x in s], 'd')}, "
         f"{span([int(x['error_frames']) for x in s], 'd')}"],
        ["monitor's kernel receive buffer (`rx_buffer_bytes`)",
         f"{span([int(x['rx_buffer_bytes']) / 2**20 for x in s], '.0f')} MiB"],
    ]
    return table(runs, where, rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", type=Path, required=True)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--doc", type=Path, default=DOC)
    a = ap.parse_args(argv)
    if a.runs < 1:
        ap.error("--runs must be at least 1")
    try:
        where = machine()
        cmds = ctest_commands(a.build.resolve())
        vm = command_of(cmds, "vm_socketcan", a.build)
        mon = command_of(cmds, "vm_monitor", a.build)
        fm = command_of(cmds, "vm_socketcan_failure_modes", a.build)
        with tempfile.TemporaryDirectory(prefix="vm_doc.") as tmp:
            runs = []
            for i in range(a.runs):
                runs.append(measure_run(vm, Path(tmp) / f"run{i}"))
                print(f"vm_doc: vm_socketcan run {i + 1}: {runs[-1]['wall_s']:.1f} s", flush=True)
            monitor_runs = []
            for i in range(a.runs):
                monitor_runs.append(measure_run(mon, Path(tmp) / f"monitor{i}"))
                print(f"vm_doc: vm_monitor run {i + 1}: {monitor_runs[-1]['wall_s']:.1f} s",
                      flush=True)
            t0 = time.monotonic()
            run([fm[0], str(Path(tmp) / "failure-modes")] + fm[2:], 600)
            failure_modes_s = time.monotonic() - t0
        print(update_doc(a.doc, {"socketcan-vm": render(runs, failure_modes_s, where),
                                 "socketcan-vm-monitor": render_monitor(monitor_runs, where)},
                         False, ""))
    except (GenDocError, OSError, ValueError, KeyError) as exc:
        print(f"vm_doc: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
