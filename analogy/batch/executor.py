"""The one loop that runs a batch's groups: local processes, in this process or any Executor; retries and clean stops."""

from __future__ import annotations

import signal
import sys
import threading
from concurrent.futures import FIRST_COMPLETED, CancelledError, Executor, Future, ThreadPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Callable, Iterable

from ..errors import AnalogyError, SimulationError
from ..processes import halt_requests, stop_requests, worker_pool

__all__ = ["InlineExecutor", "execute", "ATTEMPTS", "PIPELINE", "SWITCH_INTERVAL"]

#: A group whose worker died is run this many times in all before it is given up.
ATTEMPTS = 2

#: The longest the loop waits between looks at :data:`~analogy.processes.stop_requests` [s].
_POLL_SECONDS = 0.25

#: Groups in flight in this process (its :data:`in_process` worker): while one group's circuit
#: runs in ngspice's own thread, which holds no Python lock, the next group's Python work goes on.
PIPELINE = 2

#: The interpreter's switch interval while groups run on threads here [s]. Every return from the
#: library takes the GIL back from the thread running Python, which by default keeps it up to 5 ms,
#: and the library waits meanwhile. With 0.5 ms the default arm's batch ran 7,993 scenes/s against
#: 7,147 (medians of five alternating runs of 4,000 scenes; 1 ms gave 7,568). Once the library was
#: held for ngspice's own work alone, one process reached 0.85 of the floor with 0.1 ms against 0.82
#: with 0.2 ms and 0.5 ms, and 0.05 ms was no better (medians of 6 to 8 alternating runs of 5,000).
SWITCH_INTERVAL = 0.0001

_SWITCHES = threading.Lock()
_SWITCHED: list = [0, None]         # batches running groups on threads here, and the interval before them


def _short_switches(on: bool) -> None:
    """Enter (*on*) or leave a batch running groups on threads: the first in lowers the switch
    interval to :data:`SWITCH_INTERVAL`, the last out restores the one before."""
    with _SWITCHES:
        if on:
            if _SWITCHED[0] == 0:
                _SWITCHED[1] = sys.getswitchinterval()
                sys.setswitchinterval(min(_SWITCHED[1], SWITCH_INTERVAL))
            _SWITCHED[0] += 1
        else:
            _SWITCHED[0] -= 1
            if _SWITCHED[0] == 0:
                sys.setswitchinterval(_SWITCHED[1])


class InlineExecutor(Executor):
    """Runs each submitted call at once, in this process: a batch with nothing to spread."""

    def submit(self, fn, /, *args, **kwargs) -> Future:
        """Call ``fn(*args, **kwargs)`` now; its result or exception is the returned future's.

        Parameters
        ----------
        fn : callable
            The work.
        *args
            Its positional arguments.
        **kwargs
            Its keyword arguments.
        """
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except Exception as exc:        # noqa: BLE001 - the caller reads it from the future
            future.set_exception(exc)
        return future


class _Stop(BaseException):
    """SIGTERM, turned into a clean stop like Ctrl-C (past every ``except Exception``)."""


def _end_pool(pool) -> None:
    """Stop a process pool now: pending groups cancelled, workers killed."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        if p.is_alive():
            p.kill()
    for p in procs:
        p.join(timeout=5)


def _end_threads(pool, inflight: dict, done: Callable, threads: bool) -> None:
    """Stop this process's group threads: a circuit running in ngspice halted and none started
    (:data:`~analogy.processes.halt_requests`: that group raises KeyboardInterrupt and is dropped),
    the Python work in flight waited for, and the groups that finished handed over."""
    if not threads:
        return
    halt_requests.ask()
    try:
        pool.shutdown(wait=True, cancel_futures=True)
    finally:                        # whatever interrupts the wait, no later run is halted
        halt_requests.clear()
    for future, item in inflight.items():
        if not future.cancelled() and future.exception() is None:
            done(item[1], future.result())
    inflight.clear()


def _death_types() -> tuple:
    """Dask's report of a dead worker, when Dask is in use (never imported for it: a quarter second)."""
    scheduler = sys.modules.get("distributed.scheduler")
    killed = getattr(scheduler, "KilledWorker", None)
    return (killed,) if isinstance(killed, type) else ()


