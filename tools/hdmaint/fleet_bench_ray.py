"""The same per-log task (engine.task) on Ray, for fleet_bench.py's Dask-vs-Ray
table only.  Ray is not a project dependency: run with a Python that has
it (and numpy, scipy, cantools, threadpoolctl), PYTHONPATH=tools:

    python -m hdmaint.fleet_bench_ray FLEET_DIR WORKERS   -> one JSON line"""
from __future__ import annotations

import json
import sys
import time


def main(root: str, workers: int) -> int:
    import ray
    from hdtools.fleet import catalog, engine
    logs = [r.path for r in catalog.discover([root]) if not r.problem]
    t0 = time.perf_counter()
    ray.init(num_cpus=workers, include_dashboard=False, logging_level="ERROR",
             log_to_driver=False)

    @ray.remote(num_cpus=1)
    def task(path):
        values, _, stats = engine.task(path, {"gear_ratio": 100.0, "loop": False})
        return values["duration_s"], stats["elapsed_s"]

    @ray.remote(num_cpus=1)
    def ready():
        from hdtools.analysis import cfilter   # noqa: F401 - import the C library once per worker
        return True

    ray.get([ready.remote() for _ in range(workers)])
    startup = time.perf_counter() - t0
    t1 = time.perf_counter()
    pending = [task.remote(p) for p in logs]
    dur, task_s = 0.0, 0.0
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        d, s = ray.get(done[0])
        dur, task_s = dur + d, task_s + s
    engine_s = time.perf_counter() - t1
    ray.shutdown()
    print(json.dumps({"version": ray.__version__, "logs": len(logs), "joint_hours": dur / 3600.0,
                      "engine_s": engine_s, "startup_s": startup, "task_s": task_s,
                      "wall_s": startup + engine_s}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], int(sys.argv[2])))
