"""Compute benchmark: runs tests/bench/bench_compute (host) and, if the
Cortex-M4 tooling exists, collects its instruction counts."""
from __future__ import annotations

import json
import os
import platform
import subprocess
from pathlib import Path

from .. import native

ROOT = Path(__file__).resolve().parents[3]


def machine() -> dict:
    model, cores = "unknown", os.cpu_count()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    cc = subprocess.run(["cc", "--version"], capture_output=True, text=True).stdout
    return {"cpu": model, "logical_cpus": cores, "kernel": platform.release(),
            "compiler": cc.splitlines()[0] if cc else "unknown",
            "build_dir": str(native.build_dir())}


def host(steps: int = 5000, reps: int = 31, warmup: int = 3) -> dict:
    exe = native.executable("bench_compute")
    out = subprocess.run([str(exe), "--json", "--steps", str(steps), "--reps", str(reps),
                          "--warmup", str(warmup)], check=True, capture_output=True,
                         text=True, timeout=300).stdout
    return json.loads(out)


def target(timeout_s: float = 300) -> dict:
    """Instruction counts from the Cortex-M4 tooling (tools/target, owned by
    the target helper).  Its output format is theirs: the JSON is embedded
    as-is.  Missing tool or failure is reported, never fatal."""
    tool = ROOT / "tools" / "target"
    if not tool.exists():
        return {"status": "not available", "note": "tools/target not in this tree; "
                "see docs/target.md"}
    helptext = subprocess.run([str(tool), "--help"], capture_output=True, text=True,
                              cwd=ROOT).stdout
    if "bench" not in helptext:
        return {"status": "not available", "note": "tools/target has no `bench` subcommand; "
                "see docs/target.md for the Cortex-M4 instruction counts"}
    try:
        proc = subprocess.run([str(tool), "bench", "--json"], capture_output=True, text=True,
                              timeout=timeout_s, cwd=ROOT)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return {"status": "failed", "note": str(exc)}
    if proc.returncode != 0:
        return {"status": "failed", "note": (proc.stderr or proc.stdout).strip()[-500:]}
    try:
        return {"status": "ok", "results": json.loads(proc.stdout)}
    except json.JSONDecodeError:
        return {"status": "ok", "text": proc.stdout[-4000:]}
