"""A second ngspice library in process that prints nothing: a stack's circuit runs with no callback into Python."""

from __future__ import annotations

import logging
import os
import pwd
import threading
from pathlib import Path

import numpy as np

from ..errors import SpiceError
from .ngspice import NgspiceSession, session

__all__ = ["QuietSession", "quiet_session", "run_quietly"]

#: Guards the process's one quiet session (a copy initialises under ngspice's own loading lock).
_LOCK = threading.Lock()


class QuietSession(NgspiceSession):
    """A private copy of the library the talking :func:`~analogy.solvers.ngspice.session` runs,
    initialised with no print, status, data or background-thread callback (only the one for
    a requested exit), and without ngspice's ``spinit``; none is made where a ``.spiceinit``
    would run.

    Every line ngspice prints otherwise reaches Python through a callback, which must take the
    GIL: beside a thread running Python, each waits for it. With nothing printed there is
    nothing to judge a run by but its outcome, so :func:`run_quietly` runs again in the talking
    session a run that leaves no transient plot or ends short of its t_stop. It runs in the
    foreground only, and reads no counts of iterations or rejected points (ngspice prints them).

    ``spinit`` is left out because it loads the XSPICE code models, whose one shared handle per
    file points back to the copy that loaded it last: a code-model device in the talking library
    then crashed the process. The circuits written here use none.
    """

    prints = False

    def __init__(self):
        # ngspice runs a .spiceinit in the working or home folder whatever SPICE_SCRIPTS says, and
        # one that loads code models would bring back the crash spinit is left out for
        found = _spiceinit()
        if found is not None:
            raise SpiceError(f"{found} would run in the quiet copy too")
        talking = session()     # first: the system's library is opened by its soname, which the
        # dynamic loader would match to this copy's if the copy were loaded before it
        super().__init__(talking.origin or talking._source, private=True)

    def _open(self, path: str):
        before = os.environ.get("SPICE_SCRIPTS")
        os.environ["SPICE_SCRIPTS"] = os.devnull        # no spinit (``/dev/null/spinit`` cannot exist), so no code models
        try:
            super()._open(path)
        finally:
            if before is None:
                del os.environ["SPICE_SCRIPTS"]
            else:
                os.environ["SPICE_SCRIPTS"] = before

    def run(self, netlist: str, vectors=None, stats: dict | None = None, analysis: str = "tran",
            timeout: float | None = None, until: float | None = None) -> dict[str, np.ndarray]:
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
        until : float, optional
            The time a transient run must reach.
        """
        if timeout is not None:
            raise ValueError("a quiet session runs in the foreground only: run a limited circuit in session()")
        return super().run(netlist, vectors, stats, analysis, until=until)


_QUIET: list = []           # the session, or None where it could not be loaded


def _spiceinit() -> Path | None:
    """The ``.spiceinit`` ngspice would run, in the working or home folder (None: none)."""
    for folder in (Path.cwd(), Path.home(), Path(pwd.getpwuid(os.getuid()).pw_dir)):
        if (folder / ".spiceinit").exists():
            return folder / ".spiceinit"
    return None


def quiet_session() -> QuietSession | None:
    """The process's quiet session, loaded on first use (once, whichever thread asks); None where
    the library could not be copied or initialised a second time: the stacks then run in the
    talking session, more slowly. That is logged once by the ``analogy`` logger: as a warning where
    the user's ``.spiceinit`` is the reason (theirs to move), as information where the copy could
    not be made (a file-size limit, a sandbox), which the run that follows meets again if it matters."""
    with _LOCK:
        if not _QUIET:
            try:
                _QUIET.append(QuietSession())
            except (SpiceError, OSError) as exc:
                _QUIET.append(None)
                logging.getLogger("analogy").log(
                    logging.WARNING if _spiceinit() is not None else logging.INFO,
                    "no quiet copy of the ngspice library (%s): batched groups run in the talking one, "
                    "more slowly", exc)
        return _QUIET[0]


def run_quietly(netlist: str, t_stop: float, stats: dict | None = None) -> dict[str, np.ndarray]:
    """A transient *netlist* of this package's writing run to *t_stop* in the quiet session; where it
    fails (no transient plot, or time short of *t_stop*), run again in the talking session, whose
    messages make the error.

    The netlist's element and analysis lines are judged by their outcome alone: every malformed
    one tried (an unknown device or parameter, a bad number, a duplicate name, a bad ``.tran``, a
    line of prose) left the quiet library with no transient plot where the talking one raised.
    Its ``.options`` values are checked before they are written
    (:func:`~analogy.solvers.transient.transient_settings`): ngspice runs on after an option it
    cannot read, saying so only in print.

    Parameters
    ----------
    netlist : str
        The netlist text (ASCII).
    t_stop : float
        The end of its ``.tran``.
    stats : dict, optional
        As :meth:`NgspiceSession.run`'s.
    """
    quiet = quiet_session()
    if quiet is not None:
        try:
            return quiet.run(netlist, None, stats, until=t_stop)
        except SpiceError:
            pass
    return session().run(netlist, None, stats, until=t_stop)
