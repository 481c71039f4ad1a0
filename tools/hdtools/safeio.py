"""Whole outputs or none, bounded inputs, and one-line errors for the CLIs.

Outputs are written under a temporary name in the target's directory and
renamed over the target only when every output of a command is complete
(`Outputs.commit`), so a failed or interrupted command never leaves a file
half old and half new, nor a new file next to an old one.  A target that
exists and is not a regular file (/dev/null, /dev/full, a FIFO) is written
directly.  Inputs must be regular files under a size limit.

Errors are exceptions carrying their exit status; hdtools.cli prints them as
one line (docs/results/reliability.md, "Exit status"):
  UsageError  2  bad command line or input
  OutputError 3  an output could not be written (old files untouched)
"""
from __future__ import annotations

import os
import shutil
import stat
import sys
import tempfile
from pathlib import Path

TEXT_MAX_BYTES = 64 << 20   # a calibration CSV or candump log far beyond any real one


class HdError(Exception):
    """An error with its exit status; the message is one line."""
    code = 1


class UsageError(HdError):
    code = 2


class OutputError(HdError):
    code = 3


def _why(exc: OSError) -> str:
    return exc.strerror or str(exc)


def read_bytes(path: str | os.PathLike, limit: int = TEXT_MAX_BYTES) -> bytes:
    """The bytes of a regular file of at most `limit` bytes (UsageError otherwise)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise UsageError(f"{path}: cannot read: {_why(exc)}") from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise UsageError(f"{path}: is a directory")
        if not stat.S_ISREG(st.st_mode):
            raise UsageError(f"{path}: not a regular file (FIFO, device or socket)")
        if st.st_size > limit:
            raise UsageError(f"{path}: {st.st_size} bytes, more than the limit of {limit}")
        os.set_blocking(fd, True)
        chunks, n = [], 0
        while n <= limit:
            chunk = os.read(fd, min(1 << 20, limit + 1 - n))
            if not chunk:
                break
            chunks.append(chunk)
            n += len(chunk)
        if n > limit:
            raise UsageError(f"{path}: more than the limit of {limit} bytes")
        return b"".join(chunks)
    except OSError as exc:
        raise UsageError(f"{path}: cannot read: {_why(exc)}") from None
    finally:
        os.close(fd)


def read_stdin_text(limit: int = TEXT_MAX_BYTES) -> str:
    """Standard input as text, as read_text reads a file: at most `limit`
    bytes (counted before decoding), a read error is a UsageError."""
    try:
        data = sys.stdin.buffer.read(limit + 1)
    except OSError as exc:
        raise UsageError(f"stdin: cannot read: {_why(exc)}") from None
    if len(data) > limit:
        raise UsageError(f"stdin: more than {limit} bytes")
    return decode_text(data, "stdin")


def decode_text(data: bytes, name: str) -> str:
    """UTF-8 text; a bad byte is reported with its line (UsageError)."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise UsageError(f"{name}:{line}: byte 0x{data[exc.start]:02X} is not UTF-8 text") from None


def read_text(path: str | os.PathLike, limit: int = TEXT_MAX_BYTES) -> str:
    return decode_text(read_bytes(path, limit), str(path))


class Outputs:
    """Stages several output files and publishes them together.

        with Outputs() as out:
            out.write_text("report.json", text)
            out.write_bytes("calib.bin", data)
            with out.path("plot.png") as tmp:   # a temporary path for a library
                fig.savefig(tmp, format="png")
            out.commit()        # all renamed, or OutputError and none
    Leaving the block without commit() removes every temporary file.
    """

    def __init__(self) -> None:
        self._staged: list[tuple[str, str | None]] = []   # (target, temporary or None)

    def __enter__(self) -> Outputs:
        return self

    def __exit__(self, *exc) -> None:
        self.discard()

    def _temp(self, target: str) -> tuple[int | None, str | None]:
        return _temp(target)

    def write_bytes(self, target: str | os.PathLike, data: bytes) -> None:
        target = os.fspath(target)
        fd, tmp = self._temp(target)
        try:
            if fd is None:
                with open(target, "wb") as f:
                    f.write(data)
            else:
                with os.fdopen(fd, "wb") as f:
                    f.write(data)
                    f.flush()
                    os.fsync(f.fileno())
        except OSError as exc:
            if tmp is not None:
                _unlink(tmp)
            raise OutputError(f"{target}: write failed: {_why(exc)}") from None
        self._staged.append((target, tmp))

    def write_text(self, target: str | os.PathLike, text: str) -> None:
        self.write_bytes(target, text.encode("utf-8"))

    def path(self, target: str | os.PathLike) -> _StagedPath:
        """A temporary path that a library writes to (matplotlib's savefig)."""
        return _StagedPath(self, os.fspath(target))

    def commit(self) -> None:
        staged, self._staged = self._staged, []
        try:
            for i, (target, tmp) in enumerate(staged):
                if tmp is not None:
                    os.replace(tmp, target)
                    staged[i] = (target, None)
        except OSError as exc:
            for _, tmp in staged:
                if tmp is not None:
                    _unlink(tmp)
            raise OutputError(f"{target}: cannot replace: {_why(exc)}") from None

    def discard(self) -> None:
        for _, tmp in self._staged:
            if tmp is not None:
                _unlink(tmp)
        self._staged = []


