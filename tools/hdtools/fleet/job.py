"""One fleet run: find the logs, skip those whose record is up to date, run
the rest on the engine (each record stored as it arrives), then the
consolidated table, the trends and the report."""
from __future__ import annotations

import math
import time
from pathlib import Path

from . import catalog, chunks, engine, record, report, store as st, trends


def _row(ref, chunk, key, values, problem):
    row = {name: None for name, _ in st.record.COLUMNS}
    row.update(key=key, path=ref.rel, chunk=chunk, joint=ref.joint, start_utc=ref.start_utc,
               start_day=ref.start_day, status="ok" if problem is None else "refused",
               message=problem)
    if values:
        row.update(values)
        if chunk and math.isfinite(values["chunk_offset_s"]):
            row["start_day"] = ref.start_day + values["chunk_offset_s"] / 86400.0
    for name, typ in st.record.COLUMNS:     # NaN and None are one "missing" in Parquet
        if typ == "float64" and isinstance(row[name], float) and math.isnan(row[name]):
            row[name] = None
    return row


def run(inputs, store_dir, options, th, workers=2, memory="2GiB", scheduler=None,
        direct=False, quiet=False, client=None):
    """Returns the summary (also in report.json's "run").  `client`: an
    existing dask.distributed Client to use (tests, benchmarks)."""
    t0 = time.perf_counter()
    # the defaults filled in: the content key must not depend on who called
    options = {"gear_ratio": None, "loop": False, "chunk_bytes": chunks.CHUNK_BYTES, **options}
    refs = catalog.discover(inputs)
    store = st.Store(store_dir)
    keys, jobs, by_key, unknown = [], [], {}, 0
    for ref in refs:
        base = catalog.content_key(ref, options)
        parts = None if ref.problem else chunks.parts(ref, options["chunk_bytes"])
        for i, part in enumerate(parts or [None]):
            key = base if parts is None or len(parts) == 1 else f"{base}-{i}"
            keys.append(key)
            by_key[key] = (ref, i)
            if store.has(key):
                continue
            if ref.problem:
                store.put(_row(ref, 0, key, None, ref.problem))
                unknown += 1
            else:
                jobs.append((key, ref.path, part))
    stats = []

    def on_result(key, values, problem, s):
        store.put(_row(*by_key[key], key, values, problem))
        if s:
            stats.append(s)

    t_engine = time.perf_counter()
    if jobs and direct:
        engine.run_direct(jobs, options, on_result, quiet)
    elif jobs:
        own, given = client is None, client
        try:
            with engine.deferred_sigint():
                client = given or engine.connect(scheduler, workers, memory)
            engine.run(client, jobs, options, on_result, quiet)
        finally:
            if own and client is not None:
                with engine.deferred_sigint():
                    engine.close(client)
    t_done = time.perf_counter()
    table = store.table(keys)
    store.write_table(table)
    rows = table.to_pylist()
    ok = [r for r in rows if r["status"] == "ok"]
    per_path = {}
    for r in rows:
        per_path[r["path"]] = per_path.get(r["path"], 0) + 1
    refused = [{"path": r["path"] + (f" chunk {r['chunk']}" if per_path[r["path"]] > 1 else ""),
                "message": r["message"]} for r in rows if r["status"] != "ok"]
    if options["gear_ratio"] is None:
        ok, odd = gear_outliers(ok)
        refused += [{"path": r["path"] + (f" chunk {r['chunk']}" if per_path[r["path"]] > 1 else ""),
                     "message": why} for r, why in odd]
    joint_rows = trends.joints(ok, th)
    done = len(jobs) + unknown
    summary = {"logs": len({r["path"] for r in rows}), "records": len(rows), "analysed": done, "skipped_up_to_date": len(rows) - done,
               "refused": refused, "joints": len(joint_rows),
               "flagged": [j["joint"] for j in joint_rows if j["flagged"]],
               "joint_hours": sum(r["duration_s"] for r in ok) / 3600.0,
               "engine": "direct" if direct else (scheduler or f"LocalCluster x{workers}"),
               "engine_s": t_done - t_engine, "total_s": time.perf_counter() - t0,
               "task_s": sum(s["elapsed_s"] for s in stats),
               "max_rss_mb_per_worker": _rss_by_worker(stats)}
    doc = report.document(joint_rows, refused, {k: v for k, v in summary.items()
                                                if k not in ("refused", "flagged")}, th)
    report.write(Path(store_dir), doc)
    return summary


def gear_outliers(ok):
    """Without --gear-ratio each log's ratio is its own (inferred); a log
    whose ratio is not that of most of its joint's logs is another joint
    type (a mislabelled log): (rows kept, [(row, why)] left out of the
    trends).  A joint whose logs have no majority ratio is left out whole."""
    tol = record.GEAR_TOLERANCE
    by_joint: dict[str, list] = {}
    for r in ok:
        by_joint.setdefault(r["joint"], []).append(r)
    kept, odd = [], []
    for rows in by_joint.values():
        def near(a, b):
            return abs(a["gear_ratio"] - b["gear_ratio"]) <= tol * b["gear_ratio"]
        best = max(rows, key=lambda r: sum(near(o, r) for o in rows))
        if 2 * sum(near(o, best) for o in rows) > len(rows):
            for r in rows:
                if near(r, best):
                    kept.append(r)
                else:
                    odd.append((r, f"gear ratio {r['gear_ratio']:.4g} ({r['gear_source']}), most "
                                   f"of joint {r['joint']}'s logs {best['gear_ratio']:.4g}: another "
                                   "joint type, left out of its trends"))
        else:
            seen = ", ".join(sorted({f"{r['gear_ratio']:.4g}" for r in rows}))
            odd += [(r, f"joint {r['joint']}'s logs disagree on the gear ratio ({seen}): give "
                        "--gear-ratio") for r in rows]
    order = {id(r): i for i, r in enumerate(ok)}
    return sorted(kept, key=lambda r: order[id(r)]), odd


def _rss_by_worker(stats):
    by = {}
    for s in stats:
        by[s["pid"]] = max(by.get(s["pid"], 0.0), s["max_rss_mb"])
    return sorted(by.values(), reverse=True)


def summary_line(s) -> str:
    chunks_note = f" in {s['records']} records" if s["records"] != s["logs"] else ""
    return (f"{s['logs']} logs{chunks_note} ({s['analysed']} analysed, {s['skipped_up_to_date']} up to date, "
            f"{len(s['refused'])} refused), {s['joints']} joints, {s['joint_hours']:.3g} "
            f"joint-hours; flagged: {', '.join(s['flagged']) or 'none'}")
