"""The ``analogy batch`` command: a sweep into a store on local processes or Dask, or a store's report."""

from __future__ import annotations

import logging
import os
import sys
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Iterator

from ..errors import EXIT_ACCURACY, EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, InputError, SimulationError
from .outputs import check_folder
from .scene_options import preset_option
from ..processes import scratch_folder

__all__ = ["batch_command", "batch_options", "dask_executor", "scheduler_address", "CONNECT_SECONDS"]

#: How long a scheduler has to answer: Dask's own timeout covers the TCP connection, not a
#: listener that accepts and never speaks, so the whole handshake gets this deadline too.
CONNECT_SECONDS = 15.0

def batch_options(sub) -> None:
    """Add the ``batch`` subcommand and its options to the subparsers *sub*.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``analogy`` command's subparsers.
    """
    p = sub.add_parser("batch", help="run a sweep file's scenes into a resumable Parquet store; "
                                     "'analogy batch report DIR' summarises one",
                       usage="analogy batch SWEEP.toml -o DIR [options]\n       analogy batch report DIR [-o FOLDER]",
                       description="Run a sweep into its store (rerun the same command to resume), or summarise "
                                   "a store: 'report DIR' writes report.md and its plots into DIR/_report "
                                   "(or -o FOLDER) and prints the summary.")
    p.add_argument("sweep_file", metavar="SWEEP.toml", help="a scene file with a [sweep] table, or 'report'")
    p.add_argument("report_dir", nargs="?", metavar="DIR", help="with 'report': the store to summarise")
    p.add_argument("-o", "--output", metavar="DIR", help="the results store (required for a run; for a "
                   "report, the folder for report.md and its plots, default DIR/_report)")
    p.add_argument("--workers", type=int, default=2, help="local worker processes (default 2)")
    p.add_argument("--dask", action="store_true", help="run on a Dask LocalCluster of --workers processes")
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on the Dask cluster at ADDRESS")
    p.add_argument("--isolated", action="store_true",
                   help="one ngspice run per scene: each error exactly as alone, but slower")
    p.add_argument("--trajectories", type=int, default=0, metavar="N",
                   help="also store N evenly spaced points of every solver's joint rates")
    preset_option(p, None, "override the sweep's accuracy preset (a name or a tolerance)")
    p.add_argument("--solvers", help="override the sweep's solvers, e.g. spice,exact")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (plain lines stay)")


def scheduler_address(text: str) -> str:
    """*text* as a Dask scheduler address ``tcp://host:port``, or one sentence saying what is wrong.

    Parameters
    ----------
    text : str
        ``tcp://host:port`` or ``host:port``.
    """
    address = text.strip()
    scheme, sep, place = address.partition("://")
    if not sep:
        scheme, place = "tcp", address
    host, colon, port = place.rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if scheme != "tcp" or not colon or not host or not port.isdigit() or not 0 < int(port) < 65536 \
            or any(c in host for c in "/[]@ \\") or len(address) > 300:
        shown = repr(text) if len(text) < 80 else "the one given"
        raise InputError(f"--scheduler needs a Dask scheduler address like tcp://127.0.0.1:8786, got {shown}"
                         + (" (only tcp:// is set up here: tls needs certificates, the other protocols their own libraries)"
                            if sep and scheme != "tcp" else ""))
    return f"tcp://{place}"


def _connect(client_class, address: str):
    """A client of the scheduler at *address*, or one sentence once :data:`CONNECT_SECONDS` pass."""
    import threading
    out: dict = {}

    def connect():
        try:
            out["client"] = client_class(address, timeout=f"{CONNECT_SECONDS:g}s")
        except Exception as exc:        # noqa: BLE001 - handed back as one sentence
            out["error"] = exc
    worker = threading.Thread(target=connect, daemon=True)
    worker.start()
    worker.join(CONNECT_SECONDS + 5)
    if worker.is_alive():
        raise InputError(f"the Dask scheduler at {address} did not answer within {CONNECT_SECONDS + 5:g} s")
    if "error" in out:
        exc = out["error"]
        detail = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise InputError(f"cannot reach the Dask scheduler {address}: {detail}") from None
    return out["client"]


