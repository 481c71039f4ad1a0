"""Benchmarks of the ROS 2 paths (numbers, not pass/fail):

    .venv/bin/python -m hdmaint.ros2_bench [--duration S] [--update-docs docs/how-to/ros2.md]

1. the monitor's recording cost: one 1 kHz sample (JointState, the Float64
   channels, a heartbeat a second) encoded and written to an MCAP file,
   per sample and as the CPU share of a 1 kHz joint;
2. `analyze` on an MCAP recording against the CSV path: the simulated hour
   of analysis.bench_speed (hdsim, 1 kHz) as a CSV, the same samples as an
   MCAP recording with every channel a monitor writes, each analysed in a
   child process (wall time, peak resident memory).
--update-docs writes the numbers into docs/how-to/ros2.md ("Benchmarks")."""
from __future__ import annotations

import argparse
import os
import platform
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from hdtools import docblock, native
from hdtools.analysis import bench_speed
from hdtools.analysis.results import read_csv
from hdtools.rosio import bagout, messages, stream
from hdtools.safeio import Outputs

BLOCK = "ros2-bench"     # hdtools.docblock


def _samples(cols: dict):
    """The CSV's rows as monitor samples (TorqueRaw = the measured torque;
    the signals a simulation lacks are zero, so every channel is written)."""
    n = len(cols["t_s"])
    t_ns = np.round(cols["t_s"] * 1e9).astype(np.int64) + 1_700_000_000 * 10**9
    out_angle = cols.get("output_angle_rad")
    for i in range(n):
        tq = float(cols["torque_nm"][i])
        yield {"stamp_ns": int(t_ns[i]), "TorqueRaw": tq, "TorqueFiltered": tq, "Ripple": 0.0,
               "MotorVelocity": 0.0, "Faults": 0.0, "KfStatus": 0.0,
               "motor_angle_rad": float(cols["motor_angle_rad"][i]),
               "output_angle_rad": None if out_angle is None else float(out_angle[i]),
               "output_velocity_rad_s": None}


def write_mcap(csv: Path, target: Path) -> tuple[int, float, float]:
    """(samples, wall s, CPU s) to write the CSV's samples as a recording."""
    header, arr = read_csv(csv)
    cols = {h: arr[:, i] for i, h in enumerate(header)}
    out = bagout.BagOutput(str(target), "mcap")
    rec = stream.Recording(messages.Encoder("joint1", 1), [out])
    t0, c0 = time.perf_counter(), time.process_time()
    n = 0
    for s in _samples(cols):
        rec.sample(s)
        n += 1
        if n % 1000 == 0:            # the 1 Hz heartbeat
            rec.diagnostics(s["stamp_ns"], "RUN", 0, {"state": "RUN"})
    rec.close()
    return n, time.perf_counter() - t0, time.process_time() - c0


MONITOR_S = 10.0


def monitor_cost(tmp: Path, mcap: bool) -> dict:
    """`hdsense monitor` on the emulated joint (python-can's virtual bus,
    1 kHz, the emulator in the same process) for MONITOR_S: its summary,
    and the process's CPU seconds per second."""
    import contextlib
    import io
    import uuid
    from hdtools import cli, emu, summary
    channel = f"bench-{uuid.uuid4().hex[:8]}"
    args = ["monitor", "-i", "virtual", channel, "--duration", str(MONITOR_S), "-q"]
    if mcap:
        args += ["--mcap", str(tmp / "monitor.mcap")]
    out = io.StringIO()
    with emu.Emulator() as j, j.attach("virtual", channel):
        c0, t0 = time.process_time(), time.perf_counter()
        with contextlib.redirect_stdout(out):
            cli.main(args)
        cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    s = summary.parse(out.getvalue())
    return {"pairs": int(s["telemetry_pairs"]), "lost": int(s["lost_telemetry"]),
            "frames": int(s["frames"]), "wall_s": wall, "cpu_per_s": cpu / wall}


