"""hdsense fleet against the simulated fleet's truth and against itself run
without the engine (docs/results/fleet.md, "Tests").

The fleet (seed 7) is not the one the thresholds were chosen on (seed 1):
held out.  The engine runs are compared with the direct run (the same task
called in this process) bit for bit: records.parquet's bytes.  A real
`dask scheduler` and two `dask worker` processes are started on 127.0.0.1;
one worker is killed mid-run."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from conftest import ROOT

from hdtools.fleet import engine, job, record, simfleet, trends  # noqa: E402

SEED = 7                # held out: the thresholds were looked at on seed 1
OPTIONS = {"gear_ratio": 100.0, "loop": False}
START_S = 60


@pytest.fixture(scope="module")
def fleet(hdsim, tmp_path_factory):
    root = tmp_path_factory.mktemp("fleet")
    truth = simfleet.generate(root, hdsim, n_joints=8, days=10, logs_per_day=1, log_s=60.0,
                              seed=SEED)
    (root / "j003" / "2026-01-20T08-00-00.csv").write_bytes(b"t_s,torque_nm\n\x00\x01garbage\n")
    return root, truth


def _run(fleet, store, **kw):
    return job.run([str(fleet[0])], store, OPTIONS, trends.load_thresholds(), quiet=True, **kw)


@pytest.fixture(scope="module")
def direct(fleet, tmp_path_factory):
    store = tmp_path_factory.mktemp("direct")
    return store, _run(fleet, store, direct=True)


def _bytes(store):
    return (Path(store) / "records.parquet").read_bytes()


def _start_day(utc):
    from datetime import datetime, timezone
    from hdtools.fleet import catalog
    t = datetime.strptime(utc, "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=timezone.utc)
    return (t - catalog.EPOCH).total_seconds() / 86400.0


EXPECTED_ALARM = {"meshing": "meshing 2x", "friction": ("viscous friction", "Coulomb friction"),
                  "gain": "gauge gain", "tooth": "new line motor 1x"}


def test_truth_wearing_flagged_healthy_not(fleet, direct):
    _, truth = fleet
    doc = json.loads((direct[0] / "report.json").read_text())
    wearing = {j["joint"] for j in truth["joints"] if j["wear"] != "none"}
    assert set(doc["flagged"]) == wearing
    rows = {j["joint"]: j for j in doc["joints"]}
    for tj in truth["joints"]:
        if tj["wear"] == "none":
            continue
        want = EXPECTED_ALARM[tj["wear"]]
        want = (want,) if isinstance(want, str) else want
        assert set(rows[tj["joint"]]["alarms"]) & set(want), (tj, rows[tj["joint"]]["alarms"])
        onset = _start_day(tj["onset_utc"])
        for a in rows[tj["joint"]]["alarms"]:
            # never before the wear began (a causal, per-day evaluation)
            assert rows[tj["joint"]]["indicators"][a]["first_flagged_day"] > onset
        if tj["wear"] == "tooth":
            ind = rows[tj["joint"]]["indicators"]["new line motor 1x"]
            assert ind["change_point"] and 0 < ind["change_point_day"] - onset <= 1.0


def test_corrupt_log_reported_rest_complete(fleet, direct):
    s = direct[1]
    assert [r["path"] for r in s["refused"]] == ["j003/2026-01-20T08-00-00.csv"]
    assert s["logs"] == 81 and s["analysed"] == 81
    doc = json.loads((direct[0] / "report.json").read_text())
    assert sum(j["records"] for j in doc["joints"]) == 80


def test_rerun_skips_up_to_date_and_redoes_a_changed_log(fleet, direct, tmp_path):
    store = tmp_path / "store"
    shutil.copytree(direct[0], store)
    assert _run(fleet, store, direct=True)["analysed"] == 0
    log = fleet[0] / "j000" / "2026-01-05T08-00-00.csv"
    saved = log.read_bytes()
    try:
        log.write_bytes(saved.replace(b"\n0.005000,", b"\n0.005001,", 1))
        s = _run(fleet, store, direct=True)
        assert s["analysed"] == 1 and s["skipped_up_to_date"] == 80
    finally:
        log.write_bytes(saved)
    assert _run(fleet, store, direct=True)["analysed"] == 0
    assert _bytes(store) == _bytes(direct[0])


def test_local_cluster_equals_direct_bit_for_bit(fleet, direct, tmp_path):
    s = _run(fleet, tmp_path, workers=2, memory="1GiB")
    assert s["analysed"] == 81
    assert _bytes(tmp_path) == _bytes(direct[0])


def _dask(*args):
    exe = Path(sys.executable).parent / "dask"
    return [str(exe), *args]


class Cluster:
    """`dask scheduler` and two `dask worker --no-nanny` on 127.0.0.1."""

    def __init__(self, tmp):
        env = dict(os.environ, PYTHONPATH=str(ROOT / "tools"))
        sfile = tmp / "scheduler.json"
        quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "env": env}
        self.procs = [subprocess.Popen(_dask("scheduler", "--host", "127.0.0.1", "--port", "0",
                                             "--no-dashboard", "--scheduler-file", str(sfile)),
                                       **quiet)]
        deadline = time.monotonic() + START_S
        while not sfile.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(0.2)
        self.address = json.loads(sfile.read_text())["address"]
        for _ in range(2):
            self.procs.append(subprocess.Popen(
                _dask("worker", self.address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                      "--host", "127.0.0.1", "--memory-limit", "1GiB"), **quiet))
        self.workers = self.procs[1:]

    def client(self):
        from distributed import Client
        c = Client(self.address, timeout=START_S, set_as_default=False)
        c.wait_for_workers(2, timeout=START_S)
        return c

    def stop(self):
        for p in reversed(self.procs):
            if p.poll() is None:
                p.terminate()
        for p in self.procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.fixture
def cluster(tmp_path):
    c = Cluster(tmp_path)
    yield c
    c.stop()


def test_real_scheduler_two_workers_equals_direct(fleet, direct, cluster, tmp_path):
    client = cluster.client()
    try:
        pids = set(client.run(os.getpid).values())
        s = _run(fleet, tmp_path / "store", client=client)
    finally:
        client.close()
    assert pids == {p.pid for p in cluster.workers}
    assert s["analysed"] == 81
    assert _bytes(tmp_path / "store") == _bytes(direct[0])


def test_worker_killed_mid_run_nothing_lost_or_duplicated(fleet, direct, cluster, tmp_path):
    client = cluster.client()
    store = tmp_path / "store"
    result, killed_at = {}, {}

    def work():
        result["s"] = _run(fleet, store, client=client)

    t = threading.Thread(target=work)
    t.start()
    records = store / "records"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        n = len(list(records.glob("*.parquet"))) if records.is_dir() else 0
        if n >= 8:
            os.kill(cluster.workers[1].pid, signal.SIGKILL)
            killed_at["records"] = n
            break
        time.sleep(0.005)
    t.join(timeout=180)
    client.close()
    assert not t.is_alive()
    assert 8 <= killed_at["records"] < 81, killed_at      # it was mid-run
    assert cluster.workers[1].wait(timeout=10) == -signal.SIGKILL
    s = result["s"]
    assert s["analysed"] == 81 and len(s["refused"]) == 1
    table = pq.read_table(store / "records.parquet")
    keys = table.column("key").to_pylist()
    assert len(keys) == len(set(keys)) == 81
    assert _bytes(store) == _bytes(direct[0])


def test_unreachable_scheduler_one_line_not_a_hang(fleet, tmp_path):
    import socket
    with socket.socket() as s:       # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.monotonic()
    p = subprocess.run([str(ROOT / "tools" / "hdsense"), "fleet", str(fleet[0]), "--store",
                        str(tmp_path / "st"), "--scheduler", f"tcp://127.0.0.1:{port}"],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == engine.EngineError.code
    assert len(p.stderr.strip().splitlines()) == 1 and "cannot connect" in p.stderr
    assert time.monotonic() - t0 < engine.CONNECT_TIMEOUT_S + 30


def test_long_log_in_chunks_each_at_its_place(hdsim, tmp_path):
    """A 5 min log cut into chunks of 1 MB: one record per chunk, each
    placed at the time of its first row (read here from the CSV at the
    chunk's byte offset), every sample in one chunk, and each chunk's
    meshing line that of the whole log's record (a healthy joint)."""
    from hdtools.fleet import chunks
    joint = next(j for j in simfleet.plan(8, 10, SEED, 300.0, 3.0) if j.wear == "none")
    ini = tmp_path / "long.ini"
    ini.write_text(simfleet.scenario_text(joint, 0.0, 300.0, 5))
    big = tmp_path / "long" / joint.joint / "2026-01-05T08-00-00.csv"
    big.parent.mkdir(parents=True)
    subprocess.run([str(hdsim), str(ini), "--csv", str(big)], check=True, capture_output=True)
    opts = dict(OPTIONS, chunk_bytes=1 << 20)
    s = job.run([str(tmp_path / "long")], tmp_path / "st", opts, trends.load_thresholds(),
                direct=True, quiet=True)
    rngs = chunks.ranges(str(big), 1 << 20)
    assert len(rngs) >= 3 and s["records"] == len(rngs) and not s["refused"]
    rows = pq.read_table(tmp_path / "st" / "records.parquet").to_pylist()
    assert [r["chunk"] for r in rows] == list(range(len(rngs)))
    data = big.read_bytes()
    for r, (a, _) in zip(rows, rngs):
        t_first = float(data[a:data.index(b"\n", a)].decode().split(",")[0])
        assert r["chunk_offset_s"] == pytest.approx(t_first, abs=1e-9)
        assert r["start_day"] == pytest.approx(rows[0]["start_day"] + t_first / 86400, abs=1e-9)
    whole = job.run([str(tmp_path / "long")], tmp_path / "st_whole", OPTIONS,
                    trends.load_thresholds(), direct=True, quiet=True)
    assert whole["records"] == 1
    w = pq.read_table(tmp_path / "st_whole" / "records.parquet").to_pylist()[0]
    assert sum(r["samples"] for r in rows) == w["samples"] == data.count(b"\n") - 1
    for r in rows:
        assert r["motor2_amp_nm"] == pytest.approx(w["motor2_amp_nm"], rel=0.05)


def test_long_candump_log_in_chunks_keeps_every_sample_once(tmp_path):
    """A 60 s candump -l log of the firmware (host runner on the simulated
    joint) cut into 4 chunks: every chunk starts at a TELEM_A line, gets
    the log's preamble (BOOT, parameter answers), and decodes to exactly the
    whole log's telemetry rows in order (python-can + cantools decode each
    part; the reference is the whole log's decode); each chunk sits at the
    host time of its first frame."""
    from hdtools import canproto, native
    from hdtools.fleet import chunks
    try:
        host = native.find_file("hdjoint-host", target="hdjoint-host")
    except (FileNotFoundError, subprocess.CalledProcessError):
        pytest.skip("hdjoint-host not built")
    log = tmp_path / "j005" / "2026-01-05T08-00-00.log"
    log.parent.mkdir()
    subprocess.run([str(host), "--sensors", f"sim:{ROOT / 'tests/tools/scenarios/motor6.ini'}",
                    "--duration", "60", "--can", f"log:{log}"], check=True, capture_output=True)
    size = log.stat().st_size
    rngs = chunks.ranges(str(log), size // 4 + 1)
    assert len(rngs) == 4
    data = log.read_bytes()
    assert all(chunks._is_telem_a(data[a:data.index(b"\n", a)]) for a, _ in rngs)
    whole_log = canproto.decode_log(log, None)
    whole = whole_log["telemetry"]
    assert len(whole_log["boots"]) == 1       # the runner answers no parameters
    parts, offsets = [], []
    for rng in rngs:
        with chunks.extracted(str(log), rng) as (tmp, where):
            part = canproto.decode_log(tmp, None)
            assert part["params"] == whole_log["params"] and len(part["boots"]) == 1
            parts += part["telemetry"]
            offsets.append(where["offset_s"])
    key = ("SeqA", "TorqueRaw", "TorqueFiltered", "MotorVelocity")
    assert [tuple(r[k] for k in key) for r in parts] == [tuple(r[k] for k in key) for r in whole]
    host_first = [float(data[a:data.index(b")", a)].strip(b"(")) for a, _ in rngs]
    assert offsets == pytest.approx([t - host_first[0] for t in host_first], abs=1e-9)
    recs = [record.analyze_log(str(log), gear_ratio=100.0, byte_range=r) for r in rngs]
    assert [r["chunk_offset_s"] for r in recs] == offsets


def test_docs_thresholds_table_is_current():
    from hdmaint import fleet_bench as bench
    text = (ROOT / "docs" / "results" / "fleet.md").read_text()
    assert bench.thresholds_table() in text


def test_client_killed_mid_run_loses_nothing_done(fleet, direct, tmp_path):
    """SIGKILL the `hdsense fleet` process itself mid-run: every record it
    wrote is whole and is not redone; the next run does exactly the rest."""
    store = tmp_path / "store"
    env = dict(os.environ, PYTHONPATH=str(ROOT / "tools"))
    p = subprocess.Popen([sys.executable, "-m", "hdtools.cli", "fleet", str(fleet[0]), "--store",
                          str(store), "--gear-ratio", "100", "--direct", "--quiet"], env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    records = store / "records"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and p.poll() is None:
        if records.is_dir() and len(list(records.glob("*.parquet"))) >= 10:
            p.send_signal(signal.SIGKILL)
            break
        time.sleep(0.005)
    assert p.wait(timeout=30) == -signal.SIGKILL
    done = len(list(records.glob("*.parquet")))
    assert 10 <= done < 81 and not (store / "records.parquet").exists()
    s = _run(fleet, store, direct=True)
    assert s["analysed"] == 81 - done and s["skipped_up_to_date"] == done
    assert not list(records.glob(".*"))
    assert _bytes(store) == _bytes(direct[0])


def test_loop_record_keeps_what_analyze_added_the_tooth_line(fleet):
    """--loop: the whole analyze loop on a log of the tooth joint after its
    onset adds a motor-order-1 block (the truth's new line), and its held-out
    innovation is below the reference model's."""
    from hdtools.fleet import record
    tooth = next(j for j in fleet[1]["joints"] if j["wear"] == "tooth")
    log = sorted((fleet[0] / tooth["joint"]).glob("*.csv"))[-1]
    rec = record.analyze_log(str(log), gear_ratio=100.0, loop=True)
    assert rec["loop_run"] and "motor order 1" in rec["loop_added"].split("; ")
    assert rec["loop_out_of_sample_innovation_after_nm"] < rec["out_of_sample_innovation_rms_nm"]


def test_report_flagged_joints_first_and_refusals_listed(fleet, direct):
    doc = json.loads((direct[0] / "report.json").read_text())
    flags = [j["flagged"] for j in doc["joints"]]
    assert flags == sorted(flags, reverse=True) and any(flags)
    html = (direct[0] / "report.html").read_text()
    rows = [html.index(f"<td>{j['joint']}</td>") for j in doc["joints"]]
    assert rows == sorted(rows)
    assert "j003/2026-01-20T08-00-00.csv" in html.split("Refused logs")[1]
    assert (direct[0] / "report.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