@contextmanager
def dask_executor(workers: int, scheduler: str | None = None) -> Iterator[object]:
    """A ``concurrent.futures`` executor over Dask: the cluster at *scheduler*, or a LocalCluster.

    The local cluster has *workers* processes of one thread each, since ngspice's
    shared library is not thread-safe.

    Parameters
    ----------
    workers : int
        Worker processes of a local cluster.
    scheduler : str, optional
        Address of a running scheduler.
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise InputError("Dask is not installed: pip install 'analogy[dask]'") from None
    cluster = None
    scratch = ExitStack()
    # a lost worker or scheduler is reported here in one sentence, not by Dask's own tracebacks
    for name in list(logging.root.manager.loggerDict):
        if name.split(".")[0] in ("distributed", "tornado", "asyncio"):
            quiet = logging.getLogger(name)
            scratch.callback(quiet.setLevel, quiet.level)
            quiet.setLevel(logging.CRITICAL + 1)
    try:
        try:
            if scheduler is None:
                # the cluster's spill and lock files in a folder of ours, so that a stop leaves nothing in /tmp
                import dask
                folder = str(scratch.enter_context(scratch_folder("dask")))
                scratch.enter_context(dask.config.set({"temporary-directory": folder}))
                cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=logging.ERROR, local_directory=folder)
                scratch.callback(cluster.close)
                client = Client(cluster)
            else:
                client = _connect(Client, scheduler_address(scheduler))
                scratch.callback(client.close)
                try:        # a scheduler without workers would take the tasks and wait in silence
                    client.wait_for_workers(1, timeout=CONNECT_SECONDS)
                except TimeoutError:
                    raise InputError(f"the Dask scheduler {scheduler} has no worker (none joined within "
                                     f"{CONNECT_SECONDS:g} s): start one with 'dask worker {scheduler}'") from None
        except (OSError, TimeoutError) as exc:
            raise InputError(f"cannot reach the Dask scheduler {scheduler}: {exc}") from None
        except RuntimeError as exc:
            raise SimulationError(f"the Dask cluster did not start: {exc}") from None
    except BaseException:           # SIGTERM or Ctrl-C while the cluster starts: nothing left behind
        scratch.close()
        raise
    try:
        yield client.get_executor()
    finally:
        client.close()
        scratch.close()             # the cluster, then its folder and the loggers' levels


def batch_command(args) -> int:
    """Run ``analogy batch`` from parsed arguments; return the exit code.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed arguments.
    """
    if args.sweep_file == "report":
        return _report(args)
    if args.report_dir is not None:
        raise InputError(f"unexpected argument {args.report_dir!r}: give one sweep file and -o DIR")
    if args.output is None:
        raise InputError("give the results folder with -o DIR")
    if args.workers < 1:
        raise InputError("--workers must be at least 1")
    from ..batch.runner import run_sweep, with_overrides
    from ..batch.sweep import load_sweep
    solvers = None
    if args.solvers is not None:
        solvers = tuple(dict.fromkeys(s.strip() for s in args.solvers.split(",") if s.strip()))
        if not solvers:
            raise InputError("--solvers names no solver")
    sweep = with_overrides(load_sweep(args.sweep_file), args.preset, solvers)
    progress = False if args.no_progress else None
    if args.scheduler is not None:
        scheduler_address(args.scheduler)       # one sentence before anything runs
    if args.dask or args.scheduler is not None:
        with dask_executor(args.workers, args.scheduler) as executor:
            run = run_sweep(sweep, args.output, executor=executor, isolated=args.isolated,
                            trajectories=args.trajectories, progress=progress)
    else:
        run = run_sweep(sweep, args.output, workers=args.workers, isolated=args.isolated,
                        trajectories=args.trajectories, progress=progress)
    print(run.summary())
    if run.interrupted:
        print(f"analogy: interrupted: finished groups are stored in {args.output}; "
              "run the same command to resume", file=sys.stderr)
        return EXIT_INTERRUPTED
    print(f"stored in {args.output} (read it with pandas.read_parquet or 'analogy batch report {args.output}')")
    # the whole store is judged, earlier runs' rows too: a resumed sweep's exit is the sweep's
    if bad := {s: run.stored[s] for s in ("failed", "invalid", "refused", "worker-died") if run.stored.get(s)}:
        print("analogy: simulation failed: the store holds " + ", ".join(f"{v} {k}" for k, v in bad.items())
              + " scenes (their messages are in the store's message column)", file=sys.stderr)
        return EXIT_FAILED
    if run.stored.get("inaccurate"):
        print(f"analogy: accuracy: {run.stored['inaccurate']} scenes in the store are outside their preset's "
              "bound (status 'inaccurate')", file=sys.stderr)
        return EXIT_ACCURACY
    return EXIT_OK


def _report(args) -> int:
    from ..batch.report import batch_report
    if args.report_dir is None:
        raise InputError("give the store to report on: analogy batch report DIR")
    report = batch_report(args.report_dir)
    store = Path(os.path.abspath(args.report_dir))
    folder = Path(os.path.abspath(args.output)) if args.output else store / "_report"
    inside = folder.relative_to(store).parts if folder.is_relative_to(store) else None
    if inside:              # below the store, no part of the path may be a symlink out of it
        from ..scenes.paths import inside_folder
        inside_folder(store, str(Path(*inside, "report.md")))
    if inside is not None and (not inside or not inside[0].startswith("_")):
        raise InputError(f"a report inside the store {args.report_dir} goes in a folder whose name starts "
                         "with _ (the default is _report), so that the store stays a Parquet dataset")
    check_folder(folder, "the report")
    try:
        written = report.write(folder)
    except OSError as exc:
        raise InputError(f"cannot write the report: {exc}") from None
    print(report.summary())
    print("wrote " + ", ".join(str(p) for p in written))
    return EXIT_OK
