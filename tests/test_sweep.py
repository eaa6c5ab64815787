"""Sweeps: designs by index, scenes by axis, a store that holds each scene once however the run went."""

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analogy.batch import load_sweep, read, run_batch, run_sweep, sweep_from
from analogy.batch.designs import design_points, index_permutation
from analogy.cli import main
from analogy.errors import InputError
from analogy.scenes.builtin import scene
from sweep_text import HEAD

SWEEP = HEAD + """[sweep]
method = "{method}"
count = {count}
seed = 3
group_size = {group}
[sweep.axes]
q2 = [-3.0, 3.0]
d1 = [0.5, 3]
"""


def sweep_file(tmp_path, method="random", count=300, group=50) -> Path:
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP.format(method=method, count=count, group=group))
    return path


@pytest.mark.parametrize("count", [1, 2, 7, 1000, 4097])
def test_index_permutation_is_a_bijection_of_the_range(count):
    pi = index_permutation(np.arange(count), count, seed=11)
    assert sorted(pi.tolist()) == list(range(count))


def test_latin_hypercube_hits_every_stratum_of_every_axis_once():
    count = 500
    u = design_points("lhs", 0, count, count=count, seed=2, shape=(0, 0, 0))
    for axis in u.T:
        assert sorted(np.floor(axis * count).astype(int).tolist()) == list(range(count))


@pytest.mark.parametrize("method", ["random", "lhs", "sobol"])
def test_a_point_does_not_depend_on_how_the_run_is_divided(method):
    whole = design_points(method, 0, 9000, count=9000, seed=5, shape=(0, 0))
    parts = [design_points(method, a, b, count=9000, seed=5, shape=(0, 0)) for a, b in
             ((0, 1), (1, 4500), (4500, 8999), (8999, 9000))]
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    assert np.all((whole >= 0) & (whole < 1))


def test_a_grid_is_every_combination_once_last_axis_fastest():
    sw = sweep_from(scene("default"), {"q2": [0.0, 1.0, 2.0], "topology": ["serial", "parallel"]})
    assert len(sw) == 6
    got = [(s.q[1], s.topology) for s in sw.scenes()]
    assert got == [(q, t) for q in (0.0, 1.0, 2.0) for t in ("serial", "parallel")]


def test_a_scene_of_the_sweep_is_the_base_scene_with_its_axis_values():
    base = scene("default")
    sw = sweep_from(base, {"q2": [-1.0, 1.0], "d2": {"low": 0.5, "high": 2.0, "scale": "log"},
                           "rate1": [0.0, 0.5]}, method="lhs", count=40, seed=1)
    values = sw.values(sw.points(0, 40))
    assert np.all((values["d2"] >= 0.5) & (values["d2"] <= 2.0))
    for k, sc in enumerate(sw.scenes()):
        expected = base.replace(q=(base.q[0], values["q2"][k]), initial_rates=(values["rate1"][k], 0.0),
                                parameters={**base.parameter_values, "d2": values["d2"][k]})
        assert sc.key == expected.key


@pytest.mark.parametrize("axes, design, message", [
    ({"q3": [0.0, 1.0]}, {}, "has 2 joints"),
    ({"q2": [0.0, 1.0]}, {"method": "random"}, "needs count"),
    ({"q2": {"low": 0.0, "high": 1.0}}, {}, "grid over a range needs count"),
    ({"preset": ["fast", "sloppy"]}, {}, "unknown accuracy preset .sloppy."),
    ({"q2": [1.0, 0.0]}, {"method": "lhs", "count": 4}, "low <= high"),
])
def test_bad_sweeps_are_refused_with_one_sentence(axes, design, message):
    with pytest.raises(InputError, match=message):
        sweep_from(scene("default"), axes, **design)


@pytest.mark.ngspice
def test_the_store_holds_one_row_per_scene_with_the_in_memory_batch_errors(tmp_path):
    """The store path and the in-memory path solve the same groups: the same numbers, to the bit."""
    sw = load_sweep(sweep_file(tmp_path, count=300, group=100))
    run = run_sweep(sw, tmp_path / "store", workers=2, progress=False)
    assert run.solved == 300 and run.statuses == {"ok": 300}
    frame = pd.read_parquet(tmp_path / "store")
    assert len(frame) == 300 and frame["key"].is_unique and frame["scene"].is_unique
    frame = read(tmp_path / "store")
    scenes = sw.scenes()
    assert frame["key"].tolist() == [s.key for s in scenes]
    np.testing.assert_array_equal(frame["q2"], [s.q[1] for s in scenes])
    memory = run_batch(scenes, "fast", solvers=("spice", "exact"), group_size=100, workers=1)
    np.testing.assert_array_equal(frame["error_spice"], memory.solver_errors["spice"])
    assert frame["error_spice"].max() < 1e-3 and frame["error_exact"].isna().all()    # exact is the yardstick
    again = run_sweep(sw, tmp_path / "store", workers=2, progress=False)
    assert again.skipped == 300 and again.solved == 0


