"""Whatever starts processes owns them: a command killed with SIGKILL or SIGTERM leaves no process,
no library copy and no temporary file behind (checked by process tree, 5 s after the kill)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sweep_text import sweep_text

pytestmark = [pytest.mark.ngspice, pytest.mark.slow]

SWEEP = sweep_text(1_000_000)

SCRIPT = """
from analogy import run_batch
from analogy.scenes.builtin import scene
base = scene("default")
while True:
    run_batch([base.replace(q=(0.0, 0.001 * k)) for k in range(400)], "fast", group_size=20, workers=2)
"""

ANALOGY = [sys.executable, "-c", "import sys; from analogy.cli import main; sys.exit(main())"]


def _processes() -> dict[int, tuple[int, str]]:
    """Every live process: pid to (parent pid, start time), from /proc."""
    out = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        if fields[0] != "Z":
            out[int(entry.name)] = (int(fields[1]), fields[19])
    return out


def _tree(root: int) -> dict[int, str]:
    """*root* and its descendants, each with its start time (a pid may be reused later)."""
    procs = _processes()
    found, frontier = {}, [root]
    while frontier:
        pid = frontier.pop()
        if pid in procs:
            found[pid] = procs[pid][1]
            frontier += [child for child, (parent, _) in procs.items() if parent == pid]
    return found


def _alive(tree: dict[int, str]) -> list[int]:
    procs = _processes()
    return [pid for pid, start in tree.items() if pid in procs and procs[pid][1] == start]


CASES = {
    "batch": (ANALOGY + ["batch", "{dir}/sweep.toml", "-o", "{dir}/out", "--workers", "2"], 2),
    "batch --dask": (ANALOGY + ["batch", "{dir}/sweep.toml", "-o", "{dir}/out", "--workers", "2", "--dask"], 2),
    "throughput": (ANALOGY + ["throughput", "-n", "4000", "--baseline", "400", "--repeats", "50",
                              "--no-progress"], 1),
    "run_batch": ([sys.executable, "-c", SCRIPT], 2),
}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the process tree from /proc")
@pytest.mark.parametrize("case, sig", [
    # SIGKILL of the batch command, which skips every clean-up, in the default run; the rest
    # (6 s to 60 s each) in the deep pass
    pytest.param(case, sig, id=f"{case}-{sig.name}", marks=() if sig == signal.SIGKILL and case == "batch"
                 else pytest.mark.deep)
    for case in CASES for sig in (signal.SIGKILL, signal.SIGTERM)])
def test_a_killed_command_leaves_no_process_and_no_file(case, sig, tmp_path):
    argv, children = CASES[case]
    (tmp_path / "sweep.toml").write_text(SWEEP)
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp))
    proc = subprocess.Popen([a.format(dir=tmp_path) for a in argv], cwd=tmp_path, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        tree = _tree(proc.pid)
        while len(tree) < 1 + children and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.2)
            tree = _tree(proc.pid)
        assert len(tree) >= 1 + children, f"{case} never started its workers: {proc.stderr.read()!r}"
        time.sleep(1.0)                 # the workers are at work
        tree = _tree(proc.pid)          # everything it started by now
        proc.send_signal(sig)
        proc.wait(timeout=60)
        time.sleep(5.0)
        left = _alive(tree)
        assert not left, f"{case} after {sig.name}: {len(left)} of {len(tree)} processes alive: {left}"
        left = sorted(p.name for p in tmp.iterdir())
        if sig == signal.SIGKILL and left:
            # SIGKILL skips every clean-up: what a killed process left is only its own scratch
            # folders, and the next process that asks for one removes them
            assert all(name.split("-")[:2] == ["analogy", "dask"] and int(name.split("-")[2]) in tree
                       for name in left), left
            subprocess.run([sys.executable, "-c", "from analogy.processes import scratch_folder\n"
                            "with scratch_folder('dask'): pass"], env=env, check=True)
            left = sorted(p.name for p in tmp.iterdir())
        assert not left, f"{case} after {sig.name} left {left}"
    finally:
        for pid in _alive(_tree(proc.pid)) if proc.poll() is None else []:
            os.kill(pid, signal.SIGKILL)
        proc.kill()
        proc.wait()
