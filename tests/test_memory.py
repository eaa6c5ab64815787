"""Memory: thousands of in-process SPICE runs leave resident memory and ngspice's buffers flat."""

import os
import subprocess
import sys

import pytest

from analogy.diagnostics.memory import memory_per_run
from analogy.solvers.quiet_ngspice import quiet_session
from analogy.solvers.spice import session

pytestmark = [pytest.mark.ngspice, pytest.mark.slow]


def test_two_thousand_runs_grow_resident_memory_by_at_most_half_a_kilobyte_each():
    # ngspice's leak was per command, not per time point, so the fast preset shows it as well
    # as the accurate one, in a few seconds.
    result = memory_per_run(runs=2_000, preset="fast", warmup=200)
    assert result.kb_per_run <= 0.5, str(result)


def test_the_library_keeps_no_printed_lines_between_runs():
    result = memory_per_run(runs=50, preset="fast", warmup=0)
    assert session()._ng.lines == [] and result.buffered_lines == 0


def test_two_thousand_ode_runs_at_fast_grow_resident_memory_by_at_most_a_tenth_of_a_kilobyte_each():
    # The fast preset's LSODA: scipy's LSODA class keeps 0.78 kB per call (scipy 1.17), which
    # this bound would catch eightfold; odeint's LSODA keeps nothing. One page over the runs
    # is 0.002 kB each.
    result = memory_per_run(runs=2_000, preset="fast", warmup=200, solver="ode")
    assert result.kb_per_run <= 0.1, str(result)


def test_freed_arrays_are_reused_without_new_page_faults():
    # Fresh interpreters: numpy temporaries of 240 kB (59 pages each, past glibc's mapping
    # threshold of 128 kB), several alive at once, made and freed 400 times. Kept for reuse,
    # they fault no page again; mapped afresh, they fault thousands.
    code = (
        "import resource, sys, numpy as np\n"
        "from analogy.heap import retain_freed_memory\n"
        "if sys.argv[1] == 'keep' and not retain_freed_memory(): print('none'); raise SystemExit\n"
        "a = np.random.rand(100, 2, 150)\n"
        "for _ in range(10): b = np.exp(a) * a + np.sin(a) * a + np.cos(a) * np.tanh(a)\n"
        "f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt\n"
        "for _ in range(400): b = np.exp(a) * a + np.sin(a) * a + np.cos(a) * np.tanh(a)\n"
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)\n")

    def faults(mode):
        return subprocess.run([sys.executable, "-c", code, mode], capture_output=True, text=True,
                              check=True).stdout.strip()
    kept = faults("keep")
    if kept == "none":
        pytest.skip("the C library is not glibc: its own allocation policy stays")
    default = int(faults("default"))
    assert int(kept) < 400, f"{kept} page faults over 400 loops, where each mapped temporary faults 59"
    if default < 4000:
        pytest.skip(f"this C library reuses these arrays by itself ({default} faults): nothing to compare")
    assert int(kept) * 10 < default


def test_two_thousand_runs_in_the_quiet_library_grow_resident_memory_by_at_most_half_a_kilobyte_each():
    # The quiet copy frees its circuits as the talking one does (destroy all, remcirc, NULL).
    def resident_kb():
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1024
    text = "* rc\nI1 0 n1 DC 1\nR1 n1 0 1\nC1 n1 0 1\n.tran 0.01 1 uic\n.end\n"
    quiet = quiet_session()
    for _ in range(200):
        quiet.run(text, None, {})
    before = resident_kb()
    for _ in range(2000):
        quiet.run(text, None, {})
    assert (resident_kb() - before) / 2000 <= 0.5