@pytest.mark.ngspice
def test_isolated_scenes_give_each_scene_its_result_alone(tmp_path):
    sw = load_sweep(sweep_file(tmp_path, count=4, group=4))
    run_sweep(sw, tmp_path / "store", workers=1, isolated=True, progress=False)
    frame = read(tmp_path / "store")
    alone = [run_batch([s], "fast", solvers=("spice", "exact"), workers=1).errors[0] for s in sw.scenes()]
    np.testing.assert_array_equal(frame["error_spice"], alone)


def _children(pid: int) -> list[int]:
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def _alive(pids) -> list[int]:
    alive = []
    for p in pids:
        try:
            state = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if state != "Z":
            alive.append(p)
    return alive


def _start_batch(path, store):
    return subprocess.Popen([sys.executable, "-m", "analogy", "batch", str(path), "-o", str(store),
                             "--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_for_groups(store: Path, proc, groups: int, timeout=120.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if len(list((store / "_pending").glob("g*[0-9].arrow"))) >= groups:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    raise AssertionError("the batch stored too few groups in time")


@pytest.mark.ngspice
@pytest.mark.slow
# SIGTERM's clean stop is also checked by test_orphans; its resume here is in the deep pass
@pytest.mark.parametrize("sig", [signal.SIGKILL, pytest.param(signal.SIGTERM, marks=pytest.mark.deep)])
def test_a_killed_then_resumed_sweep_holds_each_scene_once_with_uninterrupted_values(tmp_path, sig):
    path = sweep_file(tmp_path, count=3000, group=50)
    store = tmp_path / "killed"
    proc = _start_batch(path, store)
    _wait_for_groups(store, proc, 25)          # 25 of 60 groups stored: killed close to half way
    workers = _children(proc.pid)
    assert workers
    proc.send_signal(sig)
    proc.wait(timeout=30)
    if sig == signal.SIGTERM:
        assert proc.returncode == 130
        assert "run the same command to resume" in proc.stderr.read()
    time.sleep(5.0)
    assert _alive(workers) == [], "worker processes outlived their parent"
    # A worker killed mid-write may leave its temporary file; the resume removes it.
    assert main(["batch", str(path), "-o", str(store), "--no-progress"]) == 0
    assert not list(store.rglob("*.tmp"))
    assert main(["batch", str(path), "-o", str(tmp_path / "whole"), "--no-progress"]) == 0
    resumed, whole = read(store), read(tmp_path / "whole")
    assert len(resumed) == 3000 and resumed["scene"].is_unique and resumed["key"].is_unique
    pd.testing.assert_frame_equal(resumed.drop(columns=[c for c in resumed if c.startswith("seconds_")]),
                                  whole.drop(columns=[c for c in whole if c.startswith("seconds_")]))


@pytest.mark.ngspice
@pytest.mark.slow
def test_a_dask_local_cluster_gives_the_rows_of_local_processes(tmp_path):
    pytest.importorskip("distributed")
    path = sweep_file(tmp_path, count=400, group=50)
    assert main(["batch", str(path), "-o", str(tmp_path / "local"), "--no-progress"]) == 0
    assert main(["batch", str(path), "-o", str(tmp_path / "dask"), "--dask", "--workers", "2",
                 "--no-progress"]) == 0
    local, dask = read(tmp_path / "local"), read(tmp_path / "dask")
    seconds = [c for c in local if c.startswith("seconds_")]
    pd.testing.assert_frame_equal(local.drop(columns=seconds), dask.drop(columns=seconds))


@pytest.mark.ngspice
def test_a_folder_of_another_sweep_is_refused(tmp_path, capsys):
    """It holds computed scenes, which the other sweep would lose (an empty or all-invalid one is taken over)."""
    pytest.importorskip("pyarrow")
    assert main(["batch", str(sweep_file(tmp_path, count=10)), "-o", str(tmp_path / "s"), "--no-progress",
                 "--workers", "1"]) == 0
    path = sweep_file(tmp_path, count=11)
    assert main(["batch", str(path), "-o", str(tmp_path / "s")]) == 2
    assert "holds the results of another sweep" in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["batch", "SWEEP"], "-o DIR"),
    (["batch", "report"], "give the store"),
])
def test_batch_usage_errors_are_one_line_and_exit_2(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_a_scene_file_with_a_sweep_table_points_to_batch(tmp_path, capsys):
    assert main(["run", str(sweep_file(tmp_path))]) == 2
    assert "run it with analogy batch" in capsys.readouterr().err


@pytest.mark.ngspice
def test_batch_report_summarises_quantiles_axes_and_worst_scenes(tmp_path, capsys):
    path = sweep_file(tmp_path, count=200, group=100)
    assert main(["batch", str(path), "-o", str(tmp_path / "s"), "--no-progress"]) == 0
    assert main(["batch", "report", str(tmp_path / "s")]) == 0
    out = capsys.readouterr().out
    assert "| spice |" in out and "## Error against q2" in out and "worst scenes" in out
    for name in ("report.md", "report.html", "errors_by_axis.png", "error_histogram.png", "error_map.png"):
        assert (tmp_path / "s" / "_report" / name).stat().st_size > 0
    page = (tmp_path / "s" / "_report" / "report.html").read_text()
    # the page holds the markdown's tables, and the plots inline
    assert "<th>spice median</th>" in page and "<h2>Error against q2</h2>" in page
    assert page.count("data:image/png;base64,") == 3 and "https://" not in page
    assert len(pd.read_parquet(tmp_path / "s")) == 200       # the report leaves the dataset readable


@pytest.mark.ngspice
def test_trajectories_are_kept_downsampled_in_a_second_table(tmp_path):
    from analogy.batch import read_trajectories
    sw = load_sweep(sweep_file(tmp_path, count=6, group=3))
    run_sweep(sw, tmp_path / "s", workers=1, trajectories=11, progress=False)
    traj = read_trajectories(tmp_path / "s")
    assert set(traj["solver"]) == {"spice", "exact"}
    assert len(traj) == 6 * 2 * 11 and set(traj["key"]) == set(read(tmp_path / "s")["key"])
    one = traj[(traj["solver"] == "exact") & (traj["key"] == traj["key"].iloc[0])]
    np.testing.assert_allclose(one["t"], np.linspace(0.0, 10.0, 11))
    assert len(pd.read_parquet(tmp_path / "s")) == 6          # the second table is not in the rows
    assert [c for c in traj.columns if c not in ("key", "solver", "t")] == ["r1", "r2"]    # as in the CSV
    for part in (tmp_path / "s" / "_trajectories").glob("part-*.parquet"):          # as an older store wrote it
        pd.read_parquet(part).rename(columns={"r1": "rate1", "r2": "rate2"}).to_parquet(part)
    assert list(read_trajectories(tmp_path / "s").columns) == list(traj.columns)


@pytest.mark.ngspice
@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_groups_of_a_killed_worker_are_retried_and_every_scene_stored_once(tmp_path, sig):
    """SIGTERM ends the worker, as SIGKILL does: the batch is not interrupted (a forked worker
    does not keep the command's own SIGTERM handler)."""
    path = sweep_file(tmp_path, count=4000, group=50)
    store = tmp_path / "s"
    proc = _start_batch(path, store)
    _wait_for_groups(store, proc, 5)
    victim = _children(proc.pid)[0]
    os.kill(victim, sig)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0 and "Traceback" not in err, err
    frame = read(store)
    assert len(frame) == 4000 and frame["scene"].is_unique
    assert set(frame["status"]) == {"ok"}          # retried groups were solved, not lost


@pytest.mark.ngspice
def test_run_takes_several_scene_files_and_overrides_their_preset(tmp_path, capsys):
    for name, q in (("a", "0.3"), ("b", "-1.0")):
        (tmp_path / f"{name}.toml").write_text(
            f'[model]\nrobot = "serial2"\n[configuration]\nq = [0, {q}]\n[inputs]\nforces = [1, 0]\n'
            't_stop = 2\n[solvers]\nuse = ["spice", "exact"]\npreset = "accurate"\n')
    assert main(["run", str(tmp_path / "a.toml"), str(tmp_path / "b.toml"), "--preset", "fast",
                 "--solvers", "spice,ode"]) == 0
    out = capsys.readouterr().out
    assert out.count("== ") == 2 and "ode" in out and "fast" in out
    assert main(["run", str(tmp_path / "a.toml"), str(tmp_path / "missing.toml")]) == 2
    assert "a.toml" not in capsys.readouterr().out          # nothing ran before every file was read


def test_progress_is_plain_lines_when_stderr_is_not_a_terminal():
    import io

    from analogy.progress import Progress
    log = io.StringIO()
    bar = Progress(1000, initial=100, stream=log, every=0.0)
    bar.update(450)
    bar.close()
    lines = log.getvalue().splitlines()
    assert lines and all("of 1,000 scenes" in line and "\r" not in line for line in lines)
    assert lines[-1].startswith("550 of 1,000 scenes (55.0%)")


def test_a_sweep_scene_past_the_work_budget_is_stored_as_refused_and_the_others_run(tmp_path, capsys):
    from analogy.batch.store import read
    body = SWEEP.split("[sweep]")[0] + ('[sweep]\nmethod = "grid"\ngroup_size = 20\n[sweep.axes]\n'
                                         't_stop = [1, 10, 1e8]\nq2 = [0.1, 0.5]\n')
    (tmp_path / "s.toml").write_text(body)
    assert main(["batch", str(tmp_path / "s.toml"), "-o", str(tmp_path / "out"), "--no-progress"]) == 1
    rows = read(tmp_path / "out")
    late = rows["t_stop"] == 1e8
    assert (rows.loc[late, "status"] == "refused").all() and late.sum() == 2
    assert rows.loc[late, "message"].str.contains("more than the budget").all()
    assert (rows.loc[~late, "status"] == "ok").all() and (~late).sum() == 4


def test_a_resumed_sweep_exits_as_its_whole_store_says(tmp_path, capsys):
    """Exit codes judge the sweep, not one run: a resume that solves nothing new still exits 1
    while the store holds refused scenes, and says how many."""
    body = SWEEP.split("[sweep]")[0] + ('[sweep]\nmethod = "grid"\ngroup_size = 20\n[sweep.axes]\n'
                                         't_stop = [1, 1e8]\nq2 = [0.1, 0.5]\n')
    (tmp_path / "s.toml").write_text(body)
    args = ["batch", str(tmp_path / "s.toml"), "-o", str(tmp_path / "out"), "--no-progress"]
    assert main(args) == 1
    capsys.readouterr()
    assert main(args) == 1
    out, err = capsys.readouterr()
    assert "solved 0 of 4 scenes" in out and "the store holds 2 refused scenes" in err


@pytest.mark.parametrize("axis, word", [('force1 = ["stpe(2)", "step(1)"]', "force1"),
                                        ('dynamics = ["linear", "nonlinaer"]', "dynamics"),
                                        ('topology = ["serial", "paralel"]', "topology")])
def test_a_typo_among_an_axis_choices_is_refused_before_any_scene_runs(tmp_path, capsys, axis, word):
    (tmp_path / "s.toml").write_text(HEAD + f'[sweep]\nmethod = "grid"\n[sweep.axes]\n{axis}\nq2 = [0.1, 0.2]\n')
    assert main(["batch", str(tmp_path / "s.toml"), "-o", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"axis {word}:" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_sweep_axes_take_units_as_scene_files_do_and_judge_them(tmp_path, capsys):
    """"10 deg" on a revolute joint is 0.1745 rad and "500 ms" a t_stop of 0.5 s, stored in SI;
    a length on that joint, or a mass for a time, is one sentence before any scene runs."""
    def sweep(axes):
        (tmp_path / "s.toml").write_text(HEAD + f'[sweep]\nmethod = "grid"\n[sweep.axes]\n{axes}')
        return load_sweep(tmp_path / "s.toml")
    sw = sweep('q2 = ["10 deg", 0.5]\nt_stop = ["500 ms", 2]\nl1 = ["20 cm", 1]\n')
    values = sw.values(sw.points(0, sw.size))
    assert sorted(set(values["q2"])) == [np.deg2rad(10), 0.5] and sorted(set(values["t_stop"])) == [0.5, 2.0]
    assert sorted(set(values["l1"])) == [pytest.approx(0.2), 1.0]
    for axes, why in [('q2 = ["10 mm", 0.5]\n', "q2 is an angle"), ('t_stop = ["2 kg", 1]\n', "a unit of [mass]"),
                      ('l1 = ["2 kg", 1]\n', "l1 is a length")]:
        with pytest.raises(InputError, match=f"axis {axes.split()[0]}: .*{re.escape(why)}"):
            sweep(axes)
