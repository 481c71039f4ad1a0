"""tools/target budget's tables and docs/results/budget.json are rendered
from the measured numbers (tests/target, LABELS target python stm32f4; no
cross build, no QEMU: the renderers are pure functions of a budget dict).

A small hand-made budget (a clock of 100 MHz so that microseconds are easy
to check by hand) goes through the renderers; every expected cell below is
computed here from the definitions in docs/results/target.md (us = max instructions
x worst-case cycles per instruction / MHz; share = us / 1000 us), never read
back from the code.  --update-docs must keep everything outside its markers,
write all three files or none, and refuse a page without markers with one
line on stderr and exit status 2 before measuring anything.
"""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

from hdmaint import budget, budget_docs, budget_render
from hdmaint import stm32f4 as f4
from hdmaint.board import TargetError

MHZ = 100
BEGIN, END = "<!-- BEGIN generated:target-budget -->", "<!-- END generated:target-budget -->"
PATHS = ("kfpartial", "kffrozen", "kflost", "kfclamp", "kfreset", "kfrollback", "kfworst")
SIZES = {"4": 4, "6": 6, "8": 8, "default": 7, "max": 17}


def entry(states, mean, mx, best, worst):
    return {"states": states, "calls": 64, "mean": mean, "max": mx, "cycles_best": best,
            "cycles_worst": worst}


def fake_counts() -> dict:
    c = {"empty:-": entry(0, 0, 0, 1, 1), "loop:-": entry(0, 1010, 2020, 1, 1)}
    for key, n in SIZES.items():
        c[f"kf:{key}"] = entry(n, 100 * n, 100 * n + 20, 150 * n, 200 * n)
        c[f"isr:{key}"] = entry(n, 1000 + 100 * n, 1600 + 100 * n, 1500, 2000 + 150 * n)
        c[f"isrcmd:{key}"] = entry(n, 1400 + 100 * n, 2000 + 100 * n, 1900, 2600 + 150 * n)
        c[f"dense:{key}"] = entry(n, 40 * n * n, 40 * n * n, 60 * n * n, 80 * n * n)
        for i, kind in enumerate(PATHS):
            c[f"{kind}:{key}"] = entry(n, 150 * n + i, 150 * n + 10 * i, 200 * n, 300 * n)
    # The firmware default (7 states): round numbers, checked by hand below.
    c["kf:default"] = entry(7, 500, 520, 900, 1000)            # 2 cycles/insn
    c["isr:default"] = entry(7, 2000, 2600, 2500, 3000)        # 1.5
    c["isrcmd:default"] = entry(7, 2400, 3120, 3000, 3600)     # 1.5
    c["dense:default"] = entry(7, 6000, 6004, 9000, 12000)     # 2
    for kind, mx in zip(PATHS, (700, 650, 900, 1000, 800, 750, 1104)):
        c[f"{kind}:default"] = entry(7, mx - 4, mx, 1500, 2.5 * (mx - 4))  # 2.5
    # At 4 states the clamp path is the worst one.
    c["kfclamp:4"] = entry(4, 5000, 5000, 6000, 7000)
    return c


def fake_m4(heap=()) -> dict:
    counts = fake_counts()
    return {
        "flash_bytes": 40000, "ram_bytes": 90000, "stack_reserved_bytes": 8192,
        "stack_worst_bytes": 2332, "heap_symbols": list(heap), "counter_check": 2000,
        "instructions": counts, "kf_paths": budget.kf_paths_of(counts),
        "memory": {"data": 0, "bss": 81808,
                   "components": [["filter/", 30000, 0], ["board/mps2_an386", 2000, 81808]],
                   "ram_objects": [["g_mock", 57000], ["g_fw", 6400]]},
        "stack": {"main": [1000, ["main 200", "hd_fw_background 800"]], "frame": 108,
                  "isrs": [["SysTick (the 1 kHz ISR)", 1100, ["SysTick_Handler 40",
                                                              "hd_fw_isr 1060"]]],
                  "fault": [16, ["HardFault_Handler 8", "sh_exit 8"]], "notes": []},
        "marker_overhead": 1, "tick_limits": {"rx": 2, "acks": 1}, "clock_mhz": MHZ,
        "failures": []}