def run(duration_s: float) -> list[str]:
    sim = native.find_file("hdsim", target="hdsim_cli")
    with tempfile.TemporaryDirectory() as tmp:
        csv, bag = Path(tmp) / "hour.csv", Path(tmp) / "hour.mcap"
        subprocess.run([str(sim), str(bench_speed.SCENARIO), "--duration", str(duration_s),
                        "--set", "ripple=output:2:0.8:0.4", "--csv", str(csv)],
                       check=True, capture_output=True)
        plain, rec = monitor_cost(Path(tmp), False), monitor_cost(Path(tmp), True)
        n, wall, cpu = write_mcap(csv, bag)
        sizes = (csv.stat().st_size / 1e6, bag.stat().st_size / 1e6)
        by_csv = bench_speed._child(csv, False)
        by_bag = bench_speed._child(bag, False)
    per_sample_us = 1e6 * cpu / n
    hours = n / 1000.0 / 3600.0
    t_ratio = by_bag["elapsed_s"] / by_csv["elapsed_s"]
    m_ratio = by_bag["peak_rss_mb"] / by_csv["peak_rss_mb"]
    truthless = [r["summary"].split("; error vs truth")[0] for r in (by_bag, by_csv)]
    same = ("the same result (the CSV also has the truth)" if truthless[0] == truthless[1] else
            f"results differ: {by_bag['summary']!r} vs {by_csv['summary']!r}")
    return [
        f"Measured {time.strftime('%Y-%m-%d')} on {platform.processor() or platform.machine()}"
        f" ({os.cpu_count()} cores, shared), `python -m hdmaint.ros2_bench --duration "
        f"{duration_s:g}`:",
        "",
        "| what | measured |",
        "|---|---|",
        f"| recording: one 1 kHz sample encoded and written to MCAP (7 messages, a heartbeat a "
        f"second) | {per_sample_us:.1f} us CPU, so {per_sample_us / 10:.1f} % of a core at 1 kHz "
        f"({n / wall:.0f} samples/s written, {3 * n / wall:.0f} frames/s with TELEM_C in every "
        f"sample) |",
        f"| `monitor --mcap` on the emulated joint at 1 kHz, {MONITOR_S:g} s (virtual bus, the "
        f"emulator in the same process) | {rec['pairs']} samples, {rec['lost']} lost, "
        f"{rec['frames'] / rec['wall_s']:.0f} frames/s; process CPU {100 * rec['cpu_per_s']:.0f} % "
        f"of a core, {100 * plain['cpu_per_s']:.0f} % without --mcap ({plain['lost']} lost) |",
        f"| `analyze` on {hours:.2f} h at 1 kHz, CSV ({sizes[0]:.0f} MB) | "
        f"{by_csv['elapsed_s']:.1f} s, peak {by_csv['peak_rss_mb']:.0f} MB |",
        f"| `analyze` on the same samples as an MCAP recording ({sizes[1]:.0f} MB) | "
        f"{by_bag['elapsed_s']:.1f} s, peak {by_bag['peak_rss_mb']:.0f} MB: "
        f"**{t_ratio:.2f}x** the time, **{m_ratio:.2f}x** the memory ({same}) |",
        "",
        f"The goal is at most 1.2x the CSV path's time and memory: "
        f"{'met' if t_ratio <= 1.2 and m_ratio <= 1.2 else 'not met'}. "
        "The MCAP path decodes every JointState and Float64 message in Python (rosbags); the "
        "CSV reader parses columns with numpy.",
        "The monitor's frames/s and CPU on the VM's `vcan` are not measured yet."]


def update_docs(doc: Path, lines: list[str]) -> None:
    new = docblock.splice(doc.read_text(), BLOCK, "\n".join(lines), str(doc))
    with Outputs() as out:
        out.write_text(doc, new)
        out.commit()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=bench_speed.HOUR_S)
    ap.add_argument("--update-docs", type=Path, metavar="docs/how-to/ros2.md")
    args = ap.parse_args(argv)
    lines = run(args.duration)
    print("\n".join(lines))
    if args.update_docs:
        update_docs(args.update_docs, lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
