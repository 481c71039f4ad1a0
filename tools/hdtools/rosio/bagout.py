"""A recording as a bare .mcap file or a rosbag2 folder (metadata.yaml +
one .mcap, storage "mcap", version 9: what `ros2 bag play` takes since
Iron), written by rosbags under a temporary name next to the target and
renamed only when closed: an interrupted or failed recording leaves no
half-written file and an old target as it was (safeio's rule).

The device's VERSION/INFO answers and parameters go into rosbag2's
custom_data (metadata.yaml), which the storage also writes as the MCAP
file's "rosbag2" metadata record, so a bare .mcap carries them too."""
from __future__ import annotations

import os
import shutil

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from rosbags.rosbag2.errors import WriterError

from ..safeio import OutputError, StagedDir
from . import messages

KINDS = ("mcap", "rosbag2")


class BagOutput:
    """write(topic, msgtype, cdr, stamp_ns) ... close() -> the target exists."""

    def __init__(self, target: str, kind: str, metadata: dict[str, str] | None = None):
        if kind not in KINDS:
            raise ValueError(kind)
        self.target, self.kind = target, kind
        self.metadata = dict(metadata or {})
        self.count = 0
        if kind == "rosbag2" and os.path.lexists(target):
            raise OutputError(f"{target}: exists (a rosbag2 folder is never written over)")
        if kind == "mcap" and os.path.isdir(target):
            raise OutputError(f"{target}: cannot write: is a directory")
        base = os.path.basename(os.path.abspath(target))
        # a target that exists and is not a regular file (/dev/null, a FIFO)
        # is written in place at the end, from a folder in the system's temp
        self.in_place = kind == "mcap" and os.path.exists(target) and not os.path.isfile(target)
        self.staged = StagedDir(target, in_system_temp=self.in_place)
        self.tmp = self.staged.path
        name = base[:-5] if kind == "mcap" and base.endswith(".mcap") else base
        self.bag = os.path.join(self.tmp, name or "bag")
        self.writer = Writer(self.bag, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        self.connections: dict[str, object] = {}
        self._guard(self.writer.open)

    def _guard(self, fn, *args):
        try:
            return fn(*args)
        except (OSError, WriterError) as exc:
            why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            self.abort()
            raise OutputError(f"{self.target}: write failed: {why}") from None

    def write(self, topic: str, msgtype: str, data: bytes, stamp_ns: int) -> None:
        conn = self.connections.get(topic)
        if conn is None:
            conn = self.connections[topic] = self._guard(
                lambda: self.writer.add_connection(topic, msgtype,
                                                   typestore=messages.TYPESTORE))
        self._guard(self.writer.write, conn, int(stamp_ns), data)
        self.count += 1

    def close(self) -> None:
        self.finish()
        self.commit()

    def finish(self) -> None:
        """Completes the files under the temporary name (commit renames)."""
        for key, value in self.metadata.items():
            self.writer.set_custom_data(key, str(value))
        self._guard(self.writer.close)
        self._guard(self._sync)

    def _sync(self) -> None:
        """On disk before the rename (a power cut then leaves the old target
        or the whole new one)."""
        for name in os.listdir(self.bag):
            fd = os.open(os.path.join(self.bag, name), os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)

    def commit(self) -> None:
        mcap = os.path.join(self.bag, os.path.basename(self.bag) + ".mcap")
        if not self.in_place:
            self.staged.publish(self.bag if self.kind == "rosbag2" else mcap)
            return
        try:
            with open(mcap, "rb") as src, open(self.target, "wb") as dst:
                shutil.copyfileobj(src, dst)
        except OSError as exc:
            self.abort()
            raise OutputError(f"{self.target}: write failed: {exc.strerror}") from None
        self.staged.discard()

    def abort(self) -> None:
        writer, self.writer = getattr(self, "writer", None), None
        if writer is not None and writer.storage is not None:
            try:
                writer.abort()
            except Exception:  # noqa: BLE001 - already failing: the files are removed below
                pass
        staged = getattr(self, "staged", None)
        if staged is not None:
            staged.discard()
