"""Mutation fuzzing of the Python CSV readers (libFuzzer cannot reach them and
no Python fuzzing package is pinned): calibration CSV (hdtools.calibtool.csvio.
read_csv) and measured-log loader (hdtools.analysis.loading.load).

Seeds follow docs/how-to/calibration.md and the hdsim / hdjoint-host CSV columns.
Each seed is mutated (byte flips, insertions, deletions, splices, duplicated
lines, numbers replaced by extremes) with a fixed RNG seed, a few thousand
inputs per reader.  Property: a reader either returns, or raises its own
documented error (CalibError / InputError); never any other exception.
Any failing input is printed so it can become a fixed regression case.
"""

import numpy as np
import pytest

from hdtools.calibtool.csvio import read_csv
from hdtools.calibtool.lib import CalibError
from hdtools.analysis.loading import InputError, load

CALIB_SEED = (
    "experiment,direction,position_deg,torque_nm,bridge_v\n"
    "1,load,0,0,0.001\n1,load,0,10,1.516\n1,load,0,20,3.031\n1,unload,0,10,1.518\n"
    "2,load,90,0,-0.002\n2,load,90,10,1.512\n2,load,90,20,3.027\n"
)
LOG_SEED = "t_s,motor_angle_rad,torque_nm\n" + "".join(
    f"{k * 0.001:.3f},{k * 0.156:.4f},{3 + np.sin(2 * k * 0.156):.4f}\n" for k in range(300))
EXTREMES = [b"nan", b"inf", b"-inf", b"1e309", b"-0", b"", b"1e-320", b"9" * 400, b"0x10", b"\xff\xfe"]


def mutate(rng, data: bytes) -> bytes:
    b = bytearray(data)
    for _ in range(int(rng.integers(1, 6))):
        op = int(rng.integers(0, 7))
        pos = int(rng.integers(0, len(b) + 1))
        if op == 0 and b:
            b[min(pos, len(b) - 1)] ^= 1 << int(rng.integers(0, 8))
        elif op == 1:
            b[pos:pos] = bytes(rng.integers(0, 256, int(rng.integers(1, 8)), dtype=np.uint8))
        elif op == 2:
            del b[pos:pos + int(rng.integers(1, 16))]
        elif op == 3:
            b[pos:pos] = bytes(rng.choice(list(b",\n\r\"'# .-e")) for _ in range(3))
        elif op == 4:
            lines = bytes(b).split(b"\n")
            i = int(rng.integers(0, len(lines)))
            lines.insert(i, lines[i])
            b = bytearray(b"\n".join(lines))
        elif op == 5:
            fields = bytes(b).split(b",")
            i = int(rng.integers(0, len(fields)))
            fields[i] = EXTREMES[int(rng.integers(0, len(EXTREMES)))]
            b = bytearray(b",".join(fields))
        else:
            b = b[:pos]
    return bytes(b)


def report(failures):
    """One line per distinct exception type, with the shortest input."""
    if failures:
        lines = [f"{t}: {m} (e.g. {d[:120]!r})" for t, (m, d) in sorted(failures.items())]
        pytest.fail("undocumented exceptions:\n" + "\n".join(lines))


# Known, reported bugs: excluded from the mutation runs so that they catch
# anything new; each gets a strict-xfail regression test below until fixed.
# (Fixed: UnicodeDecodeError from analysis.loading on non-UTF-8 bytes.)
KNOWN: dict = {}


def remember(failures, exc, data, reader=""):
    key = type(exc).__name__
    if key in KNOWN.get(reader, ()):
        return
    if key not in failures or len(data) < len(failures[key][1]):
        failures[key] = (str(exc)[:160], data)


def test_calib_csv_reader_only_raises_calib_error():
    rng = np.random.default_rng(20240601)
    seed = CALIB_SEED.encode()
    failures = {}
    for i in range(4000):
        data = mutate(rng, seed)
        text = data.decode("utf-8", errors="replace")
        try:
            read_csv(text, counts_per_volt=None if i % 2 else 3276.8)
        except CalibError:
            pass
        except Exception as exc:
            remember(failures, exc, data)
    report(failures)


def test_log_loader_only_raises_input_error(tmp_path):
    rng = np.random.default_rng(20240602)
    seed = LOG_SEED.encode()
    path = tmp_path / "log.csv"
    failures = {}
    for _ in range(600):
        data = mutate(rng, seed)
        path.write_bytes(data)
        try:
            load(path, fs_hz=None)
        except InputError:
            pass
        except Exception as exc:
            remember(failures, exc, data, "load")
    report(failures)


# Regressions found by the mutation runs above (fixed inputs).
@pytest.mark.parametrize("data", [
    b"t_s,motor_angle_rad,torque_nm\n0.000,0.0,3.0\n0.001,0.1,\xd6\n",  # not UTF-8
])
def test_log_loader_regressions(tmp_path, data):
    path = tmp_path / "log.csv"
    path.write_bytes(data)
    try:
        load(path, fs_hz=None)
    except InputError:
        pass
