"""`hdsense fleet`: per-log records of many joints' logs on Dask, in a
Parquet store, then trends and alarms per joint (docs/results/fleet.md).

Exit status (hdtools.cli): 0 every log has a record (refused logs are
reported in the summary and the report, the rest completes); 1 the engine
could not run (unreachable scheduler); 2 bad command line or input (no
logs, a bad thresholds file); 3 an output could not be written."""
from __future__ import annotations

import math
import re
import sys

from .safeio import UsageError

MEMORY_RE = re.compile(r"^\d+(\.\d+)?\s*(B|kB|KiB|MB|MiB|GB|GiB|TB|TiB)$")


def register(sub):
    p = sub.add_parser("fleet", help="gear-health trends over many joints' logs (Dask)",
                       description=__doc__)
    p.add_argument("inputs", nargs="+", metavar="DIR|GLOB",
                   help="directories (walked) or globs of logs: <joint>/<YYYY-MM-DDTHH-MM-SS>.csv "
                        "or a LOG.json sidecar")
    p.add_argument("--store", required=True, metavar="DIR",
                   help="records (Parquet), records.parquet and report.{json,html,png} go here")
    p.add_argument("--workers", type=int, default=2, help="LocalCluster workers (default 2)")
    p.add_argument("--memory-per-worker", default="2GiB", help="LocalCluster memory limit per "
                   "worker (default 2GiB)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run on this existing Dask cluster instead of a LocalCluster")
    p.add_argument("--direct", action="store_true",
                   help="no engine: the same tasks in this process (baseline, debugging)")
    p.add_argument("--gear-ratio", type=float, help="the fleet's gear ratio: a log that shows "
                   "another (2 %% off) is refused")
    p.add_argument("--chunk-mb", type=float, default=64.0,
                   help="a CSV log larger than this is cut into chunks of at most this many "
                        "MB, one task and one record each (default 64)")
    p.add_argument("--loop", action="store_true",
                   help="also run the whole analyze loop per log (slow) and keep what it added")
    p.add_argument("--thresholds", metavar="FILE.json", help="alarm thresholds over the defaults")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=main)


def _check(args):
    if args.workers < 1 or args.workers > 512:
        raise UsageError(f"--workers must be 1..512 (got {args.workers})")
    if not MEMORY_RE.match(args.memory_per_worker.strip()):
        raise UsageError(f"--memory-per-worker: expected a size such as 2GiB or 800MB "
                         f"(got {args.memory_per_worker!r})")
    if args.gear_ratio is not None and not (math.isfinite(args.gear_ratio)
                                            and args.gear_ratio >= 1):
        raise UsageError("--gear-ratio must be a finite number >= 1")
    if args.scheduler is not None and not re.match(r"^(tcp|tls|inproc|ws|wss)://\S+$",
                                                   args.scheduler):
        raise UsageError(f"--scheduler: expected tcp://HOST:PORT (got {args.scheduler!r})")
    if not (math.isfinite(args.chunk_mb) and 0.01 <= args.chunk_mb <= 1e6):
        raise UsageError(f"--chunk-mb must be 0.01..1e6 (got {args.chunk_mb:g})")
    if args.scheduler and args.direct:
        raise UsageError("--scheduler and --direct exclude each other")


def main(args) -> int:
    _check(args)
    from .fleet import job, trends
    th = trends.load_thresholds(args.thresholds)
    options = {"gear_ratio": args.gear_ratio, "loop": bool(args.loop),
               "chunk_bytes": int(args.chunk_mb * (1 << 20))}
    summary = job.run(args.inputs, args.store, options, th, workers=args.workers,
                      memory=args.memory_per_worker.strip(), scheduler=args.scheduler,
                      direct=args.direct, quiet=args.quiet)
    print(job.summary_line(summary))
    for r in summary["refused"]:
        print(f"refused: {r['path']}: {r['message']}")
    sys.stdout.flush()
    return 0