def fake_f4() -> dict:
    mem = {"flash": 54000, "boot": 5500, "ram": 17400, "bss": 9168, "data": 0, "noinit": 40,
           "stack": 8192, "nvm": 32768}
    return {
        "images": {"hd_odrive_v3": dict(mem), "hd_mini_cheetah": dict(mem, flash=53976)},
        "heap_symbols": [], "stack_worst_bytes": 3800, "stack_reserved_bytes": 8192,
        "counter_check": 2000, "tick_rate_per_20ms": 20,
        "interrupts": {"tick": entry(7, 2300, 3000, 3400, 4600),       # 2 cycles/insn
                       "cantx": entry(0, 350, 350, 480, 812)},          # 2.32
        "stack": {"main": [2500, ["main 336"]], "frame": 108,
                  "isrs": [["CAN1_TX_IRQHandler", 84, ["CAN1_TX_IRQHandler 0"]],
                           ["TIM1_UP_TIM10_IRQHandler", 872, ["stm32_board_tick 16"]]],
                  "fault": [36, ["stm32_fault_entry 16"]], "notes": []},
        "clock_mhz": MHZ, "failures": []}


def test_slow_paths_pick_the_worst():
    paths = budget.kf_paths_of(fake_counts())
    d = paths["default"]
    assert (d["typical"], d["worst"], d["worst_path"]) == (520, 1104, "all at once")
    assert d["dense_ratio"] == 12.0                                 # 6000 / 500
    assert (paths["4"]["worst"], paths["4"]["worst_path"]) == (5000, "clamp")
    assert paths["max"]["worst"] == 150 * 17 + 60                   # kfworst, i = 6


def test_mps2_tables():
    md = budget_render.render_budget(fake_m4())
    lines = md.splitlines()
    # Summary at the default: us = max x (cycles_worst / mean) / MHz.
    assert "| hd_kf_step, typical path | 520 | 10.4 | 1.0 % |" in lines        # 520*2/100
    assert "| hd_kf_step, worst path (all at once) | 1104 | 27.6 | 2.8 % |" in lines
    assert "| the tick (hd_fw_isr) | 2600 | 39.0 | 3.9 % |" in lines       # 2600*1.5/100
    assert ("| the tick with commands (2 in, 1 ACK out) | 3120 (1.20x the tick) | 46.8 "
            "| 4.7 % |") in lines
    assert lines.index("#### Summary") < lines.index(
        "#### Memory (hd_image.elf, arm-none-eabi-size -A)")
    # Instructions (mean / max) and the ratio with commands, per model.
    assert ("| 7 (firmware default) | 500 / 520 | 2000 / 2600 | 2400 / 3120 | 6000 / 6004 "
            "| 1.20 |") in lines
    assert "| 4 | 400 / 420 | 1400 / 2000 | 1800 / 2400 | 640 / 640 | 1.20 |" in lines
    assert ("| 7 (firmware default) | 900-1000 (10.4 us) | 2500-3000 (39.0 us) | "
            "3000-3600 (46.8 us) | 9000-12000 (120.1 us) |") in lines       # 6004*2/100
    assert "| 7 (firmware default) | 520 | 700 | 650 | 900 | 1000 | 800 | 750 | 1104 | " \
           "1104 (all at once) | 12.0 |" in lines
    assert "| 4 | 420 | 600 | 610 | 620 | 5000 | 640 | 650 | 660 | 5000 (clamp) | 1.6 |" in lines
    assert "| 17 (max) | 1720 | 2550 | 2560 | 2570 | 2580 | 2590 | 2600 | 2610 | " \
           "2610 (all at once) | 6.8 |" in lines                                             # 40*289 / 1700
    # Memory, stack, heap and the command limits come through unchanged.
    assert "| flash | 40000 B | 512 KB | .text (code, constants, vector table) + .data image |" \
        in lines
    assert "| RAM | 90000 B | 128 KB | .data 0 + .bss 81808 + reserved stack 8192 |" in lines
    assert "| filter/ | 30000 | 0 |" in lines
    assert "| **total worst case** | **2332** | reserved: 8192 B |" in lines
    assert "| SysTick (the 1 kHz ISR) | 1100 | SysTick_Handler 40 > hd_fw_isr 1060 |" in lines
    assert "HD_FW_RX_PER_TICK = 2 frames" in md and "HD_FW_ACKS_PER_TICK = 1 ACK" in md
    assert "= 2000 instructions (expected 2000)" in md and "64 calls each" in md
    assert "None.  Images link with `-nostdlib`" in md
    assert "FAIL: allocator symbols linked: malloc, _sbrk" in budget_render.render_budget(
        fake_m4(heap=["malloc", "_sbrk"]))


