#!/usr/bin/env python3
"""Runs inside the SocketCAN test VM (tests/vm, docs/how-to/socketcan.md): the
host tools on a real kernel's vcan0, through python-can's socketcan
interface (AF_CAN raw sockets, kernel time stamps, error frames).  /init
runs it chrooted into the host's root (run-vm.sh --share-host), so the
host's interpreter, venv and build are used as they are; OUT is the
writable folder shared back to the host.

  guest_monitor.py --runner HDJOINT_HOST --scenario INI --out DIR [--duration 2]

Every hdsense command runs as a forked child calling hdtools.cli.main(argv)
-- what `hdsense ARGS` runs -- after this process imported hdtools and
every subcommand once: an interpreter start with those imports costs about
10 s under TCG.  A capture socket (raw AF_CAN, CAN FD on, 32 MB receive
buffer, kernel time stamps) is opened first and read only at the end, so it
costs no CPU while the others run.

1. `hdsense monitor vcan0 --log monitor.log` starts and runs to the end.
2. Commands: once the monitor has printed its first line (socket bound),
   hdjoint-host runs the simulated joint on vcan0 with telemetry off
   (IDLE_CONFIG), the scenario held for an hour, and an NVM file; the
   monitor hears it and asks its GET_PARAMs; then `hdsense device vcan0`
   set r_nm2 0.5 and save; then SIGTERM to the runner (exit 143, its NVM
   file whole).
3. Telemetry: hdjoint-host --realtime --duration S at the default 1 kHz
   telemetry; at its first TELEM_A, frames of other devices and bad frames
   are injected (injected()).  Under TCG the monitor falls seconds behind
   the 4200 frames/s; its receive buffer holds them (grow_rx_buffer).
4. After the runner's exit an end marker (END_ID) is sent; when it is in
   the monitor's log (flushed every 0.5 s), the monitor has read everything
   before it and gets SIGTERM.
5. OUT gets capture.log (candump -l, kernel stamps), monitor.log,
   monitor.out/.err, device-NAME.out/.err, runner-device.out, runner.out,
   samples.csv, nvm.bin and result.json (exit codes, timings, injected).

Prints "HDVM: ok|FAIL" lines; exits 0 only if every process ended as
expected.  The data are checked on the host (test_vm_monitor.py).
"""
from __future__ import annotations

import argparse
import gc
import glob
import importlib
import json
import os
import re
import select
import shutil
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

IFACE = "vcan0"
RUN = Path("/run/hdvm-run")           # guest tmpfs: nothing slow in the hot path
END_ID = 0x7FE                        # 11-bit end marker, foreign to the joint
END_LINE = f" {IFACE} {END_ID:03X}#".encode()
IDLE_CONFIG = "telemetry_rate_hz = 0\n"   # the commands phase: heartbeats and answers only
SO_TIMESTAMPNS = 35                   # <asm-generic/socket.h>, not in Python's socket
SO_RCVBUFFORCE = 33
CAN_RAW_ERR_FILTER = 2              # <linux/can/raw.h>, not in Python 3.11's socket
CAN_ERR_FLAG = 0x20000000
CAN_EFF_FLAG = 0x80000000
CAN_RTR_FLAG = 0x40000000
CAN_ERR_CRTL = 0x00000004
CANFD_MTU = 72
# Each costs about 3 s under TCG (mostly building the parser and loading the
# DBC), so only the round trip: the value set, saved, and (on the host)
# still in force after a boot from the saved NVM.
DEVICE_STEPS = (("set", ["set", "r_nm2", "0.5"]), ("save", ["save"]))

failures = 0
T0 = time.monotonic()
with open("/proc/uptime") as _f:
    print(f"HDVM: guest_monitor.py starts at guest uptime {_f.read().split()[0]} s", flush=True)


def check(ok: bool, what: str) -> bool:
    global failures
    failures += not ok
    print(f"HDVM: {'ok  ' if ok else 'FAIL'} {what}", flush=True)
    return ok


