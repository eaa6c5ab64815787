"""ngspice in process: one session, a clean state after every run, failures as one sentence."""

from __future__ import annotations

import ctypes
import os
import re
import threading
import time as _time
from pathlib import Path

import numpy as np

from ..errors import SpiceError
from ..processes import halt_requests
from .library_copy import library_copy
from .ngspice_library import Library, VectorInfo, declared_ffi, library_path, mapped_file, short_calls, strings

__all__ = ["NgspiceSession", "collapsed", "session", "run_netlist", "library_path", "vector_key"]

_INFO_PREFIXES = ("warning", "note", "using", "doing analysis", "reference value",
                  "circuit:", "no. of data rows")
#: The longest a running circuit goes between looks at :data:`~analogy.processes.halt_requests` [s].
_STOP_POLL = 0.05
#: Seconds without progress after which a timed run is stalled (at least; a twentieth of its limit).
_STALL_WINDOW = 5.0

#: Held while a library copy initialises: ngspice reads its environment (SPICE_SCRIPTS) then.
_LOADING = threading.RLock()

_RETIRED: list = []         # libraries replaced by a fresh copy, kept alive (see NgspiceSession._open)
_CANARY = "* canary\nI1 0 n1 DC 1\nR1 n1 0 1\nC1 n1 0 1\n.tran 0.1 1 uic\n.end\n"


def vector_key(name: str) -> str:
    """The key of a vector in :meth:`NgspiceSession.run`'s result.

    ngspice names device vectors in lower case, so keys are lower case, and a node
    voltage ``v(n1)`` is keyed by its node, ``n1``; a device current ``@C1_2[i]`` is
    ``@c1_2[i]``.

    Parameters
    ----------
    name : str
        A vector name such as ``v(n1)`` or ``@C1_2[i]``.
    """
    key = name.strip().lower()
    if key.startswith("v(") and key.endswith(")"):
        key = key[2:-1]
    return key


def collapsed(exc: BaseException) -> bool:
    """True for a run whose step collapsed: ngspice's "timestep too small", a run stalled before
    its time limit (:meth:`NgspiceSession.run`), or ngspice 46's "run simulation(s) aborted" (seen
    under KLU at a PWM's and a bridge's corners); a retry with looser settings may pass.

    Parameters
    ----------
    exc : BaseException
        The failure.
    """
    text = str(exc)
    return "time step too small" in text or "run stalled" in text or "simulation(s) aborted" in text


def _is_error(text: str) -> bool:
    low = text.lower()
    if low.startswith(_INFO_PREFIXES):
        return False
    return ("error" in low or "aborted" in low or "too small" in low or "not parsed" in low
            or "fatal" in low)


def _describe_failure(lines: list[str], stage: str) -> str:
    text = " ".join(lines)
    node = None
    m = re.search(r"(?:check node|trouble with node)\s+\"?([\w#.()-]+)\"?", text, re.I)
    if m:
        node = m.group(1)
    m = re.search(r"timestep too small; time = ([0-9.eE+-]+)", text, re.I)
    if m:
        msg = f"ngspice {stage}: time step too small at t = {float(m.group(1)):.6g} s"
        if "singular" in text.lower():
            msg += ", singular matrix"
        return msg + (f" at node {node}" if node else "")
    if "singular matrix" in text.lower():
        return f"ngspice {stage}: singular matrix" + (f" at node {node}" if node else "")
    m = re.search(r"error on line (\d+)[^:]*:\s*(.*)", text, re.I)
    if m:
        return f"ngspice {stage}: error on netlist line {m.group(1)}: {m.group(2).strip()}"
    errors = [ln for ln in lines if _is_error(ln)]
    detail = errors[0] if errors else (lines[-1] if lines else "no output")
    return f"ngspice {stage}: {detail}"


_CONTROL = re.compile(r"^\s*\.control", re.I | re.M)
_ANY_CONTROL = re.compile(r"\.control", re.I)      # a plain search, six times faster: the line test only where it finds one


class _Lines:
    """A netlist as ngSpice_Circ takes it: one buffer of NUL-terminated lines and the NULL-ended
    array of pointers into it, made before the library is taken (Python work no run need wait for)."""

    __slots__ = ("buffer", "starts", "array")

    def __init__(self, ffi, netlist: str):
        if not netlist.isascii():
            raise SpiceError("netlist contains non-ASCII characters")
        if "\0" in netlist:            # it would end its line early, unseen
            raise SpiceError("netlist contains a NUL character")
        lines = netlist.splitlines()
        if _ANY_CONTROL.search(netlist) and _CONTROL.search(netlist):
            lines = _without_control(lines)
        kept = [line for line in lines if line]
        # one byte per character (ASCII): a line's length in bytes is its length
        self.buffer = ffi.new("char[]", "\0".join(kept).encode("ascii") + b"\0")
        self.starts = np.zeros(len(kept) + 1, dtype=np.uintp)       # the last pointer is NULL
        if kept:
            self.starts[1:-1] = np.cumsum(np.fromiter(map(len, kept), dtype=np.uintp, count=len(kept)) + 1)[:-1]
            self.starts[:-1] += int(ffi.cast("uintptr_t", self.buffer))
        self.array = ffi.cast("char **", ffi.from_buffer(self.starts))


