"""The batch loop shared by run_batch and run_sweep: every group handed over once, deaths retried, clean stops."""

import _thread
import os
import signal
import sys
import threading
from pathlib import Path

import pytest

from analogy.batch import executor
from analogy.batch.executor import ATTEMPTS, PIPELINE, execute
from analogy.processes import halt_requests, stop_requests
from analogy.solvers.ngspice import session

#: An undamped LC over 1e4 s at steps of at most 1e-5 s: 1e9 steps, far longer than any test.
ENDLESS = "* endless\nL1 n1 0 1\nC1 n1 0 1\nI1 0 n1 DC 1\n.tran 1e-3 1e4 0 1e-5 uic\n.end\n"


def square_or_die(payload):
    """Work for the tests (module level, so that worker processes import it by name)."""
    n, folder, parent = payload
    marker = Path(folder) / f"died-{n}"
    if os.getpid() == parent:
        if n == 5:
            os.kill(parent, signal.SIGTERM)     # run in this process: its own SIGTERM stops the loop
        return n * n
    if n == 3 and not marker.exists():
        marker.touch()
        os._exit(1)                 # dies on its first run only
    if n == 7:
        os._exit(1)                 # dies on every run
    return n * n


def square_swallowing_sigterm(payload):
    """Work that receives SIGTERM inside a block that swallows every exception, as Python does
    for a garbage-collector callback or a finalizer (where Dask's GC diagnosis met it)."""
    n, folder, parent = payload
    if n == 5:
        try:
            os.kill(parent, signal.SIGTERM)
            sum(range(1000))            # bytecode to run the handler on, inside the block
        except BaseException:           # noqa: BLE001 - the point: the handler's exception is lost
            pass
    return n * n


def square_or_endless(payload):
    """Group 2 runs a circuit that would outlast the test; the others are squares."""
    n, folder, parent = payload
    if n == 2:
        session().run(ENDLESS, None, None, timeout=600.0)
    return n * n


def _run(tmp_path, count, work=square_or_die, **kw):
    results, died = {}, []
    interrupted = execute(range(count), lambda n: (n, str(tmp_path), os.getpid()), work,
                          lambda n, r: results.__setitem__(n, r), died.append, **kw)
    return results, died, interrupted


def test_a_dead_worker_s_group_is_run_again_and_one_that_always_kills_it_fails_alone(tmp_path):
    """A pool dies whole, so the groups beside the culprit are retried, and a group that kills
    its worker on every attempt is run alone before it is given up: only it is lost."""
    results, died, interrupted = _run(tmp_path, 12, workers=2)
    assert not interrupted and died == [7]
    assert results == {n: n * n for n in range(12) if n != 7}       # each handed over once (a dict)
    assert (tmp_path / "died-3").exists()
    assert ATTEMPTS >= 2


def test_sigterm_in_this_process_stops_the_loop_and_keeps_every_finished_group(tmp_path):
    """In this process the groups run on PIPELINE threads: SIGTERM (sent from group 5) stops the
    loop, the groups in flight finish, and every finished group is handed over, in order from 0."""
    before = signal.getsignal(signal.SIGTERM)
    results, died, interrupted = _run(tmp_path, 5 + 3 + PIPELINE, workers=1, in_process=True)
    assert interrupted and died == []
    assert set(range(6)) <= set(results) <= set(range(5 + PIPELINE))
    assert results == {n: n * n for n in range(len(results))}
    assert signal.getsignal(signal.SIGTERM) is before       # the caller's handler is back


def test_sigterm_whose_exception_is_swallowed_still_stops_the_loop(tmp_path):
    """The handler's exception can be lost; its record is not: the loop stops at its next look,
    after the group it was running, and the record is consumed (a later batch runs whole). The
    handler runs in the thread that runs the group only without the pipeline's threads."""
    results, died, interrupted = _run(tmp_path, 5 + 3, work=square_swallowing_sigterm, workers=1, in_process=True,
                                      pipeline=1)
    assert interrupted and results == {n: n * n for n in range(6)} and died == []
    results, died, interrupted = _run(tmp_path, 3, workers=1, in_process=True)
    assert not interrupted and results == {n: n * n for n in range(3)}


def test_a_command_whose_sigterm_was_swallowed_ends_interrupted_and_leaves_no_record(tmp_path, monkeypatch):
    """A command during which SIGTERM's exception was lost ends with exit 130 all the same, and
    the record goes with it: a batch run later in the same process runs whole."""
    from analogy.cli import commands
    from analogy.errors import EXIT_INTERRUPTED
    from analogy.processes import stop_requests

    def swallowed(args):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            sum(range(1000))
        except BaseException:           # noqa: BLE001 - lost, as in a finalizer
            pass
        return 0
    monkeypatch.setitem(commands._COMMANDS, "scenes", swallowed)
    assert commands.main(["scenes"]) == EXIT_INTERRUPTED
    assert not stop_requests.asked()
    results, died, interrupted = _run(tmp_path, 3, workers=1, in_process=True)
    assert not interrupted and results == {n: n * n for n in range(3)}


@pytest.mark.ngspice
@pytest.mark.parametrize("stop", ["ctrl-c", "sigterm record"])
def test_a_stop_in_this_process_halts_the_running_circuit_and_keeps_every_finished_group(tmp_path, stop):
    """Groups 0, 1, 3 and 4 finish beside group 2's endless circuit; a Ctrl-C, or a SIGTERM
    whose exception was lost (only its record set), stops the loop: the circuit is halted and
    its group dropped, the others are kept, and neither record is left behind."""
    asked = _thread.interrupt_main if stop == "ctrl-c" else stop_requests.ask
    # Python's own Ctrl-C handler, which interrupt_main calls: a shell starts a background job
    # with SIGINT ignored, and Python then installs none
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(1.0, asked)
    timer.start()
    try:
        results, died, interrupted = _run(tmp_path, 5, work=square_or_endless, workers=1, in_process=True)
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, before)
    assert interrupted and died == []
    assert results == {n: n * n for n in (0, 1, 3, 4)}
    assert not halt_requests.asked() and not stop_requests.asked()
    data = session().run("* after\nR1 n1 0 1\nC1 n1 0 1\nI1 0 n1 DC 1\n.tran 0.01 1 uic\n.end\n", ["n1"])
    assert abs(data["n1"][-1] - (1 - 2.718281828459045 ** -data["time"][-1])) <= 1e-3     # reltol 1e-3, 1 V


def switch_interval(payload):
    """Work that reports the interpreter's switch interval it runs under."""
    return sys.getswitchinterval()


def test_groups_on_threads_run_at_the_short_switch_interval_which_is_restored_after(tmp_path):
    """ngspice's callbacks take the GIL from the thread running Python: while groups run on
    threads here, that thread hands it over at least every SWITCH_INTERVAL; before and after,
    the interpreter's own interval stands, a stop included."""
    before = sys.getswitchinterval()
    results, _, interrupted = _run(tmp_path, 4, switch_interval, workers=1, in_process=True)
    # the interpreter keeps the interval in whole microseconds (0.0001 reads back as 9.999999999999999e-05)
    assert not interrupted and {round(v * 1e6) for v in results.values()} == \
        {round(min(before, executor.SWITCH_INTERVAL) * 1e6)}
    assert sys.getswitchinterval() == before
    results, _, interrupted = _run(tmp_path, 8, square_or_die, workers=1, in_process=True)
    assert interrupted and sys.getswitchinterval() == before            # group 5 sent SIGTERM