def note(what: str) -> None:
    print(f"HDVM: {what}", flush=True)


def injected(protocol) -> list[tuple[str, int, bytes, int]]:
    """(what, can_id with kernel flags, data, length) of the frames injected
    while the runner runs: other devices, another joint node, frames on this
    node's identifiers the monitor must call malformed, an FD frame (the
    monitor's classic socket must never see it) and an error frame."""
    telem_a = protocol.frame("TELEM_A")
    return [
        ("foreign 11-bit (a CANopen heartbeat)", 0x701, b"\x05", 1),
        ("foreign 29-bit (another protocol)", CAN_EFF_FLAG | 0x18FF0001, bytes(8), 8),
        ("another joint: node 2's TELEM_A", CAN_EFF_FLAG | telem_a.can_id(2), bytes(8), 8),
        ("malformed: node 1's TELEM_A with 4 bytes", CAN_EFF_FLAG | telem_a.can_id(1),
         bytes(4), 4),
        ("malformed: remote frame on node 1's TELEM_A",
         CAN_EFF_FLAG | CAN_RTR_FLAG | telem_a.can_id(1), b"", 8),
        ("CAN FD frame on node 1's TELEM_A", CAN_EFF_FLAG | telem_a.can_id(1),
         bytes(range(12)), 12),
        ("error frame (controller problem)", CAN_ERR_FLAG | CAN_ERR_CRTL,
         bytes([0, 0x04, 0, 0, 0, 0, 0, 0]), 8),
    ]


def raw_socket(rcvbuf: int = 0, only: int | None = None) -> socket.socket:
    """A raw socket on IFACE: every frame (FD and error frames too), or only
    the frames of one identifier (can_id with its EFF flag)."""
    s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    s.setsockopt(socket.SOL_CAN_RAW, socket.CAN_RAW_FD_FRAMES, 1)
    if only is not None:
        mask = CAN_EFF_FLAG | CAN_RTR_FLAG | 0x1FFFFFFF
        s.setsockopt(socket.SOL_CAN_RAW, socket.CAN_RAW_FILTER, struct.pack("=II", only, mask))
    else:
        s.setsockopt(socket.SOL_CAN_RAW, CAN_RAW_ERR_FILTER, 0x1FFFFFFF)
    if rcvbuf:
        s.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, rcvbuf)
        s.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
    s.bind((IFACE,))
    return s


def send_raw(s: socket.socket, can_id: int, data: bytes, length: int, fd: bool) -> None:
    if fd:
        s.send(struct.pack("=IBBBB64s", can_id, length, 0, 0, 0, data))
    else:
        s.send(struct.pack("=IB3x8s", can_id, length, data))


def candump(sec: int, nsec: int, frame: bytes) -> str:
    """One candump -l line (can-utils' format: error frames with their
    8-digit flagged id, remote frames R + length, FD ## + flags)."""
    can_id, length, flags = struct.unpack_from("=IBB", frame)
    data = frame[8:8 + length]
    if can_id & CAN_ERR_FLAG:
        ident = f"{can_id & 0x3FFFFFFF:08X}"
    elif can_id & CAN_EFF_FLAG:
        ident = f"{can_id & 0x1FFFFFFF:08X}"
    else:
        ident = f"{can_id & 0x7FF:03X}"
    if len(frame) == CANFD_MTU:
        body = f"#{flags & 0xF:X}{data.hex().upper()}"
    elif can_id & CAN_RTR_FLAG:
        body = "R" + (f"{length:X}" if length else "")
    else:
        body = data.hex().upper()
    return f"({sec}.{nsec // 1000:06d}) {IFACE} {ident}#{body}\n"