def _without_control(lines: list[str]) -> list[str]:
    """*lines* without their ``.control`` … ``.endc`` blocks: a run in process is driven from
    here, and what such a block sets (``numdgt`` of a printed netlist) would stay set
    for every later circuit of the library."""
    out, inside = [], False
    for line in lines:
        word = line.strip().lower()
        if word.startswith(".control"):
            inside = True
        elif word.startswith(".endc"):
            inside = False
        elif not inside:
            out.append(line)
    return out


class NgspiceSession:
    """One loaded ngspice library: load a netlist, run it, read vectors, free the circuit.

    Each :meth:`run` ends with ``destroy all``, ``remcirc`` and a cleared command
    memory, and what ngspice printed is dropped, so that memory stays flat over
    thousands of runs (:func:`analogy.diagnostics.memory.memory_per_run` measures it). If ngspice
    asks to exit or fails its canary after an error, the library is loaded afresh from
    a private copy, since ngspice keeps global state that a fatal error can leave broken.
    """

    #: Whether the library prints (the quiet copy does not, so it has no counts to read).
    prints = True

    def __init__(self, path: str | None = None, private: bool = False):
        self._lock = threading.Lock()
        self._source = path or library_path()
        self._generation = 0
        #: The file the library was first loaded from, as the dynamic loader found it: copies are
        #: made of it (None where that cannot be told, or for a private copy).
        self.origin: str | None = None
        if private:         # a copy of its own: its global state shared with no other session
            self._reload()
        else:
            with _LOADING:
                self._open(self._source)
            found = mapped_file(self._short.ngSpice_Init)
            self.origin = os.path.abspath(found) if found else None

    def _open(self, path: str):
        self._ffi = declared_ffi()
        if getattr(self, "_ng", None) is not None:
            # a library left behind (a fatal error, a halted run whose thread never ended) may still
            # call back or run: its code and callbacks stay mapped for as long as the process lives
            _RETIRED.append(self._ng)
        try:
            self._ng = Library(self._ffi, path, talking=self.prints)
        except OSError as exc:
            raise SpiceError(f"cannot load the ngspice shared library {path}: {exc}") from None
        self._lib = self._ng.lib
        self._short = short_calls(path)
        self._command("set nomoremode")
        self._version = None
        if self.prints:
            found = re.search(r"ngspice-(\d+)", " ".join(t for _, t in self._command("version -s")))
            self._version = int(found.group(1)) if found else None

    def _reload(self):
        # A fresh copy has its own global state; dlopen of the same path would share it.
        src = Path(self.origin or self._resolve(self._source))
        self._generation += 1
        copy = ""
        try:
            with _LOADING, library_copy(src) as copy:
                self._open(copy)
        except (SpiceError, OSError):
            if not copy.startswith("/proc/self/fd/"):
                raise
            # a policy may refuse to map a copy in memory as code: one on disk then
            with _LOADING, library_copy(src, in_memory=False) as copy:
                self._open(copy)

    @staticmethod
    def _resolve(name: str) -> str:
        if os.path.sep in name:
            return name
        for d in ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib", "/usr/local/lib"):
            p = Path(d) / name
            if p.exists():
                return str(p)
        raise SpiceError(f"cannot locate {name} on disk to reload ngspice")

    @property
    def version(self) -> int | None:
        """ngspice's major version, as the library says (None where it prints nothing)."""
        return self._version

    def _command(self, cmd: str, release: bool = False) -> list[tuple[str, str]]:
        """Run *cmd* and return what ngspice printed; with *release*, other threads run meanwhile
        (a run: its lines come back from ngspice's callbacks, which take the GIL themselves)."""
        self._ng.lines = []
        rc = (self._lib if release else self._short).ngSpice_Command(cmd.encode("ascii"))
        if rc:
            raise SpiceError(f"ngspice rejected the command {cmd!r}")
        return self._ng.lines

    def _load(self, netlist: "_Lines") -> list[tuple[str, str]]:
        self._ng.lines = []
        rc = self._lib.ngSpice_Circ(netlist.array)
        printed = self._ng.lines
        if rc:
            printed = printed + [("stderr", f"error: ngSpice_Circ returned {rc}")]
        return printed

    def _vectors(self, plot: str) -> dict[str, np.ndarray]:
        """The plot's vectors, the real ones of one length copied into the rows of one array
        (a batch reads hundreds; the library is held meanwhile)."""
        ffi, lib = self._ffi, self._short
        listed = lib.ngSpice_AllVecs(plot.encode())
        names = strings(ffi, ffi.cast("char **", listed)) if listed else []
        found = []
        for name in names:
            address = lib.ngGet_Vec_Info(f"{plot}.{name}".encode())
            if address:         # one struct in ngspice, filled again by each call: read at once
                info = VectorInfo.from_address(address)
                found.append((name, info.v_realdata, info.v_compdata, info.v_length))
        out = {}
        for length in dict.fromkeys(n for _, real, _, n in found if real):
            these = [(name, real) for name, real, _, n in found if real and n == length]
            block = np.empty((len(these), length))
            start, row = ffi.from_buffer(block), 8 * length
            for j, (name, real) in enumerate(these):
                # cffi's memmove keeps the GIL (ctypes' gives it up, and another thread may keep it)
                ffi.memmove(start + j * row, ffi.cast("char *", real), row)
                out[vector_key(name)] = block[j]
        for name, real, pairs, n in found:
            if not real and pairs:      # an AC sweep: (re, im) pairs
                both = np.ctypeslib.as_array((ctypes.c_double * (2 * n)).from_address(pairs))
                out[vector_key(name)] = both[0::2] + 1j * both[1::2]
        return out

    def _plot(self) -> str:
        """The current plot's name ("" when there is none)."""
        name = self._short.ngSpice_CurPlot()
        return name.decode() if name else ""

    def _free(self):
        self._command("destroy all")
        self._command("remcirc")
        # ngspice keeps every command it has parsed (about 0.2 kB each) until it is sent NULL.
        self._short.ngSpice_Command(None)
        self._ng.lines = []         # what a run said is read by then

    def _healthy(self) -> bool:
        try:
            lines = self._load(_Lines(self._ffi, _CANARY)) + self._command("run", release=True)
            ok = not any(_is_error(t) for s, t in lines) and not self._ng.exited and self._plot().startswith("tran")
            self._free()
            return ok
        except SpiceError:
            return False

    def run(self, netlist: str, vectors=None, stats: dict | None = None,
            analysis: str = "tran", timeout: float | None = None, until: float | None = None) -> dict[str, np.ndarray]:
        """Run a transient (or, with *analysis* ``"ac"``, an AC) netlist: ``{"time": …, node: …}``.

        The vectors of one length are rows of one array (one copy out of ngspice); the time or
        frequency vector is an array of its own.

        Parameters
        ----------
        netlist : str
            The netlist text (ASCII).
        vectors : sequence of str, optional
            Return only these, keyed as given; each is looked up by :func:`vector_key`,
            so ``n1``, ``v(n1)`` and ``@c1_2[i]`` all work.
        stats : dict, optional
            Filled with ngspice's ``iterations`` and ``rejected`` time points, and the seconds
            ``waited`` for another thread's run to end.
        analysis : {"tran", "ac"}
            The netlist's analysis; an AC run returns ``"frequency"`` and complex vectors.
        timeout : float, optional
            Wall-time limit [s]: the run goes to ngspice's background thread and is
            halted past it (:class:`SpiceError`, "time limit").
        until : float, optional
            The time a transient run must reach (its t_stop): one that ends short fails.

        Raises
        ------
        SpiceError
            With one sentence naming the failure and, where ngspice says, the node.
        """
        if halt_requests.asked():       # a batch is stopping its group threads: no new circuit
            raise KeyboardInterrupt
        if until is not None and analysis != "tran":
            raise ValueError("until is the end of a transient run")
        lines = _Lines(self._ffi, netlist)
        asked = _time.perf_counter()
        with self._lock:
            if self._ng.exited:         # it asked to exit, or a halted run's thread never ended
                self._reload()
            if stats is not None:       # another thread's run held the library: not this run's time
                stats["waited"] = stats.get("waited", 0.0) + _time.perf_counter() - asked
            try:
                data = self._run(lines, vectors, stats, analysis, timeout)
                if until is not None and not (data["time"].size and data["time"][-1] >= until * (1 - 1e-9)):
                    end = data["time"][-1] if data["time"].size else 0.0
                    raise SpiceError(f"ngspice transient analysis failed: it ended at t = {end:g} s, short of "
                                     f"{until:g} s")
                return data
            except SpiceError:
                # Leave a clean instance for the next run, whatever state ngspice is in.
                if self._ng.exited or not self._healthy():
                    self._reload()
                raise

    def _timed(self, timeout: float) -> list[tuple[str, str]]:
        """``bg_run``, halted with ``bg_halt`` past *timeout*, or once stalled: ngspice's own steps have
        no other bound.

        A run whose progress (ngspice's "tran: p%", to 0.1%) stays put for a twentieth of the time
        limit cannot finish within it (the rest would take a thousand times as long), so it is halted
        then as stalled rather than at the limit: ngspice 39 was seen to crawl without end where its
        step sat near the tolerance, under PWM drives, and never say "timestep too small".
        """
        self._ng.lines = []
        self._ng.finished.clear()
        self._ng.progress = 0.0
        if self._lib.ngSpice_Command(b"bg_run"):
            raise SpiceError("ngspice rejected the command 'bg_run'")
        start = _time.perf_counter()
        end, window = start + timeout, max(_STALL_WINDOW, timeout / 20)
        seen, since = self._ng.progress, start
        stalled = False
        try:
            # in slices: a batch stopping its group threads halts the run
            while not (finished := self._ng.finished.wait(min(_STOP_POLL, max(end - _time.perf_counter(), 0.0)))):
                if halt_requests.asked():       # a stop, as Ctrl-C makes one: no result at all
                    self._halt()
                    raise KeyboardInterrupt
                now = _time.perf_counter()
                if self._ng.progress != seen:
                    seen, since = self._ng.progress, now
                elif self.prints and seen > 0 and now - since >= window:
                    stalled = True      # a quiet library says no progress: only the time limit applies there
                    break
                if now >= end:
                    break
        except BaseException:           # a signal (Ctrl-C, SIGTERM) while ngspice runs: halt it first
            if not self._ng.finished.is_set():
                self._halt()
            raise
        if not finished:
            self._halt()
            if stalled:
                raise SpiceError(f"ngspice's run stalled: it stayed at {seen:.1%} of its time span for "
                                 f"{window:g} s, so it would pass its time limit of {timeout:g} s (its step "
                                 "collapsing near the tolerance without saying so)")
            raise SpiceError(f"ngspice passed its time limit of {timeout:g} s: the circuit needs more "
                             "steps than that allows (raise the timeout, or use the fast preset)")
        return self._ng.lines

    def _halt(self) -> None:
        """Stop a background run and free its circuit."""
        self._lib.ngSpice_Command(b"bg_halt")
        if self._ng.finished.wait(60.0):
            self._free()
        else:       # its thread still runs: nothing of it is touched; the next run loads a fresh copy
            self._ng.exited = True

    def _run(self, lines: _Lines, vectors, stats=None, analysis="tran", timeout=None):
        index = "time" if analysis == "tran" else "frequency"
        load = self._load(lines)
        errors = [t for s, t in load if _is_error(t)]
        if errors or self._ng.exited:
            self._free()
            raise SpiceError(_describe_failure([t for s, t in load], "could not parse the netlist"))
        ran = self._command("run", release=True) if timeout is None else self._timed(timeout)
        failed = [t for s, t in ran if _is_error(t)]
        plot = self._plot()
        if failed or self._ng.exited or not plot.startswith(analysis):
            self._free()
            stage = "transient analysis failed" if analysis == "tran" else "AC analysis failed"
            raise SpiceError(_describe_failure([t for s, t in ran], stage))
        data = self._vectors(plot)
        if stats is not None and self.prints:
            for _, text in self._command("rusage rejected"):
                name, _, value = text.partition(" = ")
                key = {"Transient iterations": "iterations", "Rejected timepoints": "rejected"}.get(name)
                if key and value.strip().isdigit():
                    stats[key] = int(value)
        self._free()
        if index not in data:
            raise SpiceError(f"ngspice returned no {index} vector")
        # the index on its own: kept alone (a shared grid), it holds no other vector's memory
        data[index] = data[index].real.copy() if index == "frequency" else data[index].copy()
        if vectors is not None:
            missing = [v for v in vectors if vector_key(v) not in data]
            if missing:
                raise SpiceError(f"ngspice did not save vector {missing[0]!r}")
            data = {index: data[index], **{v: data[vector_key(v)] for v in vectors}}
        return data


_SESSION: NgspiceSession | None = None
_SESSION_LOCK = threading.Lock()


def session() -> NgspiceSession:
    """The process's ngspice session, loaded on first use (once, whichever thread asks)."""
    global _SESSION
    with _SESSION_LOCK:
        if _SESSION is None:
            _SESSION = NgspiceSession()
        return _SESSION


def run_netlist(netlist: str, vectors=None) -> dict[str, np.ndarray]:
    """Run *netlist* in the process's ngspice session.

    Parameters
    ----------
    netlist : str
        The netlist text.
    vectors : sequence of str, optional
        Vectors to return (see :meth:`NgspiceSession.run`).
    """
    return session().run(netlist, vectors)