def _again(item: tuple, attempts: dict, retry: list, solo: list, died: Callable, alone: bool) -> None:
    """A numbered group whose worker died: retried; after :data:`ATTEMPTS` runs, run alone
    (a pool dies whole, so a group beside the culprit is not blamed), then given up."""
    attempts[item[0]] = attempts.get(item[0], 0) + 1
    if attempts[item[0]] < ATTEMPTS:
        retry.append(item)
    elif not alone:
        solo.append(item)
    else:
        died(item[1])


class _Loop:
    """One run of :func:`execute`: the pool, the groups in flight and their attempts."""

    def __init__(self, groups: Iterable, payload: Callable, work: Callable, done: Callable, died: Callable,
                 workers: int, executor: Executor | None, in_process: bool, stored: Callable[[], str],
                 pipeline: int = PIPELINE) -> None:
        self.payload, self.work, self.done, self.died, self.stored = payload, work, done, died, stored
        self.own = executor is None
        self.local = self.own and (workers > 1 or not in_process)
        self.threads = self.own and not self.local          # groups on threads of this process
        self.workers, self.pipeline = workers, max(pipeline, 1)
        self.pool = self._new_pool() if self.own else executor
        self.limit = 4 * workers if self.local else self.pipeline if self.own else 64
        self.pending = enumerate(groups)         # numbered: a retried group keeps its number
        self.inflight: dict = {}
        self.attempts: dict = {}
        self.retry: list = []
        self.solo: list = []
        self.deaths = (BrokenProcessPool,) + _death_types()

    def _new_pool(self):
        if self.local:
            return worker_pool(self.workers)
        return ThreadPoolExecutor(self.pipeline, thread_name_prefix="analogy-group") if self.pipeline > 1 \
            else InlineExecutor()

    def _renew(self) -> None:
        _end_pool(self.pool)
        self.pool = self._new_pool()

    def run(self) -> None:
        """Submit, wait, hand over, until every group is done; a stop asked raises :class:`_Stop`."""
        while True:
            if stop_requests.asked():   # a stop whose exception was swallowed, here or before the loop
                raise _Stop()
            self._fill()
            if not self.inflight:
                return
            self._collect()

    def _fill(self) -> None:
        """Submit groups until :attr:`limit` are in flight; a suspect runs with nothing beside it."""
        while len(self.inflight) < self.limit:
            if self.solo and self.inflight:
                return
            item = self.solo.pop() if self.solo else self.retry.pop() if self.retry else next(self.pending, None)
            if item is None:
                return
            try:
                future = self.pool.submit(self.work, self.payload(item[1]))
            except BrokenProcessPool:
                # a worker died since the last wait: the group never ran, so it waits for
                # the new pool (made after the dead futures come back, or here)
                if not self.local:
                    raise
                self.retry.append(item)
                if not self.inflight:
                    self._renew()
                    continue
                return
            self.inflight[future] = item
            if self.attempts.get(item[0], 0) >= ATTEMPTS:
                return

    def _collect(self) -> None:
        """Wait for a group to finish (or a stop), and hand over what finished; a dead pool is renewed."""
        alone = len(self.inflight) == 1 or not self.local     # an outside executor reports each task's own death
        while True:                 # what finished is handed over, even when a stop was asked
            finished, _ = wait(list(self.inflight), timeout=_POLL_SECONDS, return_when=FIRST_COMPLETED)
            if finished or stop_requests.asked():
                break
        broken = False
        for future in finished:
            item = self.inflight.pop(future)
            try:
                result = future.result()
            except CancelledError:
                # only an outside executor cancels: a Dask scheduler that stopped, say
                raise SimulationError("the executor cancelled the work (did the Dask scheduler stop?)"
                                      + self.stored()) from None
            except self.deaths as exc:
                broken = broken or isinstance(exc, BrokenProcessPool)
                _again(item, self.attempts, self.retry, self.solo, self.died, alone)
                continue
            self.done(item[1], result)
        if broken and self.local:        # every other group in flight died with the pool
            for item in self.inflight.values():
                _again(item, self.attempts, self.retry, self.solo, self.died, alone)
            self.inflight.clear()
            self._renew()

    def close(self) -> None:
        """End the pool this loop made."""
        if self.local:
            _end_pool(self.pool)
        elif self.own:
            self.pool.shutdown(wait=True, cancel_futures=True)


