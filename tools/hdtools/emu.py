"""The joint emulator for tests: the real firmware on the mock HAL, fed by
the simulated joint (firmware/host/hd_emu.c, libhd_emu.so through ctypes),
optionally attached to a python-can bus in a thread.

    with Emulator(scenario="duration_s = 60") as joint:
        joint.tick(1000)                       # one second of device time
        frames = joint.pop_all()               # can.Message, device time stamps
    bus = can.Bus(interface="virtual", channel="t1")
    with Emulator() as joint, joint.attach("virtual", "t1"):
        ...                                    # the joint answers on channel t1
    with Emulator(dynamic=True) as joint:      # a drive and the dynamic joint:
        joint.set_environment(stiffness_nm_rad=200.0)   # the control loop closes
        joint.tick(); joint.truth().output_torque_nm

Attached, the emulator runs its ticks at real time (or `speed` times that),
sends what the firmware transmits onto the bus and hands the firmware every
frame it receives from the bus (the firmware counts the foreign ones).  It
is a test instrument: the tools under test talk to it only over the bus.
"""
from __future__ import annotations

import ctypes
import threading
import time

import can

from . import native

HAL_CAN_FLAG_EXT = 0x01
HAL_CAN_FLAG_FD = 0x02
HAL_CAN_FLAG_ERR = 0x04
HAL_CAN_FLAG_RTR = 0x08
HAL_RESET_POWER_ON = 0x01
HAL_RESET_SOFTWARE = 0x04
TICK_US = 1000


class Truth(ctypes.Structure):
    """hd_emu_truth_t: the dynamic joint's state at the end of the last tick."""
    _fields_ = [(n, ctypes.c_double) for n in (
        "t_s", "output_torque_nm", "motor_torque_nm", "person_torque_nm", "output_angle_rad",
        "output_velocity_rad_s", "drive_current_a")]


class Frame(ctypes.Structure):
    _fields_ = [("t_us", ctypes.c_uint64), ("id", ctypes.c_uint32), ("flags", ctypes.c_uint8),
                ("len", ctypes.c_uint8), ("data", ctypes.c_uint8 * 8)]


_LIB = None


def _lib():
    global _LIB
    if _LIB is None:
        lib = native.load_library("hd_emu")
        P = ctypes.c_void_p
        lib.hd_emu_create.restype = P
        lib.hd_emu_create.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p,
                                      ctypes.c_size_t]
        lib.hd_emu_destroy.argtypes = [P]
        lib.hd_emu_create_dynamic.restype = P
        lib.hd_emu_create_dynamic.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_size_t]
        lib.hd_emu_set_environment.restype = ctypes.c_int
        lib.hd_emu_set_environment.argtypes = [P, ctypes.c_double, ctypes.c_double,
                                               ctypes.c_double]
        lib.hd_emu_truth.restype = ctypes.c_int
        lib.hd_emu_truth.argtypes = [P, ctypes.POINTER(Truth)]
        lib.hd_emu_tick.restype = ctypes.c_uint32
        lib.hd_emu_tick.argtypes = [P, ctypes.c_uint32]
        lib.hd_emu_push_rx.restype = ctypes.c_int
        lib.hd_emu_push_rx.argtypes = [P, ctypes.POINTER(Frame)]
        lib.hd_emu_pop_tx.restype = ctypes.c_int
        lib.hd_emu_pop_tx.argtypes = [P, ctypes.POINTER(Frame)]
        lib.hd_emu_tx_lost.restype = ctypes.c_uint64
        lib.hd_emu_tx_lost.argtypes = [P]
        lib.hd_emu_power_cycle.restype = ctypes.c_int
        lib.hd_emu_power_cycle.argtypes = [P, ctypes.c_uint32]
        lib.hd_emu_nvm.restype = ctypes.POINTER(ctypes.c_uint8)
        lib.hd_emu_nvm.argtypes = [P, ctypes.POINTER(ctypes.c_size_t)]
        lib.hd_emu_ticks.restype = ctypes.c_uint64
        lib.hd_emu_ticks.argtypes = [P]
        lib.hd_emu_boots.restype = ctypes.c_uint32
        lib.hd_emu_boots.argtypes = [P]
        lib.hd_emu_ended.restype = ctypes.c_int
        lib.hd_emu_ended.argtypes = [P]
        _LIB = lib
    return _LIB


def to_message(f: Frame) -> can.Message:
    return can.Message(timestamp=f.t_us * 1e-6, arbitration_id=f.id,
                       is_extended_id=bool(f.flags & HAL_CAN_FLAG_EXT),
                       is_remote_frame=bool(f.flags & HAL_CAN_FLAG_RTR),
                       is_error_frame=bool(f.flags & HAL_CAN_FLAG_ERR),
                       dlc=f.len, data=bytes(f.data[:f.len]))


def from_message(msg: can.Message) -> Frame | None:
    """The HAL frame of a bus message; None for what a classic CAN
    controller never hands over (FD frames, more than 8 bytes)."""
    if msg.is_fd or len(msg.data) > 8:
        return None
    f = Frame()
    f.id = msg.arbitration_id
    f.flags = ((HAL_CAN_FLAG_EXT if msg.is_extended_id else 0) |
               (HAL_CAN_FLAG_RTR if msg.is_remote_frame else 0) |
               (HAL_CAN_FLAG_ERR if msg.is_error_frame else 0))
    f.len = len(msg.data) if not msg.is_remote_frame else 0
    for i, b in enumerate(bytes(msg.data)[:f.len]):
        f.data[i] = b
    return f


