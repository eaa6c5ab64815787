"""A second ngspice library in process that prints nothing: a stack's circuit runs with no callback into Python."""

from __future__ import annotations

import threading

import numpy as np

from ..errors import SpiceError
from .ngspice import NgspiceSession, _short_calls, declared_ffi, session

__all__ = ["QuietSession", "quiet_session", "run_quietly"]


class _Silent:
    """What a session reads of PySpice's library object, for a library loaded with no print callback."""

    ngspice_version = None

    def __init__(self, ffi) -> None:
        self.ffi = ffi
        self.lines: list = []           # stays empty: nothing is printed
        self.exited = False
        self.finished = threading.Event()

    def _convert_string_array(self, array) -> list[str]:
        out, k = [], 0
        while array[k] != self.ffi.NULL:
            out.append(self.ffi.string(array[k]).decode("utf-8", "replace"))
            k += 1
        return out


class QuietSession(NgspiceSession):
    """A private copy of the ngspice library, initialised with no print, status, data or
    background-thread callback (only the one for a requested exit).

    Every line ngspice prints otherwise reaches Python through a callback, which must take the
    GIL: alone, a batch circuit of 100 2-DOF arms ran in 7.0 ms here against 8.4 ms in the
    talking session, and beside a thread running Python each callback waits for the GIL.
    With nothing printed there is nothing to judge a run by but its outcome, so a run that
    leaves no transient plot, or one short of its end, is run again in the talking session
    (:func:`run_quietly`). It runs in the foreground only, and counts no rejected points.
    """

    def __init__(self, path: str | None = None):
        super().__init__(path, private=True)

    def _open(self, path: str):
        ffi = declared_ffi()
        lib = ffi.dlopen(path)
        silent = _Silent(ffi)

        def exit_requested(status, immediate, quit_, ident, user):
            silent.exited = True
            return status
        silent.on_exit = ffi.callback("int(int, bool, bool, int, void*)", exit_requested)    # kept alive
        null = ffi.NULL
        if lib.ngSpice_Init(null, null, silent.on_exit, null, null, null, null):
            raise SpiceError(f"cannot initialise the ngspice shared library {path}")
        self._ffi, self._lib, self._ng = ffi, lib, silent
        self._short = _short_calls(path)
        self._command("set nomoremode")

    def run(self, netlist: str, vectors=None, stats: dict | None = None, analysis: str = "tran",
            timeout: float | None = None) -> dict[str, np.ndarray]:
        """:meth:`NgspiceSession.run`, in the foreground; a failure names no cause (nothing is printed).

        Parameters
        ----------
        netlist : str
            The netlist text (ASCII).
        vectors : sequence of str, optional
            Vectors to return.
        stats : dict, optional
            Filled with the seconds ``waited`` for another thread's run.
        analysis : {"tran", "ac"}
            The netlist's analysis.
        timeout : None
            Must be None: a limited run needs the background thread and its callback.
        """
        if timeout is not None:
            raise ValueError("a quiet session runs in the foreground only: run a limited circuit in session()")
        return super().run(netlist, vectors, stats, analysis)


_QUIET: QuietSession | None = None
_QUIET_LOCK = threading.Lock()


def quiet_session() -> QuietSession:
    """The process's quiet session, loaded on first use (once, whichever thread asks)."""
    global _QUIET
    with _QUIET_LOCK:
        if _QUIET is None:
            # The talking library first: the system's is opened by its name (libngspice.so.0), which
            # the dynamic loader would match to this copy's soname if the copy were loaded before it.
            session()
            _QUIET = QuietSession()
        return _QUIET


def run_quietly(netlist: str, t_stop: float, stats: dict | None = None) -> dict[str, np.ndarray]:
    """A transient *netlist* run to *t_stop* in the quiet session; where it shows a failure (no transient
    plot, or time short of *t_stop*), run again in the talking session, whose messages make the error.

    Every malformed netlist tried (an unknown device or parameter, a bad number, a duplicate
    name, a bad ``.tran``, a line of prose) left the quiet library with no transient plot
    where the talking one raised, and every netlist the talking one ran reached its end in both.

    Parameters
    ----------
    netlist : str
        The netlist text (ASCII).
    t_stop : float
        The end of its ``.tran``.
    stats : dict, optional
        As :meth:`NgspiceSession.run`'s.
    """
    try:
        data = quiet_session().run(netlist, None, stats)
        if data["time"].size and data["time"][-1] >= t_stop * (1 - 1e-9):
            return data
    except SpiceError:
        pass
    return session().run(netlist, None, stats)