def test_mps2_summary():
    s = budget_render.budget_summary(fake_m4())
    assert (s["default_states"], s["max_states"]) == (7, 17)
    assert sorted(s["per_states"], key=int) == ["4", "6", "7", "8", "17"]
    d = s["per_states"]["7"]
    assert d["kf_step"]["typical"] == {"mean_instructions": 500.0, "max_instructions": 520,
                                       "cycles_best": 900, "cycles_worst": 1000,
                                       "worst_us": 10.4, "budget_fraction": 0.0104}
    w = d["kf_step"]["worst"]
    assert (w["path"], w["max_instructions"], w["worst_us"]) == ("all at once", 1104, 27.6)
    assert d["kf_step"]["dense_over_typical_mean"] == 12.0
    assert d["tick"]["worst_us"] == 39.0 and d["tick"]["budget_fraction"] == 0.039
    c = d["tick_with_commands"]
    assert (c["ratio_to_tick_max"], c["frames_in"], c["acks_out"]) == (1.2, 2, 1)
    assert c["worst_us"] == 46.8 and c["budget_fraction"] == 0.0468
    assert s["per_states"]["4"]["kf_step"]["worst"]["path"] == "clamp"
    assert (s["flash_bytes"], s["stack_worst_bytes"]) == (40000, 2332)


def fake_m4_control() -> dict:
    """fake_m4 with the control sections (issue 23)."""
    n = fake_m4()
    c = n["instructions"]
    for key, k in SIZES.items():
        c[f"isrctrl:{key}"] = entry(k, 1500 + 100 * k, 2100 + 100 * k, 1, 3000 + 200 * k)
        c[f"isrctrlcmd:{key}"] = entry(k, 1500 + 100 * k, 2000 + 100 * k, 1, 3000 + 200 * k)
    c["isrctrl:default"] = entry(7, 3000, 3900, 4000, 6000)       # 2 cycles/insn
    c["isrctrlcmd:default"] = entry(7, 3100, 3800, 4000, 4650)    # 1.5
    c["isrctrl:max"] = entry(17, 4000, 5000, 1, 8000)             # 2
    c["isrctrlcmd:max"] = entry(17, 4000, 4500, 1, 4000)          # 1
    c["ctrl:default"] = entry(7, 250, 300, 400, 750)              # 3
    return n