class Emulator:
    """One emulated joint (see the module doc)."""

    def __init__(self, scenario: str | None = "duration_s = 3600", config: str | None = None,
                 dynamic: bool = False):
        """dynamic: the dynamic joint with a drive (hd_emu_create_dynamic;
        the scenario is not used)."""
        err = ctypes.create_string_buffer(600)
        self._lib = _lib()
        cfg = config.encode() if config is not None else None
        if dynamic:
            self._h = self._lib.hd_emu_create_dynamic(cfg, err, len(err))
        else:
            self._h = self._lib.hd_emu_create(scenario.encode() if scenario is not None else None,
                                              cfg, err, len(err))
        if not self._h:
            raise ValueError(err.value.decode(errors="replace"))
        self._lock = threading.Lock()

    def close(self) -> None:
        if self._h:
            self._lib.hd_emu_destroy(self._h)
            self._h = None

    def __enter__(self) -> Emulator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------- direct control
    def tick(self, n: int = 1) -> int:
        with self._lock:
            return int(self._lib.hd_emu_tick(self._h, n))

    def push(self, msg: can.Message) -> bool:
        f = from_message(msg)
        if f is None:
            return False
        with self._lock:
            return self._lib.hd_emu_push_rx(self._h, ctypes.byref(f)) == 0

    def pop_all(self) -> list[can.Message]:
        out, f = [], Frame()
        with self._lock:
            while self._lib.hd_emu_pop_tx(self._h, ctypes.byref(f)):
                out.append(to_message(f))
        return out

    def power_cycle(self, reset_cause: int = HAL_RESET_POWER_ON) -> None:
        with self._lock:
            if self._lib.hd_emu_power_cycle(self._h, reset_cause) != 0:
                raise RuntimeError("the firmware did not start")

    def nvm(self) -> ctypes.Array:
        """The NVM bytes, writable in place (tests corrupt records here)."""
        size = ctypes.c_size_t()
        ptr = self._lib.hd_emu_nvm(self._h, ctypes.byref(size))
        return (ctypes.c_uint8 * size.value).from_address(ctypes.addressof(ptr.contents))

    def set_environment(self, stiffness_nm_rad: float = 0.0, damping_nm_s_rad: float = 0.0,
                        person_torque_nm: float = 0.0) -> None:
        """What the dynamic joint's output meets from the next tick on."""
        with self._lock:
            rc = self._lib.hd_emu_set_environment(self._h, stiffness_nm_rad, damping_nm_s_rad,
                                                  person_torque_nm)
        if rc != 0:
            raise ValueError("set_environment: not a dynamic joint, or a bad value")

    def truth(self) -> Truth:
        t = Truth()
        with self._lock:
            if self._lib.hd_emu_truth(self._h, ctypes.byref(t)) != 0:
                raise ValueError("truth: not a dynamic joint")
        return t

    @property
    def ticks(self) -> int:
        return int(self._lib.hd_emu_ticks(self._h))

    @property
    def boots(self) -> int:
        return int(self._lib.hd_emu_boots(self._h))

    @property
    def tx_lost(self) -> int:
        return int(self._lib.hd_emu_tx_lost(self._h))

    @property
    def ended(self) -> bool:
        return bool(self._lib.hd_emu_ended(self._h))

    def run_frames(self, ticks: int, chunk: int = 100) -> list[can.Message]:
        """Runs `ticks` ticks and returns every frame sent (device time)."""
        out = []
        left = ticks
        while left > 0:
            n = self.tick(min(chunk, left))
            out += self.pop_all()
            if n == 0:
                break
            left -= n
        return out

    # ----------------------------------------------------------- on a bus
    def attach(self, interface: str = "virtual", channel: str = "hdjoint-emu",
               speed: float = 1.0, on_chunk=None, **bus_kwargs) -> _Attached:
        """Runs the joint on a python-can bus in a thread until the returned
        context ends (`with joint.attach(...):`).  on_chunk(emulator), if
        given, is called in that thread after every few ticks (a test
        recording the truth)."""
        return _Attached(self, interface, channel, speed, bus_kwargs, on_chunk)


class _Attached:
    CHUNK_TICKS = 2

    def __init__(self, emu: Emulator, interface, channel, speed, bus_kwargs, on_chunk=None):
        self.emu, self.speed, self.on_chunk = emu, speed, on_chunk
        self.bus = can.Bus(interface=interface, channel=channel, **bus_kwargs)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="hd-emu", daemon=True)
        self.error: BaseException | None = None
        self.received = 0

    def __enter__(self) -> _Attached:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self.bus.shutdown()

    def _run(self) -> None:
        try:
            start = time.monotonic()
            done = 0
            while not self._stop.is_set():
                while True:
                    msg = self.bus.recv(timeout=0)
                    if msg is None:
                        break
                    self.received += 1
                    self.emu.push(msg)
                due = int((time.monotonic() - start) * 1000.0 * self.speed)
                if due - done > 200:            # fell far behind (a loaded machine):
                    start += (due - done - 200) / (1000.0 * self.speed)   # slip, never burst
                    due = done + 200
                n = min(self.CHUNK_TICKS, due - done)
                if n <= 0:
                    time.sleep(0.0005)
                    continue
                ran = self.emu.tick(n)
                done += n
                if self.on_chunk is not None:
                    self.on_chunk(self.emu)
                for m in self.emu.pop_all():
                    self.bus.send(m)
                if ran < n:                     # the scenario ended
                    break
        except BaseException as exc:  # noqa: BLE001 - reported to the test
            self.error = exc