def _on_sigterm() -> object:
    """In the main thread, SIGTERM asks for a stop and raises :class:`_Stop` (once); the old handler."""
    if threading.current_thread() is not threading.main_thread():
        return None
    stopping: list = []

    def _term(signum, frame):
        if not stopping:            # once: a second SIGTERM must not break the clean-up
            stopping.append(signum)
            stop_requests.ask()
            raise _Stop()
    return signal.signal(signal.SIGTERM, _term)


def execute(groups: Iterable, payload: Callable, work: Callable, done: Callable, died: Callable, *,
            workers: int = 2, executor: Executor | None = None, in_process: bool = False,
            stored: Callable[[], str] = lambda: "", pass_signals: bool = False, pipeline: int = PIPELINE) -> bool:
    """Run ``work(payload(group))`` for every group and hand each result to ``done(group, result)``.

    Groups are submitted lazily, a few per worker, and each result is handed over as it
    arrives. Without *executor*, *workers* local processes run them (one: this process).
    With *in_process*, one worker is this process itself, with *pipeline* groups in
    flight on threads; otherwise every group runs in a worker process, so that a crash in one
    is that group's own. A group whose worker died is retried, then given to ``died(group)``.
    SIGINT and SIGTERM stop the loop cleanly: what was handed over stays (in this process,
    with every group in flight that finished), workers are ended; with
    *pass_signals* the signal then goes on to the caller (KeyboardInterrupt, or SIGTERM
    raised again under the caller's own handler).

    Parameters
    ----------
    groups : iterable
        What to run, in order.
    payload : callable
        A group's argument for *work*, made when it is submitted.
    work : callable
        A module-level function (it is pickled by name for worker processes).
    done : callable
        Receives each group and its result.
    died : callable
        Receives a group whose worker died on every attempt.
    workers : int
        Local worker processes when no *executor* is given.
    executor : Executor, optional
        Runs the groups instead (a Dask client's ``get_executor()``, say).
    in_process : bool
        Run in this process when *workers* is 1.
    stored : callable
        What is kept so far and how to resume, for the message of an executor that failed.
    pass_signals : bool
        After the clean stop, pass SIGINT or SIGTERM on instead of returning True.
    pipeline : int
        Groups in flight on threads where they run in this process (1: one at a time, no thread).

    Returns
    -------
    bool
        True when SIGINT or SIGTERM stopped the loop before the end.
    """
    loop = _Loop(groups, payload, work, done, died, workers, executor, in_process, stored, pipeline)
    old_term = _on_sigterm()
    switched = False
    try:
        if loop.threads and loop.pipeline > 1:
            _short_switches(True)
            switched = True
        loop.run()
    except KeyboardInterrupt:
        stopped = signal.SIGINT
        _end_threads(loop.pool, loop.inflight, done, loop.threads)
    except _Stop:
        stopped = signal.SIGTERM
        _end_threads(loop.pool, loop.inflight, done, loop.threads)
        stop_requests.clear()           # acted on: the caller hears of it below, or from the return
    except Exception as exc:
        # a group's own failure is its work's to report: what reaches here is the outside executor's
        if loop.own or isinstance(exc, AnalogyError):
            raise
        detail = " ".join(str(exc).split())[:160] or type(exc).__name__
        raise SimulationError(f"the executor failed ({type(exc).__name__}: {detail}; did the Dask scheduler "
                              f"stop?){stored()}") from None
    else:
        return False
    finally:
        if switched:
            _short_switches(False)
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
        loop.close()
    if pass_signals:
        if stopped == signal.SIGINT:
            raise KeyboardInterrupt
        signal.raise_signal(stopped)        # the caller's handler, or the default end of the process
    return True
