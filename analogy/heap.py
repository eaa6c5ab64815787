"""The C heap's thresholds, raised so that freed memory is reused instead of mapped afresh."""

from __future__ import annotations

import ctypes
import threading

__all__ = ["retain_freed_memory", "RETAINED"]

#: Freed memory glibc keeps for reuse before it returns any to the system [bytes]; arrays up
#: to half of it come from the heap, not from a mapping of their own.
RETAINED = 64 << 20

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3     # malloc.h
_DONE: list = []
_LOCK = threading.Lock()


def retain_freed_memory() -> bool:
    """Keep up to :data:`RETAINED` bytes of freed memory for reuse (glibc's ``mallopt``); once per process.

    By default glibc maps an array past 128 kB afresh (raising that threshold only to the largest
    mapped block freed so far) and trims freed memory back to the system, so numpy's short-lived
    arrays of a batch group (a stack's states over SPICE's points, some 240 kB each, several alive
    at once) page-faulted on every use: a loop of such arrays faulted 8,700 pages where 145 remain
    with these thresholds, and ngspice running beside it took 12 to 15 ms for a batch circuit
    that takes 8 ms when the loop keeps its memory. Setting the threshold ends glibc's own
    adjustment of it, and each heap (one per thread that allocates) may keep up to
    :data:`RETAINED` for good. So the ``analogy`` command calls this in its own process and in its
    worker processes, and a program calling the package decides for itself.

    Returns
    -------
    bool
        Whether the thresholds are set (False where the C library is not glibc).
    """
    with _LOCK:
        if not _DONE:
            try:
                mallopt = ctypes.CDLL(None).mallopt
            except (OSError, AttributeError):       # not glibc: its own policy stays
                _DONE.append(False)
            else:
                mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
                _DONE.append(mallopt(_M_MMAP_THRESHOLD, RETAINED // 2) == 1 and
                             mallopt(_M_TRIM_THRESHOLD, RETAINED) == 1)
        return _DONE[0]
