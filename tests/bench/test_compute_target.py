"""tools/bench's Cortex-M4 part (hdmaint.bench.compute.target) takes the
numbers from the budget code of tools/target (hdmaint.budget) in-process: the rows it
reports are the budget's, and a setup problem or a failed check is reported
as a status, never raised."""

from hdmaint import budget as budget_tool
from hdmaint.board import TargetError
from hdmaint.bench import compute

BUDGET = {
    "flash_bytes": 40000, "ram_bytes": 80000, "stack_reserved_bytes": 8192,
    "stack_worst_bytes": 2500, "heap_symbols": [], "counter_check": 2000,
    "instructions": {
        "kf:default": {"states": 7, "calls": 64, "mean": 670.0, "max": 675},
        "isr:default": {"states": 7, "calls": 64, "mean": 2100.0, "max": 2590},
        "isrcmd:default": {"states": 7, "calls": 64, "mean": 2500.0, "max": 2990},
        "dense:default": {"states": 7, "calls": 64, "mean": 8404.0, "max": 8412},
        "kf:max": {"states": 17, "calls": 64, "mean": 2200.0, "max": 2216},
        "empty:-": {"states": 0, "calls": 1, "mean": 0.0, "max": 0},
    },
    "kf_paths": {"default": {"typical": 675, "worst": 1440, "worst_path": "all at once"},
                 "max": {"typical": 2216, "worst": 4140, "worst_path": "all at once"}},
    "failures": [],
}


def test_rows_are_the_budget_numbers(monkeypatch):
    monkeypatch.setattr(budget_tool, "budget", lambda board=None: BUDGET)
    res = compute.target()
    assert res["status"] == "ok"
    assert res["instructions_max"] == {
        7: {"kf": 675, "isr": 2590, "dense": 8412, "kf_worst": 1440},
        17: {"kf": 2216, "kf_worst": 4140}}
    assert res["flash_bytes"] == 40000 and res["stack_worst_bytes"] == 2500


def test_failed_check_and_setup_problem_are_reported(monkeypatch):
    failed = dict(BUDGET, failures=["worst-case stack 9000 B exceeds the reserved 8192 B"])
    monkeypatch.setattr(budget_tool, "budget", lambda board=None: failed)
    res = compute.target()
    assert res["status"] == "failed" and "9000 B" in res["note"]

    def missing(board=None):
        raise TargetError("arm-none-eabi-gcc not found: run tools/setup")
    monkeypatch.setattr(budget_tool, "budget", missing)
    res = compute.target()
    assert res == {"status": "failed", "note": "arm-none-eabi-gcc not found: run tools/setup"}
