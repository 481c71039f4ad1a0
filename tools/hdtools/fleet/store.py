"""The columnar store: one Parquet file per log record, written through a
temporary name and renamed (hdtools.safeio), so a crash or a full disk
mid-run loses nothing already done and leaves no half-written record; and
the consolidated table STORE/records.parquet (sorted by joint, start,
path), rewritten whole at the end of a run.

    STORE/records/<key>.parquet   one row, key = catalog.content_key
    STORE/records.parquet         every record of this run's logs

A store is used by one run at a time: a run removes the temporary files
a killed run left in records/."""
from __future__ import annotations

import os
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from ..safeio import OutputError, Outputs
from . import record

TYPES = {"string": pa.string(), "float64": pa.float64(), "int64": pa.int64(), "bool": pa.bool_()}
SCHEMA = pa.schema([(name, TYPES[t]) for name, t in record.COLUMNS])
TABLE_NAME = "records.parquet"


def _write_table(table: pa.Table, target: Path) -> None:
    with Outputs() as out:
        try:
            with out.path(target) as tmp:
                pq.write_table(table, tmp, compression="zstd")
        except OSError as exc:     # pyarrow's own error for a failed write
            raise OutputError(f"{target}: write failed: {exc}") from None
        out.commit()


class Store:
    def __init__(self, root):
        self.root = Path(root)
        self.records = self.root / "records"
        if self.root.exists() and not self.root.is_dir():
            raise OutputError(f"--store {self.root}: exists and is not a directory")
        try:
            self.records.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"--store {self.root}: cannot create: {exc.strerror}") from None
        if not os.access(self.records, os.W_OK | os.X_OK):
            raise OutputError(f"--store {self.root}: not writable")
        for stale in self.records.glob(".*.tmp"):   # a run killed mid-write left it
            try:
                stale.unlink()
            except OSError:
                pass

    def _path(self, key: str) -> Path:
        return self.records / f"{key}.parquet"

    def has(self, key: str) -> bool:
        return self._path(key).is_file()

    def put(self, row: dict) -> None:
        _write_table(pa.Table.from_pylist([row], schema=SCHEMA), self._path(row["key"]))

    def get(self, key: str) -> dict:
        try:
            return pq.read_table(self._path(key), schema=SCHEMA).to_pylist()[0]
        except (OSError, pa.ArrowException, IndexError) as exc:
            raise OutputError(f"{self._path(key)}: unreadable record ({exc}); delete it "
                              "to redo that log") from None

    def table(self, keys) -> pa.Table:
        """The records of these keys, sorted by joint, start, path."""
        rows = [self.get(k) for k in sorted(set(keys))]
        rows.sort(key=lambda r: (r["joint"] or "", r["start_utc"] or "", r["path"]))
        return pa.Table.from_pylist(rows, schema=SCHEMA)

    def write_table(self, table: pa.Table) -> Path:
        target = self.root / TABLE_NAME
        _write_table(table, target)
        return target
