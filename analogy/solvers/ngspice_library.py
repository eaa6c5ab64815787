"""ngspice's C API in process: a library loaded and initialised with callbacks of our own, read through ctypes."""

from __future__ import annotations

import ctypes.util
import locale
import os
import threading
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import SpiceError

if TYPE_CHECKING:
    import cffi

__all__ = ["Library", "declared_ffi", "library_path", "short_calls", "strings", "VectorInfo", "mapped_file"]

_CDEF_DONE = False


def library_path() -> str:
    """The ngspice shared library to load: $NGSPICE_LIBRARY_PATH or the system's libngspice."""
    path = os.environ.get("NGSPICE_LIBRARY_PATH") or ctypes.util.find_library("ngspice")
    if not path:
        raise SpiceError("the ngspice shared library was not found: install the Debian package "
                         "libngspice0 (bash setup.sh does) or set NGSPICE_LIBRARY_PATH")
    return path


#: The C types a run names in cffi calls (the netlist's lines, the vectors read back): cffi parses each
#: on first use, 15 ms in all here.
_RUN_TYPES = ("char[]", "char *", "char **", "uintptr_t")


def declared_ffi() -> "cffi.FFI":
    """PySpice's cffi object with its declarations of ngspice's C API (taken once), the C locale set for ngspice."""
    locale.setlocale(locale.LC_NUMERIC, "C")   # ngspice parses numbers with the C locale
    from PySpice.Spice.NgSpice import Shared
    global _CDEF_DONE
    if not _CDEF_DONE:
        Shared.ffi.cdef(Path(Shared.__file__).with_name("api.h").read_text())
        for name in _RUN_TYPES:     # parsed once with the declarations, not inside the first run
            Shared.ffi.typeof(name)
        _CDEF_DONE = True
    return Shared.ffi


class Library:
    """One initialised ngspice library, through ngspice's C API with PySpice's declarations of it.

    PySpice 1.5's ``NgSpiceShared`` declares the API afresh for each instance (a second one fails:
    "duplicate declaration of struct ngcomplex"), and its background callback returns None where
    ngspice wants an int and reads "thread ended" as "running". Rather than override its private
    methods, the library gets callbacks of our own: what it prints, how far a run has come, a request
    to exit, the end of a background run; or, *talking* False, only the exit, so that no callback
    (each takes the GIL) slows a run.
    """

    def __init__(self, ffi, path: str, talking: bool = True):
        self.lines: list[tuple[str, str]] = []      # what the last command printed: (stream, text)
        self.exited = False                         # ngspice asked to exit: its state is unusable
        self.finished = threading.Event()           # set when a background run ends
        self.progress = 0.0                         # the share of a transient run done, as ngspice says
        self.lib = ffi.dlopen(path)
        null = ffi.NULL
        exit_ = ffi.callback("int(int, bool, bool, int, void *)", self._exit)
        printed = ffi.callback("int(char *, int, void *)", self._printed) if talking else null
        status = ffi.callback("int(char *, int, void *)", self._status) if talking else null
        ended = ffi.callback("int(bool, int, void *)", self._background) if talking else null
        self._callbacks = (exit_, printed, status, ended)       # alive as long as the library may call them
        self._ffi = ffi
        if self.lib.ngSpice_Init(printed, status, exit_, null, null, ended, null):
            raise SpiceError(f"cannot initialise the ngspice shared library {path}")

    def _printed(self, message, ident, user) -> int:     # the callbacks' signatures are ngspice's
        stream, _, text = self._ffi.string(message).decode("utf-8", "replace").partition(" ")
        self.lines.append((stream, text.strip()))
        return 0

    def _status(self, message, ident, user) -> int:
        # "tran: 12.3%": how far a run has come (ngspice says it as the percentage changes)
        text = self._ffi.string(message).decode("utf-8", "replace")
        head, _, rest = text.partition(":")
        if head.strip() == "tran" and rest.strip().endswith("%"):
            try:
                self.progress = float(rest.strip()[:-1]) / 100.0
            except ValueError:
                pass
        return 0

    def _background(self, ended, ident, user) -> int:
        if ended:           # ngspice passes true when its background thread has ended
            self.finished.set()
        return 0

    def _exit(self, status, immediate, quit_, ident, user) -> int:
        self.exited = True
        return status


def short_calls(path: str) -> ctypes.PyDLL:
    """The library's short calls, through ctypes.PyDLL, which keeps the GIL during a call.

    cffi releases the GIL around every call, and takes it back afterwards: while another thread
    runs Python, each return waits up to the interpreter's switch interval (5 ms), so reading
    200 vectors could wait a second. A run and a parse still go through cffi, releasing it.
    dlopen of a loaded path returns the same library, with the same global state.

    Parameters
    ----------
    path : str
        The library file, loaded already.
    """
    lib = ctypes.PyDLL(path)
    # addresses: the vector_info struct is read through a ctypes Structure (see VectorInfo)
    lib.ngGet_Vec_Info.argtypes, lib.ngGet_Vec_Info.restype = [ctypes.c_char_p], ctypes.c_void_p
    lib.ngSpice_AllVecs.argtypes, lib.ngSpice_AllVecs.restype = [ctypes.c_char_p], ctypes.c_void_p
    lib.ngSpice_CurPlot.argtypes, lib.ngSpice_CurPlot.restype = [], ctypes.c_char_p
    lib.ngSpice_Command.argtypes, lib.ngSpice_Command.restype = [ctypes.c_char_p], ctypes.c_int
    return lib


def strings(ffi, array) -> list[str]:
    """The strings of a NULL-ended ``char **``.

    Parameters
    ----------
    ffi : cffi.FFI
        The declarations.
    array : cdata
        The ``char **``.
    """
    out, k = [], 0
    while array[k] != ffi.NULL:
        out.append(ffi.string(array[k]).decode("utf-8", "replace"))
        k += 1
    return out


class VectorInfo(ctypes.Structure):
    """ngspice's ``vector_info`` (sharedspice.h), read where ngGet_Vec_Info points."""
    _fields_ = [("v_name", ctypes.c_char_p), ("v_type", ctypes.c_int), ("v_flags", ctypes.c_short),
                ("v_realdata", ctypes.c_void_p), ("v_compdata", ctypes.c_void_p), ("v_length", ctypes.c_int)]


class _DlInfo(ctypes.Structure):
    """The ``Dl_info`` that ``dladdr`` fills."""
    _fields_ = [("dli_fname", ctypes.c_char_p), ("dli_fbase", ctypes.c_void_p),
                ("dli_sname", ctypes.c_char_p), ("dli_saddr", ctypes.c_void_p)]


def mapped_file(function) -> str | None:
    """The file a loaded library's *function* (a ctypes function) came from, as the dynamic loader
    found it (``dladdr``); None where that cannot be told.

    Parameters
    ----------
    function : ctypes function
        A function of the library.
    """
    try:
        dladdr = ctypes.CDLL(None).dladdr
    except (OSError, AttributeError):
        return None
    info = _DlInfo()
    if not dladdr(ctypes.cast(function, ctypes.c_void_p), ctypes.byref(info)) or not info.dli_fname:
        return None
    return os.fsdecode(info.dli_fname)