def drain_capture(s: socket.socket, path: Path) -> int:
    s.setblocking(False)
    n = 0
    with open(path, "w") as f:
        while True:
            try:
                frame, anc, _, _ = s.recvmsg(CANFD_MTU, socket.CMSG_SPACE(16))
            except BlockingIOError:
                return n
            sec, nsec = next(struct.unpack("=qq", d[:16]) for lvl, typ, d in anc
                             if lvl == socket.SOL_SOCKET and typ == SO_TIMESTAMPNS)
            f.write(candump(sec, nsec, frame))
            n += 1


def spawn(cli, name: str, argv: list[str]) -> int:
    """hdsense ARGV in a forked child, stdout/stderr to RUN/NAME.out/.err."""
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid:
        return pid
    rc = 4
    try:
        for fd, suffix in ((1, "out"), (2, "err")):
            f = os.open(RUN / f"{name}.{suffix}", os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
            os.dup2(f, fd)
            os.close(f)
        try:
            rc = cli.main(argv)
        except SystemExit as exc:
            rc = exc.code if isinstance(exc.code, int) else 2
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(rc)


def wait_child(pid: int, timeout_s: float) -> int | None:
    """Exit status (negative: killed by that signal), None on timeout."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        got, status = os.waitpid(pid, os.WNOHANG)
        if got == pid:
            return os.waitstatus_to_exitcode(status)
        time.sleep(0.05)
    return None


def wait_for(predicate, timeout_s: float, step_s: float = 0.05) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(step_s)
    return predicate()


def monitor_log_count(needle: bytes) -> int:
    """How often needle is in the monitor's log so far (its temporary file
    while it runs: whole lines, written every 0.5 s)."""
    return sum(Path(p).read_bytes().count(needle)
               for p in glob.glob(str(RUN / ".monitor.log.*.tmp")))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runner", required=True)
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--duration", default="2")
    a = ap.parse_args()
    # The tools take the C library from the runner's build tree (hdtools.native
    # never builds, and the VM's environment has no HD_BUILD_DIR).
    os.environ.setdefault("HD_BUILD_DIR", str(Path(a.runner).resolve().parents[2]))
    RUN.mkdir(parents=True, exist_ok=True)
    times: dict[str, float] = {}
    rcs: dict[str, int | None] = {}

    def mark(key: str) -> float:
        times[key] = round(time.monotonic() - T0, 3)
        return times[key]

    def runner(name: str, extra: list[str], scenario: str = a.scenario) -> subprocess.Popen:
        return subprocess.Popen(
            [a.runner, "--sensors", f"sim:{scenario}", "--can", f"socketcan:{IFACE}",
             "--realtime"] + extra, stdout=open(RUN / f"{name}.out", "wb"),
            stderr=subprocess.STDOUT)

    note("--- hdsense monitor / device on vcan0 (python-can socketcan)")
    from hdtools import cli, cmd_monitor, protocol
    for name in cli.SUBCOMMANDS:          # what every `hdsense` start imports
        importlib.import_module(f"hdtools.cmd_{name}")
    gc.freeze()     # the children's garbage collector leaves these pages shared (~0.4 s each)
    note(f"python imports {mark('imports_s'):.2f} s")
    ack_line = f" {IFACE} {protocol.frame('ACK').can_id(1):08X}#".encode()

    capture = raw_socket(rcvbuf=32 << 20)
    inject = raw_socket()
    monitor = spawn(cli, "monitor", ["monitor", IFACE, "--log", str(RUN / "monitor.log"),
                                     "--duration", "150", "--interval", "0.5"])
    procs: list[subprocess.Popen] = []
    try:
        said = lambda name: (RUN / name).exists() and (RUN / name).stat().st_size > 0  # noqa: E731
        wait_for(lambda: said("monitor.out") or said("monitor.err"), 60)
        ready = said("monitor.out") and not said("monitor.err")
        if not check(ready, f"hdsense monitor started ({mark('monitor_ready_s'):.2f} s)"):
            return 1
        # -- commands: a joint with telemetry off, hdsense device
        (RUN / "idle.cfg").write_text(IDLE_CONFIG)
        held = re.sub(r"(?m)^duration_s\s*=.*$", "duration_s = 3600",
                      Path(a.scenario).read_text())
        (RUN / "held.ini").write_text(held)
        procs.append(runner("runner-device", ["--config", str(RUN / "idle.cfg"), "--nvm",
                                              str(RUN / "nvm.bin")], str(RUN / "held.ini")))
        n_query = len(cmd_monitor.QUERY_PARAMS)
        asked = wait_for(lambda: monitor_log_count(ack_line) >= n_query, 60, 0.2)
        check(asked, f"the monitor's {n_query} GET_PARAMs answered "
                     f"({mark('monitor_queried_s'):.2f} s)")
        for name, args in DEVICE_STEPS:
            t = time.monotonic()
            pid = spawn(cli, f"device-{name}", ["device", IFACE, "--timeout", "3"] + args)
            rcs[f"device-{name}"] = rc = wait_child(pid, 60)
            check(rc == 0, f"hdsense device {IFACE} {' '.join(args)}: exit {rc} "
                           f"in {time.monotonic() - t:.2f} s")
        procs[-1].send_signal(signal.SIGTERM)
        rcs["runner-device"] = rc = procs[-1].wait(timeout=30)
        check(rc == 143, f"runner (commands) ended on SIGTERM: exit {rc} "
                         f"({mark('device_done_s'):.2f} s)")
        # -- telemetry at 1 kHz, with foreign and bad frames
        bell = raw_socket(only=CAN_EFF_FLAG | protocol.frame("TELEM_A").can_id(1))
        procs.append(runner("runner", ["--duration", a.duration,
                                       "--csv", str(RUN / "samples.csv")]))
        mark("runner_start_s")
        heard = bool(select.select([bell], [], [], 30)[0])
        check(heard, f"the runner's first TELEM_A on {IFACE} ({mark('first_telem_s'):.2f} s)")
        for what, can_id, data, length in injected(protocol):
            send_raw(inject, can_id, data, length, fd=what.startswith("CAN FD"))
        rcs["runner"] = rc = procs[-1].wait(timeout=60)
        check(rc == 0, f"runner (telemetry) exit {rc} ({mark('runner_end_s'):.2f} s)")
        note(f"runner wall time {times['runner_end_s'] - times['runner_start_s']:.2f} s")
        send_raw(inject, END_ID, b"\xee", 1, fd=False)
        seen = wait_for(lambda: monitor_log_count(END_LINE) > 0, 90, 0.2)
        check(seen, f"the end marker in the monitor's log "
                    f"({mark('monitor_drained_s') - times['runner_end_s']:.2f} s after the "
                    "runner's end)")
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
        os.kill(monitor, signal.SIGTERM)
        rcs["monitor"] = rc = wait_child(monitor, 30)
        check(rc == 0, f"hdsense monitor ended on SIGTERM: exit {rc}")
        if rc is None:
            os.kill(monitor, signal.SIGKILL)
        mark("monitor_end_s")
        note(f"capture: {drain_capture(capture, RUN / 'capture.log')} frames")
        result = {"exit": rcs, "times_s": times, "end_id": END_ID, "duration_s": a.duration,
                  "injected": [{"what": w, "can_id": i, "len": n} for w, i, _, n in
                               injected(protocol)]}
        (RUN / "result.json").write_text(json.dumps(result, indent=1) + "\n")
        for p in sorted(RUN.iterdir()):       # a temporary left behind too
            if p.is_file():
                shutil.copyfile(p, a.out / p.name)
        note(f"test time in the VM {time.monotonic() - T0:.2f} s, {failures} failed checks")
    return 1 if failures else 0


if __name__ == "__main__":
    status = main()
    sys.stdout.flush()
    os._exit(status)      # skips tearing numpy and scipy down: ~1 s under TCG
