"""Compute benchmark: runs tests/bench/bench_compute (host) and, if the
Cortex-M4 tooling exists, collects its instruction counts."""
from __future__ import annotations

import json
import os
import platform
import subprocess
from pathlib import Path

from hdtools import native


def cpu_model() -> str:
    """The processor's name (/proc/cpuinfo), else the machine type."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.machine() or "unknown"


def machine() -> dict:
    cc = subprocess.run(["cc", "--version"], capture_output=True, text=True).stdout
    return {"cpu": cpu_model(), "logical_cpus": os.cpu_count(), "kernel": platform.release(),
            "compiler": cc.splitlines()[0] if cc else "unknown",
            "build_dir": str(native.build_dir())}


def host(steps: int = 5000, reps: int = 31, warmup: int = 3) -> dict:
    exe = native.executable("bench_compute")
    out = subprocess.run([str(exe), "--json", "--steps", str(steps), "--reps", str(reps),
                          "--warmup", str(warmup)], check=True, capture_output=True,
                         text=True, timeout=300).stdout
    return json.loads(out)


def target() -> dict:
    """Instruction counts per filter update (typical and worst of its slow
    paths) and per ISR on the Cortex-M4F image under QEMU, from the budget
    code of tools/target (hdmaint.budget; exact counts from the TCG plugin; the dense
    textbook filter is tests/bench/dense_kf_f32.c compiled into the same
    image).  A missing tool or a failure is reported, never fatal."""
    from hdmaint import board, budget as budget_tool
    try:
        budget = budget_tool.budget(board.BOARDS["mps2-an386"])
    except (board.TargetError, OSError) as exc:
        return {"status": "failed", "note": str(exc)[-500:]}
    if budget["failures"]:
        return {"status": "failed", "note": "; ".join(budget["failures"])[-500:]}
    rows = {}
    for key, v in budget.get("instructions", {}).items():
        kind = key.partition(":")[0]
        if kind in ("kf", "isr", "dense") and v.get("states"):
            rows.setdefault(int(v["states"]), {})[kind] = v["max"]
    for key, path in budget.get("kf_paths", {}).items():
        states = budget["instructions"][f"kf:{key}"]["states"]
        rows.setdefault(int(states), {})["kf_worst"] = path["worst"]
    return {"status": "ok", "instructions_max": rows,
            "flash_bytes": budget.get("flash_bytes"),
            "stack_worst_bytes": budget.get("stack_worst_bytes")}
