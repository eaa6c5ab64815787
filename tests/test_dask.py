"""A real distributed run: a scheduler and two workers as separate processes, one killed mid-sweep,
then the scheduler killed; addresses that cannot be a scheduler are refused in one sentence."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from analogy.cli import main
from sweep_text import sweep_text

pytest.importorskip("distributed")


ANALOGY = [sys.executable, "-c", "import sys; from analogy.cli import main; sys.exit(main())"]
DASK = shutil.which("dask", path=os.path.dirname(sys.executable)) or shutil.which("dask")


@pytest.mark.parametrize("address", ["not an address", "bogus://x:1", "http://x:1", "ucx://x:1", "inproc://x",
                                     "tls://127.0.0.1:1", "tcp://[::1", "/etc/passwd", "", "x:99999"])
def test_what_cannot_be_a_scheduler_address_is_refused_before_anything_runs(address, tmp_path, capsys):
    (tmp_path / "s.toml").write_text(sweep_text(10, "q2 = [-3.0, 3.0]\nd1 = [0.5, 3]\n"))
    assert main(["batch", str(tmp_path / "s.toml"), "-o", str(tmp_path / "out"), "--scheduler", address]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--scheduler needs a Dask scheduler address" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.deep
def test_a_listener_that_never_answers_is_refused_within_the_deadline(tmp_path, capsys):
    from analogy.cli.batch import CONNECT_SECONDS
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(8)
    held = []
    threading.Thread(target=lambda: held.extend(listener.accept() for _ in range(8)), daemon=True).start()
    (tmp_path / "s.toml").write_text(sweep_text(10, "q2 = [-3.0, 3.0]\nd1 = [0.5, 3]\n"))
    address = f"127.0.0.1:{listener.getsockname()[1]}"
    assert main(["batch", str(tmp_path / "s.toml"), "-o", str(tmp_path / "out"), "--scheduler", address]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"did not answer within {CONNECT_SECONDS + 5:g} s" in err
    listener.close()


def test_a_scheduler_without_workers_is_refused_instead_of_waited_on(tmp_path, capsys, monkeypatch):
    """Tasks sent to a scheduler no worker has joined would wait for ever: after the connection
    deadline the command says so in one sentence (the deadline shortened here to 2 s)."""
    from distributed import LocalCluster
    import analogy.cli.batch as batch
    monkeypatch.setattr(batch, "CONNECT_SECONDS", 2.0)
    (tmp_path / "s.toml").write_text(sweep_text(10))
    with LocalCluster(n_workers=0, processes=False, protocol="tcp://", dashboard_address=None) as empty:
        assert main(["batch", str(tmp_path / "s.toml"), "-o", str(tmp_path / "out"), "--scheduler",
                     empty.scheduler_address, "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "has no worker (none joined within 2 s)" in err


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(argv, log: Path) -> subprocess.Popen:
    return subprocess.Popen(argv, stdout=log.open("w"), stderr=subprocess.STDOUT, start_new_session=True)


def _rows(folder: Path) -> int:
    import pyarrow as pa
    count = 0
    for p in list((folder / "_pending").glob("g*[0-9].arrow")):
        try:
            with pa.memory_map(str(p)) as src:
                count += pa.ipc.open_file(src).read_all().num_rows
        except (OSError, pa.ArrowInvalid):
            pass
    return count


@pytest.mark.deep
@pytest.mark.ngspice
@pytest.mark.skipif(DASK is None, reason="needs the dask command (pip install 'analogy[dask]')")
def test_a_sweep_survives_a_killed_worker_and_resumes_after_a_killed_scheduler(tmp_path):
    from analogy.batch.store import read
    count = 4000
    (tmp_path / "s.toml").write_text(sweep_text(count, "q2 = [-3.0, 3.0]\nd1 = [0.5, 3]\n"))
    # the values of an uninterrupted run, on local processes
    assert subprocess.run(ANALOGY + ["batch", str(tmp_path / "s.toml"), "-o", str(tmp_path / "plain"),
                                     "--no-progress"], capture_output=True).returncode == 0
    plain = read(tmp_path / "plain").set_index("key")

    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = []
    try:
        def cluster():
            sched = _start([DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                           tmp_path / "scheduler.log")
            time.sleep(3)
            workers = [_start([DASK, "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard"],
                              tmp_path / f"worker{k}.log") for k in range(2)]
            procs.extend([sched, *workers])
            time.sleep(4)
            return sched, workers

        sched, workers = cluster()
        out = tmp_path / "out"
        run = _start(ANALOGY + ["batch", str(tmp_path / "s.toml"), "-o", str(out), "--scheduler", address,
                                "--no-progress"], tmp_path / "run1.log")
        procs.append(run)
        deadline = time.monotonic() + 120
        while _rows(out) < 200 and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        workers[0].send_signal(signal.SIGKILL)          # Dask reassigns its tasks
        while _rows(out) < 1200 and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        sched.send_signal(signal.SIGKILL)
        assert run.wait(timeout=120) == 1
        said = (tmp_path / "run1.log").read_text().strip().splitlines()
        assert "run the same command to resume" in said[-1] and said[-1].startswith("analogy: simulation failed")
        assert not [line for line in said if "Traceback" in line or "ERROR" in line], said
        first = len(read(out))
        assert 200 <= first < count

        for p in procs:
            p.kill()
        sched, workers = cluster()
        again = subprocess.run(ANALOGY + ["batch", str(tmp_path / "s.toml"), "-o", str(out), "--scheduler",
                                          address, "--no-progress"], capture_output=True, text=True, timeout=300)
        assert again.returncode == 0, again.stderr
        assert f"{first} already stored" in again.stdout
        rows = read(out)
        # every scene once, with the values of the uninterrupted run
        assert len(rows) == count and rows["scene"].is_unique and (rows["status"] == "ok").all()
        rows = rows.set_index("key").loc[plain.index]
        np.testing.assert_array_equal(rows["error_spice"].to_numpy(), plain["error_spice"].to_numpy())
        np.testing.assert_array_equal(rows["error_exact"].to_numpy(), plain["error_exact"].to_numpy())
    finally:
        for p in procs:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
            p.wait()
