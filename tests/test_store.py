"""The results store under faults: a damaged file, a tampered manifest, a full disk, two writers and
sweeps that ask too much each get one sentence naming what to do, and nothing stored is lost."""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from analogy.batch.store import read
from analogy.cli import main
from sweep_text import HEAD, sweep_text

pytestmark = pytest.mark.ngspice

SWEEP = sweep_text(60)


@pytest.fixture(scope="module")
def stored(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("store")
    (folder / "s.toml").write_text(SWEEP)
    assert main(["batch", str(folder / "s.toml"), "-o", str(folder / "base"), "--no-progress"]) == 0
    return folder


def _part(d: Path) -> Path:
    return sorted(d.glob("part-*.parquet"))[0]


def _flip(p: Path) -> None:
    b = bytearray(p.read_bytes())
    b[len(b) // 3] ^= 0xFF              # inside a data page, away from the footer
    p.write_bytes(bytes(b))


def _symlink(p: Path) -> None:
    p.rename(p.with_name("elsewhere.bin"))
    p.symlink_to(p.with_name("elsewhere.bin"))


DAMAGE = {
    "truncated part": (lambda d: _part(d).write_bytes(_part(d).read_bytes()[:100]), "is damaged"),
    "empty part": (lambda d: _part(d).write_bytes(b""), "is damaged"),
    "garbage part": (lambda d: _part(d).write_bytes(os.urandom(2000)), "is damaged"),
    "foreign schema": (lambda d: pq.write_table(pa.table({"x": [1, 2]}), _part(d)), "is not a part of a sweep store"),
    "symlink part": (lambda d: _symlink(_part(d)), "is a symlink"),
    "manifest list": (lambda d: (d / "_sweep.json").write_text("[]"), "is not a sweep manifest"),
    "manifest null": (lambda d: (d / "_sweep.json").write_text("null"), "is not a sweep manifest"),
    "manifest number": (lambda d: (d / "_sweep.json").write_text("3"), "is not a sweep manifest"),
    "manifest bad fields": (lambda d: (d / "_sweep.json").write_text(json.dumps({"key": 5, "scene": [1]})),
                            "is not a sweep manifest"),
}


@pytest.mark.parametrize("damage", list(DAMAGE))
@pytest.mark.parametrize("command", ["report", "resume"])
def test_a_damaged_store_is_named_in_one_sentence(damage, command, stored, tmp_path, capsys):
    folder = tmp_path / "store"
    shutil.copytree(stored / "base", folder, symlinks=True)
    spoil, said = DAMAGE[damage]
    spoil(folder)
    argv = ["batch", "report", str(folder)] if command == "report" else \
        ["batch", str(stored / "s.toml"), "-o", str(folder), "--no-progress"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and said in err and "Traceback" not in err


def test_a_flipped_data_byte_fails_its_page_checksum(stored, tmp_path, capsys):
    folder = tmp_path / "store"
    shutil.copytree(stored / "base", folder)
    _flip(_part(folder))
    assert main(["batch", "report", str(folder)]) == 2
    assert "is damaged" in capsys.readouterr().err


def test_a_truncated_pending_group_is_named_and_the_rest_is_kept(stored, tmp_path, capsys):
    folder = tmp_path / "store"
    shutil.copytree(stored / "base", folder)
    pending = folder / "_pending" / "g000000009999.arrow"
    pending.write_bytes(b"ARROW1\x00\x00trunc")
    assert main(["batch", str(stored / "s.toml"), "-o", str(folder), "--no-progress"]) == 2
    assert f"{pending} is damaged" in capsys.readouterr().err
    pending.unlink()
    assert len(read(folder)) == 60


def test_a_part_copied_in_twice_counts_its_scenes_once(stored, tmp_path, capsys):
    folder = tmp_path / "store"
    shutil.copytree(stored / "base", folder)
    shutil.copy(_part(folder), folder / "part-999999.parquet")
    assert len(read(folder)) == 60 and read(folder)["scene"].is_unique
    assert main(["batch", "report", str(folder)]) == 0
    assert "60 of 60 scenes stored" in capsys.readouterr().out


def test_a_full_disk_is_one_sentence_and_the_rerun_completes(stored, tmp_path):
    folder = tmp_path / "store"
    argv = [sys.executable, "-c", "import sys; from analogy.cli import main; sys.exit(main())",
            "batch", str(stored / "s.toml"), "-o", str(folder), "--no-progress"]

    def small_files():              # ulimit -f 4: no file past 2 kB (Python ignores SIGXFSZ)
        resource.setrlimit(resource.RLIMIT_FSIZE, (2048, 2048))
    full = subprocess.run(argv, capture_output=True, text=True, preexec_fn=small_files)
    assert full.returncode == 1, full.stderr
    assert full.stderr.count("\n") == 1 and "File too large" in full.stderr and "resume" in full.stderr
    again = subprocess.run(argv, capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    rows = read(folder)
    assert len(rows) == 60 and rows["scene"].is_unique


def test_a_second_writer_on_one_folder_is_refused(stored, tmp_path, capsys):
    from analogy.batch.runner import row_schema
    from analogy.batch.store import ResultStore
    from analogy.batch.sweep import load_sweep
    sweep = load_sweep(stored / "s.toml")
    first = ResultStore(tmp_path / "store", {**sweep.describe(), "isolated": False}, row_schema(sweep, ["spice", "exact"]))
    try:
        assert main(["batch", str(stored / "s.toml"), "-o", str(tmp_path / "store"), "--no-progress"]) == 2
        assert "another analogy batch is writing to" in capsys.readouterr().err
    finally:
        first.close()
    assert main(["batch", str(stored / "s.toml"), "-o", str(tmp_path / "store"), "--no-progress"]) == 0


def test_a_report_folder_that_is_a_symlink_out_of_the_store_is_refused(stored, tmp_path, capsys):
    folder = tmp_path / "store"
    shutil.copytree(stored / "base", folder)
    outside = tmp_path / "outside"
    outside.mkdir()
    (folder / "_report").symlink_to(outside)
    assert main(["batch", "report", str(folder)]) == 2
    assert "is a symbolic link" in capsys.readouterr().err and not list(outside.iterdir())


@pytest.mark.parametrize("design, said", [
    ('method = "grid"\n[sweep.axes]\ndd1 = [0, 1]', "axis dd1: not something a sweep can vary"),
    ('method = "grid"\n[sweep.axes]\nmessage = [0, 1]', "axis message: the results store has a column"),
    ('method = "grid"\n[sweep.axes]\nscene = [0, 1]', "axis scene: the results store has a column"),
    ('method = "grid"\n[sweep.axes]\nerror_spice = [0, 1]', "axis error_spice: the results store has a column"),
    ('method = "random"\ncount = 1000000000000\n[sweep.axes]\nq2 = [0.0, 1.0]', "more than 100,000,000"),
    ('method = "sobol"\ncount = 1099511627776\n[sweep.axes]\nq2 = [0.0, 1.0]', "more than 100,000,000"),
    ('method = "lhs"\ncount = 9223372036854775807\n[sweep.axes]\nq2 = [0.0, 1.0]', "more than 100,000,000"),
    ('method = "random"\ncount = 10\nseed = -1\n[sweep.axes]\nq2 = [0.0, 1.0]', "seed must be a whole number"),
    ('method = "grid"\n[sweep.axes]\nq2 = {low = 0, high = 1, count = 1000000000}', "values a grid axis may list"),
    ('method = "grid"\n[sweep.axes]\nq2 = {low = 0, high = 1, count = 73632978}', "values a grid axis may list"),
    ('method = "grid"\n[sweep.axes]\n' + "".join(f"{n} = {{low = 1, high = 2, count = 1000}}\n"
                                               for n in ("q1", "q2", "l1", "l2", "d1", "d2", "b1", "b2")),
     "more than 100,000,000"),
])
def test_a_sweep_that_asks_too_much_is_refused_before_a_store_exists(design, said, tmp_path, capsys):
    (tmp_path / "t.toml").write_text(HEAD + "[sweep]\n" + design + "\n")
    assert main(["batch", str(tmp_path / "t.toml"), "-o", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and said in err
    assert not (tmp_path / "out").exists()


def test_a_corrected_sweep_runs_in_the_folder_its_typo_was_refused_from(tmp_path, capsys):
    (tmp_path / "t.toml").write_text(HEAD + '[sweep]\nmethod = "grid"\n[sweep.axes]\ndd1 = [0.5, 1]\n')
    assert main(["batch", str(tmp_path / "t.toml"), "-o", str(tmp_path / "out"), "--no-progress"]) == 2
    (tmp_path / "t.toml").write_text(HEAD + '[sweep]\nmethod = "grid"\n[sweep.axes]\nd1 = [0.5, 1]\n')
    assert main(["batch", str(tmp_path / "t.toml"), "-o", str(tmp_path / "out"), "--no-progress"]) == 0
    assert (read(tmp_path / "out")["status"] == "ok").all()


def test_a_folder_of_invalid_scenes_only_is_taken_by_the_corrected_sweep(tmp_path, capsys):
    """Nothing was computed in it, so nothing is lost; a folder with one computed scene stays refused."""
    from sweep_text import HEAD

    def sweep(name, values):
        path = tmp_path / f"{name}.toml"
        path.write_text(HEAD + f'[sweep]\nmethod = "grid"\n[sweep.axes]\nl1 = {values}\n')
        return str(path)
    folder = str(tmp_path / "store")
    assert main(["batch", sweep("typo", "[0.0]"), "-o", folder, "--no-progress", "--workers", "1"]) == 1
    assert read(folder)["status"].tolist() == ["invalid"]
    capsys.readouterr()
    assert main(["batch", sweep("fixed", "[0.5, 0.0]"), "-o", folder, "--no-progress", "--workers", "1"]) == 1
    assert "held no computed scene of sweep arm" in capsys.readouterr().out
    assert read(folder)["status"].tolist() == ["ok", "invalid"]
    assert main(["batch", sweep("other", "[0.7]"), "-o", folder, "--no-progress", "--workers", "1"]) == 2
    assert "holds the results of another sweep" in capsys.readouterr().err
    assert read(folder)["status"].tolist() == ["ok", "invalid"]


def test_store_columns_are_pandas_friendly_and_an_older_store_still_reads(tmp_path):
    """The scene number is 'scene' (not 'index', which a DataFrame has), an ok row's message is
    null, and a part written with the old 'index' column reads as 'scene'."""
    import pyarrow.parquet as pq
    from analogy.batch.store import read as read_store
    from analogy.cli import main
    folder = tmp_path / "store"
    sweep = tmp_path / "s.toml"
    sweep.write_text('name = "s"\n[model]\nrobot = "serial2"\n[configuration]\nq = [0, 0.3]\n'
                     '[inputs]\nforces = [1, 0.5]\nt_stop = 1\n[sweep]\nmethod = "grid"\n'
                     '[sweep.axes]\nq2 = [0.1, 0.2, 0.3]\n')
    assert main(["batch", str(sweep), "-o", str(folder), "--no-progress"]) == 0
    frame = read_store(folder)
    assert "index" not in frame.columns and list(frame["scene"]) == [0, 1, 2]
    assert frame.loc[frame["status"] == "ok", "message"].isna().all()
    for part in folder.rglob("*.parquet"):
        table = pq.read_table(part)
        pq.write_table(table.rename_columns(["index" if n == "scene" else n for n in table.column_names]), part)
    again = read_store(folder)
    assert list(again["scene"]) == [0, 1, 2] and "index" not in again.columns


def test_a_pending_group_of_an_older_store_reads_with_the_scene_column(tmp_path):
    """A group an older run left pending (its 'index' column) is resumed as the store is read now."""
    import pyarrow as pa
    from analogy.batch.store import _read_ipc
    path = tmp_path / "g0.arrow"
    table = pa.table({"key": ["a", "b"], "index": pa.array([0, 1], pa.int64()), "status": ["ok", "ok"],
                      "message": pa.array([None, None], pa.string())})
    with pa.ipc.new_file(str(path), table.schema) as writer:
        writer.write_table(table)
    again = _read_ipc(path)
    assert again.column_names == ["key", "scene", "status", "message"]
    assert again.column("scene").to_pylist() == [0, 1]
