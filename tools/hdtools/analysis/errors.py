"""The errors of hdtools.analysis, in a module of their own so that the
readers (logfile.py, candump.py) and the loader (loading.py) share them
without importing each other."""
from __future__ import annotations

from ..safeio import UsageError


class InputError(UsageError):
    """Bad input (exit status 2): the message says what is wrong and what is
    expected."""
