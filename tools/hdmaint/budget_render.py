"""tools/target budget's tables (markdown) and its part of
docs/results/budget.json, rendered from budget.budget()'s numbers: pure
functions of that dict.  Standard library only."""
from __future__ import annotations

from .budget import KF_PATHS, MCU_CLOCKS_MHZ, MODELS, TICK_PERIOD_US, worst_us


def md_table(header: list, rows: list) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def stack_table(st: dict, total: int, reserved: int, fault_name: str,
                fault_context: str) -> str:
    rows = [["main loop (Reset_Handler + main)", st["main"][0], " > ".join(st["main"][1])]]
    for name, nbytes, path in st["isrs"]:
        rows.append(["exception entry, FP context (26 words + align)", st["frame"], "hardware"])
        rows.append([name, nbytes, " > ".join(path)])
    rows += [[f"exception entry ({fault_context})", st["frame"], "hardware"],
             [fault_name, st["fault"][0], " > ".join(st["fault"][1])],
             ["**total worst case**", f"**{total}**", f"reserved: {reserved} B"]]
    return md_table(["context", "bytes", "deepest path"], rows)


def command_label(n: dict) -> str:
    return f"ISR + commands ({n['tick_limits']['rx']} in, {n['tick_limits']['acks']} ACK out)"


def headline_table(n: dict) -> str:
    """The firmware default's filter step, tick and tick with commands in one
    table (what docs and the README quote), from budget_summary."""
    s = budget_summary(n)
    states = s["default_states"]
    row = s["per_states"][str(states)]
    step = row["kf_step"]
    parts = [("hd_kf_step, typical path", step["typical"], "")]
    if "worst" in step:
        parts.append((f"hd_kf_step, worst path ({step['worst']['path']})", step["worst"], ""))
    cmd = row["tick_with_commands"]
    parts += [("the tick (hd_fw_isr)", row["tick"], ""),
              (f"the tick with commands ({cmd['frames_in']} in, {cmd['acks_out']} ACK out)", cmd,
               f" ({cmd['ratio_to_tick_max']:.2f}x the tick)")]
    if "ctrl_step" in s:
        ctl, ctlcmd = row["tick_with_control"], row["tick_with_control_and_commands"]
        parts += [("hd_ctrl_step (the control law, every mode)", s["ctrl_step"], ""),
                  (f"the tick with control (a drive, {ctl['frames_in']} control frames in)", ctl,
                   f" ({ctl['ratio_to_tick_max']:.2f}x the tick)"),
                  (f"the tick with control and commands ({cmd['frames_in']} in)", ctlcmd,
                   f" ({ctlcmd['ratio_to_tick_max']:.2f}x the tick)")]
    return md_table([f"{states} states (firmware default)", "instructions (max)",
                     f"estimated worst-case us at {n['clock_mhz']} MHz",
                     f"share of the {TICK_PERIOD_US} us tick"],
                    [[what, f"{c['max_instructions']}{note}", f"{c['worst_us']:.1f}",
                      f"{100 * c['budget_fraction']:.1f} %"] for what, c, note in parts])