def _temp(target: str) -> tuple[int | None, str | None]:
    """(fd, temporary path) for a regular target, (None, None) to write in place."""
    try:
        st = os.stat(target)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise OutputError(f"{target}: cannot write: {_why(exc)}") from None
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise OutputError(f"{target}: cannot write: is a directory")
    if st is not None and not stat.S_ISREG(st.st_mode):
        return None, None
    directory, base = os.path.split(os.path.abspath(target))
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{base}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise OutputError(f"{target}: cannot write: {_why(exc)}") from None
    if st is not None:
        mode = st.st_mode & 0o7777
    else:
        mask = os.umask(0)
        os.umask(mask)
        mode = 0o666 & ~mask
    os.fchmod(fd, mode)
    return fd, tmp


class StreamOutput:
    """One output written a piece at a time (the monitor's candump log): a
    temporary file next to the target, as Outputs stages one (a non-regular
    target such as /dev/null is written directly).  write() sends whole
    pieces to the file; commit() syncs it and renames it over the target;
    discard() removes it.  Failures are OutputError, the temporary removed."""

    def __init__(self, target: str | os.PathLike, encoding: str = "utf-8") -> None:
        self.target = os.fspath(target)
        fd, self.tmp = _temp(self.target)
        try:
            if fd is None:
                self.file = open(self.target, "w", encoding=encoding, newline="\n")
            else:
                self.file = os.fdopen(fd, "w", encoding=encoding, newline="\n")
        except OSError as exc:
            if self.tmp is not None:
                _unlink(self.tmp)
            raise OutputError(f"{self.target}: cannot write: {_why(exc)}") from None

    def write(self, text: str) -> None:
        try:
            self.file.write(text)
            self.file.flush()
        except OSError as exc:
            self.discard()
            raise OutputError(f"{self.target}: write failed: {_why(exc)}") from None

    def commit(self) -> None:
        try:
            self.file.flush()
            if self.tmp is not None:
                os.fsync(self.file.fileno())
            self.file.close()
            if self.tmp is not None:
                os.replace(self.tmp, self.target)
                self.tmp = None
        except OSError as exc:
            self.discard()
            raise OutputError(f"{self.target}: cannot write: {_why(exc)}") from None

    def discard(self) -> None:
        try:
            self.file.close()
        except OSError:
            pass
        if self.tmp is not None:
            _unlink(self.tmp)
            self.tmp = None


class StagedDir:
    """A temporary folder next to the target for outputs a library writes as
    a folder (rosbags' Writer: a rosbag2 folder, or one .mcap inside it);
    publish() renames a path of it over the target, discard() removes it.
    in_system_temp: the target is written in place at the end (/dev/null,
    a FIFO), so the folder goes to the system's temporary directory."""

    def __init__(self, target: str | os.PathLike, in_system_temp: bool = False) -> None:
        self.target = os.fspath(target)
        directory, base = os.path.split(os.path.abspath(self.target))
        try:
            self.path = tempfile.mkdtemp(prefix=f".{base}.", suffix=".tmp",
                                         dir=None if in_system_temp else directory)
        except OSError as exc:
            raise OutputError(f"{self.target}: cannot write: {_why(exc)}") from None

    def publish(self, inside: str) -> None:
        try:
            os.replace(inside, self.target)
        except OSError as exc:
            self.discard()
            raise OutputError(f"{self.target}: write failed: {_why(exc)}") from None
        self.discard()

    def discard(self) -> None:
        shutil.rmtree(self.path, ignore_errors=True)


class _StagedPath:
    def __init__(self, outputs: Outputs, target: str) -> None:
        self.outputs, self.target = outputs, target

    def __enter__(self) -> str:
        fd, self.tmp = self.outputs._temp(self.target)
        if fd is not None:
            os.close(fd)
        return self.tmp if self.tmp is not None else self.target

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            if self.tmp is not None:
                try:
                    with open(self.tmp, "rb+") as f:
                        os.fsync(f.fileno())
                except OSError as err:
                    _unlink(self.tmp)
                    raise OutputError(f"{self.target}: write failed: {_why(err)}") from None
            self.outputs._staged.append((self.target, self.tmp))
            return False
        if self.tmp is not None:
            _unlink(self.tmp)
        if isinstance(exc, OSError):
            raise OutputError(f"{self.target}: write failed: {_why(exc)}") from None
        return False


def _unlink(path: str) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass
