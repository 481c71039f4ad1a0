"""The STM32F4 port's cross build under QEMU and its flashing commands
(tests/stm32f4, LABELS target python stm32f4).

- builds the stm32f4 preset (board images, netduinoplus2 image, bench);
- the netduinoplus2 image (this port's startup, clock code and TIM2 tick,
  samples in and CAN frames out over semihosting) matches the host build
  bit for bit, and says on its console that the clock fell back (QEMU has
  no RCC) and that the injected ADC conversion hit its bound;
- the budget of the board images: no heap, worst-case stack within the
  reserve, the counter's closed-form check, the tick at 1 kHz in the
  emulator, the ADC bound visible in the instruction counts;
- the board images keep flash sectors 1-2 (the records) out of every
  loadable segment, and tools/target flash builds the OpenOCD and DFU
  commands for exactly those segments; a missing image or tool is one line
  and exit 2, a missing board (no hardware here) one line and exit 1.
Missing arm-none-eabi-gcc, qemu-system-arm or openocd is a failure (tools/setup
installs them), never a skip.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TARGET = ROOT / "tools" / "target"
HOST_BUILD = Path(os.environ.get("HD_BUILD_DIR", ROOT / "build" / "host-debug"))
CROSS = Path(os.environ.get("HD_TARGET_BUILD_STM32F4", ROOT / "build" / "stm32f4"))
IMAGES = CROSS / "firmware" / "board" / "stm32f4"
NVM = (0x08004000, 0x0800C000)  # flash sectors 1 and 2


def run_target(*args, env=None, timeout=600):
    return subprocess.run([str(TARGET), *map(str, args)], cwd=ROOT, capture_output=True,
                          text=True, timeout=timeout, env=env)


def test_tools_installed():
    missing = [t for t in ("arm-none-eabi-gcc", "qemu-system-arm", "openocd", "dfu-util")
               if shutil.which(t) is None]
    assert not missing, f"missing {missing}: run tools/setup"


@pytest.fixture(scope="module")
def built():
    r = run_target("build", "--board", "netduinoplus2")
    assert r.returncode == 0, r.stdout + r.stderr
    return True


def stream(tmp_path: Path, seconds: float) -> Path:
    out = tmp_path / "s.hdraw"
    subprocess.run([HOST_BUILD / "sim" / "hdsim", ROOT / "sim" / "scenarios" / "paper_156.ini",
                    "--duration", str(seconds), "--csv", tmp_path / "sim.csv", "--raw", out],
                   check=True, capture_output=True)
    return out


def test_netduinoplus2_matches_the_host_bit_for_bit(built):
    r = run_target("compare", "--board", "netduinoplus2", "--scenario",
                   ROOT / "sim" / "scenarios" / "paper_156.ini", "--duration", 1,
                   "--host-build", HOST_BUILD, timeout=300)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out
    assert "1000 ticks" in out and "bit-identical" in out and "frames identical" in out, out


def test_emulator_reports_the_clock_fallback_and_the_adc_bound(built, tmp_path):
    r = run_target("run", "--board", "netduinoplus2", stream(tmp_path, 0.05), timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "running on the HSI fallback" in r.stdout, r.stdout
    assert "injected conversion not complete within the bound" in r.stdout, r.stdout
    assert "ticks 50" in r.stdout and "exit status 0" in r.stdout, r.stdout
    bad = tmp_path / "bad.hdraw"
    bad.write_bytes(b"NOPE" + bytes(28))
    r = run_target("run", "--board", "netduinoplus2", bad, timeout=120)
    assert r.returncode != 0 and "exit status 4" in r.stdout, r.stdout


def test_budget(built, tmp_path):
    out = tmp_path / "budget.json"
    r = run_target("budget", "--board", "stm32f4", "--json", out, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    b = json.loads(out.read_text())
    assert b["heap_symbols"] == []
    assert 0 < b["stack_worst_bytes"] <= b["stack_reserved_bytes"]
    assert b["counter_check"] == 2000  # hd_bench_loop(1010) - hd_bench_loop(10)
    assert b["tick_rate_per_20ms"] == 20
    for m in b["images"].values():
        assert m["boot"] <= 16 * 1024 and m["flash"] <= 512 * 1024 - 48 * 1024
        assert m["ram"] <= 128 * 1024 and m["nvm"] == 32 * 1024
    isr = b["interrupts"]
    assert isr["tick"]["mean"] > 1000 and isr["tickrx"]["mean"] > isr["tick"]["mean"]
    # The missing conversion costs the ADC wait's bound: 1000 polls of at
    # least three instructions (load, test, branch).
    assert isr["tickadc"]["mean"] - isr["tick"]["mean"] >= 3 * 1000


def load_segments(elf: Path) -> list:
    out = subprocess.run(["arm-none-eabi-readelf", "-lW", elf], check=True, capture_output=True,
                         text=True).stdout
    segs = []
    for line in out.splitlines():
        f = line.split()
        if f and f[0] == "LOAD" and int(f[4], 16) > 0:
            segs.append((int(f[3], 16), int(f[4], 16)))  # physical address, file size
    return segs


def section(elf: Path, name: str) -> tuple:
    out = subprocess.run(["arm-none-eabi-readelf", "-SW", elf], check=True, capture_output=True,
                         text=True).stdout
    m = re.search(rf"\s{re.escape(name)}\s+\S+\s+([0-9a-f]+)\s+[0-9a-f]+\s+([0-9a-f]+)", out)
    assert m, f"{name} not in {elf.name}"
    return int(m.group(1), 16), int(m.group(2), 16)


@pytest.mark.parametrize("board,image", [("odrive-v3", "hd_odrive_v3"),
                                         ("mini-cheetah", "hd_mini_cheetah")])
def test_flash_commands_leave_the_record_sectors_alone(built, board, image):
    elf = IMAGES / f"{image}.elf"
    segs = load_segments(elf)
    assert segs and all(a + n <= NVM[0] or a >= NVM[1] for a, n in segs), segs
    r = run_target("flash", "--board", board, "--dry-run")
    assert r.returncode == 0, r.stderr
    assert r.stdout == (f"openocd -f interface/stlink.cfg -f target/stm32f4x.cfg "
                        f"-c 'program {elf} verify reset exit'\n")
    r = run_target("flash", "--board", board, "--tool", "dfu", "--dry-run")
    assert r.returncode == 0, r.stderr
    boot, main = elf.with_suffix(".boot.bin"), elf.with_suffix(".main.bin")
    assert r.stdout == (f"dfu-util -a 0 -s 0x08000000 -D {boot}\n"
                        f"dfu-util -a 0 -s 0x0800C000:leave -D {main}\n")
    # The two files hold exactly the loadable bytes, at those addresses.
    boot_addr, boot_size = section(elf, ".boot")
    text_addr, _ = section(elf, ".text")
    assert (boot_addr, text_addr) == (0x08000000, 0x0800C000)
    assert boot.stat().st_size == boot_size
    assert main.stat().st_size == sum(n for a, n in segs if a >= NVM[1])


def test_dfu_binaries_follow_a_rebuilt_image(built, tmp_path):
    """--image ELF: the two binaries beside it are made, and made again once
    the ELF is newer than them (never the parts of an older build)."""
    elf = tmp_path / "board.elf"
    shutil.copyfile(IMAGES / "hd_odrive_v3.elf", elf)
    boot, main = elf.with_suffix(".boot.bin"), elf.with_suffix(".main.bin")
    want = (section(elf, ".boot")[1], (IMAGES / "hd_odrive_v3.main.bin").stat().st_size)
    for stale in (False, True):
        if stale:  # binaries of an earlier build, older than the ELF
            for p in (boot, main):
                p.write_bytes(b"old build")
                os.utime(p, (elf.stat().st_mtime - 60,) * 2)
        r = run_target("flash", "--board", "odrive-v3", "--tool", "dfu", "--image", elf,
                       "--dry-run")
        assert r.returncode == 0, r.stderr
        assert (boot.stat().st_size, main.stat().st_size) == want
    assert main.read_bytes() == (IMAGES / "hd_odrive_v3.main.bin").read_bytes()


def test_flash_errors_are_one_line(built, tmp_path):
    r = run_target("flash", "--board", "odrive-v3", "--image", tmp_path / "none.elf")
    assert r.returncode == 2 and r.stdout == "" and r.stderr.count("\n") == 1, r.stderr
    assert "no such image" in r.stderr
    bare = tmp_path / "bin"  # a PATH with the launcher's needs only: no openocd, no dfu-util
    bare.mkdir()
    for tool in ("bash", "dirname"):
        (bare / tool).symlink_to(shutil.which(tool))
    env = dict(os.environ, PATH=str(bare))
    elf = IMAGES / "hd_odrive_v3.elf"
    for tool, name in (("openocd", "openocd"), ("dfu", "dfu-util")):
        r = run_target("flash", "--board", "odrive-v3", "--tool", tool, "--image", elf, env=env)
        assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
        assert f"{name} not found" in r.stderr
    # The real OpenOCD with no ST-Link attached: it reads the interface and
    # target scripts, then cannot open the adapter.
    r = run_target("flash", "--board", "odrive-v3", "--image", elf, timeout=60)
    assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stdout + r.stderr
    assert "openocd failed" in r.stderr and "open failed" in r.stderr