def test_mps2_control_rows():
    n = fake_m4_control()
    lines = budget_render.render_budget(n).splitlines()
    assert "| hd_ctrl_step (the control law, every mode) | 300 | 9.0 | 0.9 % |" in lines
    assert ("| the tick with control (a drive, 2 control frames in) | 3900 (1.50x the tick) "
            "| 78.0 | 7.8 % |") in lines                                # 3900*2/100
    assert ("| the tick with control and commands (2 in) | 3800 (1.46x the tick) | 57.0 "
            "| 5.7 % |") in lines                                       # 3800*1.5/100
    assert ("| 7 (firmware default) | 500 / 520 | 2000 / 2600 | 2400 / 3120 | 3000 / 3900 "
            "| 3100 / 3800 | 6000 / 6004 | 1.20 |") in lines
    md = "\n".join(lines)
    assert ("The worst tick with control: 78.0 us = 7.8 % of the 1000 us tick with the "
            "firmware's default filter (7 states), 100.0 us = 10.0 % with the largest "
            "(17 states); the goal is at most 5 % (not met at the default).") in md
    s = budget_render.budget_summary(n)
    assert s["ctrl_step"]["worst_us"] == 9.0 and s["ctrl_step"]["budget_fraction"] == 0.009
    ctl = s["per_states"]["7"]["tick_with_control"]
    assert (ctl["worst_us"], ctl["ratio_to_tick_max"], ctl["frames_in"]) == (78.0, 1.5, 2)
    assert s["per_states"]["17"]["tick_with_control_and_commands"]["worst_us"] == 45.0
    # without the control sections (an older bench image) the tables are as before
    assert "hd_ctrl_step" not in budget_render.render_budget(fake_m4())
    assert "ctrl_step" not in budget_render.budget_summary(fake_m4())


def test_stm32f4_tables_and_summary():
    n = fake_f4()
    lines = f4.render(n).splitlines()
    assert ("| `hd_odrive_v3.elf` (ODrive v3.x class, STM32F405RG) | 54000 B | 5500 B of 16384 "
            "| 17400 B | .data 0 + .bss 9168 + .noinit 40 + stack 8192 |") in lines
    assert any(ln.startswith("| `hd_mini_cheetah.elf` (Mini Cheetah class, STM32F446RE) | "
                             "53976 B |") for ln in lines)
    assert ("| tick interrupt: CAN service + hd_fw_isr (ADC, encoders, filter, telemetry) | 7 "
            "| 2300 / 3000 | 3400-4600 | 60.0 | 6.0 % |") in lines           # 3000*2/100
    assert ("| CAN transmit interrupt: 3 queued frames into the mailboxes | 0 | 350 / 350 "
            "| 480-812 | 8.1 | 0.8 % |") in lines                            # 350*2.32/100
    assert "| **total worst case** | **3800** | reserved: 8192 B |" in lines
    assert lines.count("| exception entry, FP context (26 words + align) | 108 | hardware |") == 2
    s = f4.summary(n)
    assert s["images"]["hd_odrive_v3"] == {"board": "ODrive v3.x class, STM32F405RG",
                                           "flash_bytes": 54000, "sector0_bytes": 5500,
                                           "ram_bytes": 17400}
    assert s["interrupts"]["tick"]["worst_us"] == 60.0
    assert s["interrupts"]["tick"]["budget_fraction"] == 0.06
    assert s["stack_worst_bytes"] == 3800


def test_replace_block_keeps_the_rest():
    text = f"# Page\n\nbefore\n\n{BEGIN}\nold table\n{END}\n\nafter\n"
    once = budget_docs.replace_block(text, "| new |", "page.md")
    assert once.startswith("# Page\n\nbefore\n\n" + BEGIN + "\n")
    assert once.endswith(END + "\n\nafter\n")
    assert "| new |" in once and "old table" not in once
    assert budget_docs.replace_block(once, "| new |", "page.md") == once      # a second run: no change
    for bad in ("no markers\n", f"{END}\n{BEGIN}\n", f"{BEGIN}\n{BEGIN}\n{END}\n",
                f"{BEGIN}\nonly the start\n"):
        with pytest.raises(TargetError, match="page.md"):
            budget_docs.replace_block(bad, "x", "page.md")