def render_budget(n: dict) -> str:
    """The mps2-an386 budget tables (markdown) from budget()'s numbers."""
    mem, ins, mhz = n["memory"], n["instructions"], n["clock_mhz"]
    out = ["#### Summary\n", headline_table(n),
           "\n#### Memory (hd_image.elf, arm-none-eabi-size -A)\n",
           md_table(["region", "used", "of", "contents"], [
               ["flash", f"{n['flash_bytes']} B", "512 KB",
                ".text (code, constants, vector table) + .data image"],
               ["RAM", f"{n['ram_bytes']} B", "128 KB",
                f".data {mem['data']} + .bss {mem['bss']} + reserved stack "
                f"{n['stack_reserved_bytes']}"]]),
           "\nBy component (linker map):\n",
           md_table(["component", "flash B", "RAM B (static)"], mem["components"]),
           "\nLargest RAM objects: " +
           ", ".join(f"`{name}` {size} B" for name, size in mem["ram_objects"]) +
           ".  The firmware's own state is `g_fw` (hd_fw_t, two pipelines: the running "
           "model and the one a command builds); `g_mock`, `g_stream`, `g_dump`, `g_canlog` "
           "are the QEMU board's I/O (NVM in RAM, semihosting buffers) that a real board "
           "replaces with peripherals.",
           "\n#### Heap\n",
           ("FAIL: allocator symbols linked: " + ", ".join(n["heap_symbols"])
            if n["heap_symbols"] else
            "None.  Images link with `-nostdlib` (no libc; the board supplies memcpy/memset/"
            "memcmp/strlen/strcmp), the linker script `ASSERT`s that malloc/free/_sbrk are "
            "undefined, and a post-build step checks the symbol table (nm): no "
            "malloc/calloc/realloc/free/_sbrk."),
           "\n#### Worst-case stack (-fstack-usage + -fcallgraph-info call graph)\n",
           stack_table(n["stack"], n["stack_worst_bytes"], n["stack_reserved_bytes"],
                       "HardFault handler", "fault inside the ISR"),
           "\nIndirect calls (HAL vtable, CAN transmit hook) are bounded by the deepest HAL "
           "backend function linked into the image; no recursion" +
           ("; notes: " + "; ".join(n["stack"]["notes"]) if n["stack"]["notes"] else "") + "."]
    cmd = command_label(n)
    kinds = [("kf", "hd_kf_step"), ("isr", "ISR (hd_fw_isr)"), ("isrcmd", cmd),
             ("dense", "dense textbook KF")]
    control = f"isrctrl:{MODELS[0][0]}" in ins
    if control:
        kinds[3:3] = [("isrctrl", "ISR + control"), ("isrctrlcmd", "ISR + control + commands")]
    ident = f"isrident:{MODELS[0][0]}" in ins
    if ident:
        kinds.insert(5, ("isrident", "ISR + control + identification run"))
    insn_rows, cycle_rows = [], []
    for key, note in MODELS:
        states = f"{ins[f'kf:{key}']['states']}{note}"
        cells = [ins[f"{kind}:{key}"] for kind, _ in kinds]
        insn_rows.append([states] + [f"{c['mean']:.0f} / {c['max']}" for c in cells] +
                         [f"{ins[f'isrcmd:{key}']['max'] / ins[f'isr:{key}']['max']:.2f}"])
        cycle_rows.append([states] + [f"{c['cycles_best']:.0f}-{c['cycles_worst']:.0f} "
                                      f"({worst_us(c, mhz):.1f} us)" for c in cells])
    out += ["\n#### Instructions per call (QEMU TCG plugin, exact) and estimated cycles\n",
            f"Counted by tools/qemu-plugin/hdcount.c between the image's markers, "
            f"{ins['kf:4']['calls']} calls each; marker overhead ({n['marker_overhead']} "
            f"instruction) subtracted.  Counter check: hd_bench_loop(1010) - hd_bench_loop(10) "
            f"= {n['counter_check']} instructions (expected 2000).  These are **instructions, "
            "not cycles**: QEMU has no cycle model.  Cycles are estimated from the "
            "per-instruction execution counts with the Cortex-M4 TRM timings (ALU 1, LDR 1-2, "
            "STR 1-2, taken branch 2-4, VADD/VMUL 1, VMLA 3, VLDR/VSTR 2, VDIV/VSQRT 14, "
            "push/pop 1+N), zero wait states; range = best..worst case.\n",
            "Instructions per call, mean / max:\n",
            md_table(["states"] + [k[1] for k in kinds] + ["with commands / ISR (max)"],
                     insn_rows),
            "\nEstimated Cortex-M4 cycles per call, mean best-worst (worst-case time):\n",
            md_table(["states"] + [k[1] for k in kinds], cycle_rows),
            f"\nus = worst-case time at {mhz} MHz ({MCU_CLOCKS_MHZ[0][0]}; "
            f"{MCU_CLOCKS_MHZ[1][0]} at {MCU_CLOCKS_MHZ[1][1]} MHz is within 2 %): max "
            "instructions x worst-case cycles per instruction of that section.  The ISR budget "
            f"is {TICK_PERIOD_US} us per tick.  ISR = the whole 1 kHz tick body: ADC and "
            "encoder reads (hal_mock), calibration, encoder deltas, tracker, expected torque, "
            "filter, faults, telemetry (2 frames at 1 kHz) and the heartbeat (tick 0); "
            f"'{cmd}' adds command frames on every tick: the tick takes at most "
            f"HD_FW_RX_PER_TICK = {n['tick_limits']['rx']} frames (a BLOCK_ENABLE toggle of "
            "block 0, applied by the tick to the running filter, and a SET_PARAM r_nm2, whose "
            "model rebuild the background does between ticks, outside the count), applies the "
            "change the background prepared and sends at most HD_FW_ACKS_PER_TICK = "
            f"{n['tick_limits']['acks']} ACK.  Other command mixes are not enumerated: this is "
            "a measured load, not a proof of the worst case."]
    if control:
        c = ins["ctrl:default"]
        worst = {key: max(worst_us(ins[f"{k}:{key}"], mhz) for k in ("isrctrl", "isrctrlcmd"))
                 for key in ("default", "max")}
        out += [f"\nControl: 'ISR + control' is the tick on a board with a drive: "
                "the control stage (setpoint checks, watchdog and fault reactions, "
                "control/hd_ctrl's law, the drive command) runs every tick, with "
                f"HD_FW_RX_PER_TICK = {n['tick_limits']['rx']} control frames arriving every "
                "tick (a TORQUE SETPOINT and a GAINS frame, decoded and checked by the tick) "
                "and CTRL_STATE sent with the telemetry; 'ISR + control + commands' runs "
                "TORQUE with the command frames above instead, but every other SET_PARAM is a "
                "ctrl_damp_nm_s_rad that changes, so the control stage restarts the law on "
                "the new settings' plan (the plan itself is built in the background).  "
                "hd_ctrl_step alone, cycling "
                "its modes over inputs that reach the velocity, position and current limits: "
                f"{c['mean']:.0f} / {c['max']} instructions (mean / max), "
                f"{c['cycles_best']:.0f}-{c['cycles_worst']:.0f} cycles, "
                f"{worst_us(c, mhz):.2f} us at {mhz} MHz.  The worst tick with control: "
                f"{worst['default']:.1f} us = {100 * worst['default'] / TICK_PERIOD_US:.1f} % of "
                f"the {TICK_PERIOD_US} us tick with the firmware's default filter "
                f"({ins['kf:default']['states']} states), {worst['max']:.1f} us = "
                f"{100 * worst['max'] / TICK_PERIOD_US:.1f} % with the largest "
                f"({ins['kf:max']['states']} states); the goal is at most 5 % "
                f"({'met' if worst['default'] <= 0.05 * TICK_PERIOD_US else 'not met'} at the "
                "default)."]
    if control and ident:
        w = {key: worst_us(ins[f"isrident:{key}"], mhz) for key in ("default", "max")}
        out += [f"\nIdentification: 'ISR + control + identification run' is 'ISR + control' "
                "with an IDENT_START in place of the first GAINS frame: from the next tick "
                "the multisine's sample is added to the drive command and an IDENT frame goes "
                "out every tick (the waveform is built by the background, outside the count).  "
                "It runs while a joint is tuned (docs/how-to/tune-torque-loop.md), not in "
                f"operation: {w['default']:.1f} us = {100 * w['default'] / TICK_PERIOD_US:.1f} % "
                f"of the tick at the default, {w['max']:.1f} us = "
                f"{100 * w['max'] / TICK_PERIOD_US:.1f} % with the largest filter."]
    if n["kf_paths"]:
        rows = []
        for key, note in MODELS:
            r = n["kf_paths"][key]
            rows.append([f"{ins[f'kf:{key}']['states']}{note}", r["typical"]] + [r[k] for k, _ in KF_PATHS] +
                        [f"{r['worst']} ({r['worst_path']})", f"{r['dense_ratio']:.1f}"])
        out += ["\nhd_kf_step by path, max instructions per call (the bench image forces each "
                "path on every call: every gain fraction below 1, no block frozen (motor blocks "
                "below q_motion_ref_rad, output_learn_scale 0.5); motor blocks over Nyquist; a "
                "phase advance beyond four turns; every covariance block above p_max; a "
                "non-finite state; a transient's event ending (its blocks going back); all of "
                "them (but partial gains and the rollback) with an offset jump):\n",
                md_table(["states", "typical"] + [name for _, name in KF_PATHS] +
                         ["worst case", "dense / typical (mean)"], rows)]
    return "\n".join(out)


def timing(c: dict, mhz: float) -> dict:
    """One counted section for docs/results/budget.json."""
    us = worst_us(c, mhz)
    return {"mean_instructions": round(float(c["mean"]), 1), "max_instructions": c["max"],
            "cycles_best": round(c["cycles_best"]), "cycles_worst": round(c["cycles_worst"]),
            "worst_us": round(us, 2), "budget_fraction": round(us / TICK_PERIOD_US, 4)}


def budget_summary(n: dict) -> dict:
    """The mps2-an386 part of docs/results/budget.json: per filter size, the
    filter step (typical and worst path), the tick and the tick with
    commands, as instructions, estimated cycles, us and fraction of the
    tick."""
    ins, mhz = n["instructions"], n["clock_mhz"]
    per_states = {}
    for key, _ in MODELS:
        kf, isr, cmd = (ins[f"{k}:{key}"] for k in ("kf", "isr", "isrcmd"))
        step = {"typical": timing(kf, mhz)}
        if n["kf_paths"]:
            path = n["kf_paths"][key]
            kind = max(KF_PATHS, key=lambda k: path[k[0]])[0]
            step["worst"] = dict(timing(ins[f"{kind}:{key}"], mhz), path=path["worst_path"])
        step["dense"] = timing(ins[f"dense:{key}"], mhz)
        if n["kf_paths"]:
            step["dense_over_typical_mean"] = n["kf_paths"][key]["dense_ratio"]
        per_states[str(kf["states"])] = {
            "kf_step": step, "tick": timing(isr, mhz),
            "tick_with_commands": dict(timing(cmd, mhz),
                                       ratio_to_tick_max=round(cmd["max"] / isr["max"], 2),
                                       frames_in=n["tick_limits"]["rx"],
                                       acks_out=n["tick_limits"]["acks"])}
        if f"isrctrl:{key}" in ins:
            for name, kind in (("tick_with_control", "isrctrl"),
                               ("tick_with_control_and_commands", "isrctrlcmd"),
                               ("tick_with_identification", "isrident")):
                if f"{kind}:{key}" not in ins:
                    continue
                c = ins[f"{kind}:{key}"]
                per_states[str(kf["states"])][name] = dict(
                    timing(c, mhz), ratio_to_tick_max=round(c["max"] / isr["max"], 2),
                    frames_in=n["tick_limits"]["rx"])
    control = {"ctrl_step": timing(ins["ctrl:default"], mhz)} if "ctrl:default" in ins else {}
    return {**control,"image": "hd_image.elf (instructions: hd_bench.elf)",
            "flash_bytes": n["flash_bytes"], "ram_bytes": n["ram_bytes"],
            "stack_worst_bytes": n["stack_worst_bytes"],
            "stack_reserved_bytes": n["stack_reserved_bytes"],
            "default_states": ins["kf:default"]["states"], "max_states": ins["kf:max"]["states"],
            "per_states": per_states}