def docs_dir(tmp_path: Path) -> Path:
    docs = tmp_path / "docs"
    (docs / "results").mkdir(parents=True)
    (docs / "how-to").mkdir()
    (docs / "results" / "target.md").write_text(
        f"# Target\n\n## Budget\n\n{BEGIN}\n{END}\n\n## Files\n")
    (docs / "how-to" / "stm32f4.md").write_text(f"# STM32F4\n\n{BEGIN}\nold\n{END}\ntail\n")
    return docs


SOURCE = {"commit": "0123456789ab", "uncommitted_changes": False}


def test_update_docs_writes_all_three(tmp_path):
    docs = docs_dir(tmp_path)
    (docs / "results" / "target.md").chmod(0o644)
    budget_docs.write_budget_docs(docs, fake_m4(), fake_f4(), SOURCE)
    # not the temp file's 0600
    assert (docs / "results" / "target.md").stat().st_mode & 0o777 == 0o644
    target = (docs / "results" / "target.md").read_text()
    assert target.startswith("# Target\n\n## Budget\n\n" + BEGIN) and \
        target.endswith(END + "\n\n## Files\n")
    assert "| the tick (hd_fw_isr) | 2600 | 39.0 | 3.9 % |" in target
    assert "Measured at commit 0123456789ab;" in target
    stm = (docs / "how-to" / "stm32f4.md").read_text()
    assert "| 2300 / 3000 | 3400-4600 | 60.0 | 6.0 % |" in stm and "\nold\n" not in stm
    assert stm.endswith(END + "\ntail\n")
    b = json.loads((docs / "results" / "budget.json").read_text())
    assert b["source"] == SOURCE and b["tick_period_us"] == 1000
    assert b["mps2-an386"]["per_states"]["7"]["tick_with_commands"]["ratio_to_tick_max"] == 1.2
    assert b["stm32f4"]["images"]["hd_mini_cheetah"]["flash_bytes"] == 53976
    assert sorted(p.name for p in docs.rglob("*")) == ["budget.json", "how-to", "results",
                                                       "stm32f4.md", "target.md"]


def test_update_docs_all_or_none(tmp_path):
    docs = docs_dir(tmp_path)
    (docs / "results" / "budget.json").mkdir()      # a folder where the file should be
    before = {p: p.read_bytes() for p in docs.rglob("*") if p.is_file()}
    with pytest.raises(TargetError, match="budget.json: cannot write"):
        budget_docs.write_budget_docs(docs, fake_m4(), fake_f4(), SOURCE)
    # no page half-updated
    assert {p: p.read_bytes() for p in docs.rglob("*") if p.is_file()} == before


def run_target(*args):
    return subprocess.run([str(ROOT / "tools" / "target"), *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)


def test_update_docs_refuses_a_page_without_markers(tmp_path):
    docs = docs_dir(tmp_path)
    (docs / "how-to" / "stm32f4.md").write_text("# STM32F4\n\nno markers here\n")
    before = {p: p.read_bytes() for p in docs.rglob("*") if p.is_file()}
    r = run_target("budget", "--update-docs", "--docs", docs)
    assert r.returncode == 2 and r.stdout == ""
    assert len(r.stderr.splitlines()) == 1 and "stm32f4.md" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    assert {p: p.read_bytes() for p in docs.rglob("*") if p.is_file()} == before
    r = run_target("budget", "--update-docs", "--board", "stm32f4", "--docs", docs)
    assert r.returncode == 2 and len(r.stderr.splitlines()) == 1, r.stderr


def test_a_missing_slow_path_is_an_error_not_a_dropped_row():
    counts = fake_counts()
    label = f"{budget.KF_PATHS[0][0]}:default"
    del counts[label]
    with pytest.raises(TargetError, match=label):
        budget.kf_paths_of(counts)
    assert budget.kf_paths_of({k: v for k, v in counts.items() if not k.startswith("kf:")}) == {}
