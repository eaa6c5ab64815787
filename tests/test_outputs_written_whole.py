"""Every output is written whole or not at all, inside its own folder: through a temporary file
beside it, renamed into place. A symlink at the path is replaced, never followed; a signal
mid-write leaves the old file; a path that cannot take a file is refused before any work in
one sentence; a failed write loses nothing else the command computed."""

import ast
import os
import signal
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from analogy.cli import main
from analogy.files import replaced, write_text
from hang_guard import finishes

PACKAGE = Path(__file__).resolve().parent.parent / "analogy"


def one_error(capsys, *args) -> str:
    """Run the CLI; check exit 2 with one ``analogy: error:`` line and no traceback; return it."""
    code = finishes(lambda: main(list(args)))
    err = capsys.readouterr().err
    lines = [line for line in err.strip().splitlines() if not line.startswith("analogy: warning")]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("analogy: error: ") and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("flag, name", [("netlist -o", "x.cir"), ("compare --csv", "x.csv"),
                                        ("compare --plot", "x.png"), ("animate -o", "x.gif"),
                                        ("animate --sheet", "x.png")])
def test_a_symlink_at_the_output_path_is_replaced_never_followed(tmp_path, flag, name):
    command, option = flag.split()
    out = tmp_path / "out"
    out.mkdir()
    outside = tmp_path / f"outside_{name}"
    (out / name).symlink_to(outside)
    extra = {"compare": ["--preset", "fast", "--solvers", "exact"],
             "animate": ["--frames", "4", "--solver", "exact"]}.get(command, [])
    if option == "--sheet":
        extra += ["-o", str(out / "a.gif")]
    assert main([command, option, str(out / name), *extra]) in (0, 3)
    assert not outside.exists() and not os.path.lexists(outside)
    assert (out / name).is_file() and not (out / name).is_symlink() and (out / name).stat().st_size > 0
    assert not [p for p in out.iterdir() if p.name.startswith(".")]        # no temporary file left behind


def test_a_kill_mid_write_leaves_the_old_file_whole(tmp_path):
    """SIGKILL runs no clean-up: the half-written temporary file is all it can leave, and the
    file at the path keeps its old content."""
    target = tmp_path / "result.csv"
    write_text(target, "old\n")
    child = textwrap.dedent(f"""
        import os, signal
        from analogy.files import replaced
        with replaced({str(target)!r}) as tmp:
            with open(tmp, "w") as fh:
                fh.write("half of the new")
                fh.flush()
                os.kill(os.getpid(), signal.SIGKILL)
    """)
    run = subprocess.run([sys.executable, "-c", child], capture_output=True, timeout=120)
    assert run.returncode == -signal.SIGKILL
    assert target.read_text() == "old\n"


def test_an_error_mid_write_leaves_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "netlist.cir"
    write_text(target, "old\n")
    with pytest.raises(KeyboardInterrupt):
        with replaced(target) as tmp:
            tmp.write_text("half")
            raise KeyboardInterrupt         # what SIGTERM becomes in the CLI
    assert target.read_text() == "old\n" and sorted(p.name for p in tmp_path.iterdir()) == ["netlist.cir"]


def test_a_new_file_has_the_mode_a_plain_open_gives(tmp_path):
    """mkstemp makes its file 0600; the renamed output has 0666 less the umask, as open() would."""
    mask = os.umask(0)
    os.umask(mask)
    path = write_text(tmp_path / "a.txt", "x")
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~mask


def test_a_device_is_written_in_place_and_stays_a_device(capsys):
    assert main(["netlist", "-o", os.devnull]) == 0
    assert stat.S_ISCHR(os.stat(os.devnull).st_mode)


def test_a_pipe_is_refused_before_any_work_instead_of_waiting_for_a_reader(tmp_path, capsys):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert "pipe" in one_error(capsys, "netlist", "-o", str(fifo))
    assert "pipe" in one_error(capsys, "compare", "--csv", str(fifo))


@pytest.mark.parametrize("args", [["netlist", "-o", "{long}.cir"], ["animate", "-o", "{long}.gif"],
                                  ["compare", "--csv", "{long}.csv"], ["draw", "-o", "{dir}", "--stem", "{name}"],
                                  ["report", "-o", "{long}"]])
def test_a_file_name_too_long_is_one_sentence(tmp_path, capsys, args):
    name = "a" * 300
    filled = [a.format(long=str(tmp_path / name), dir=str(tmp_path), name=name) for a in args]
    assert "too long" in one_error(capsys, *filled)


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_a_full_disk_on_one_output_loses_neither_the_table_nor_the_other_output(tmp_path, capsys):
    plot = tmp_path / "run.png"
    assert main(["compare", "--preset", "fast", "--csv", "/dev/full", "--plot", str(plot)]) == 2
    out, err = capsys.readouterr()
    assert "solver" in out and f"wrote {plot}" in out and plot.stat().st_size > 0
    assert err.strip() == "analogy: error: cannot write /dev/full (No space left on device)"


#: Writes that go elsewhere than a temporary path from :func:`analogy.files.replaced` or a
#: buffer in memory, each into a file it has just made in its own scratch folder.
SCRATCH_WRITES = {("solvers/gnucap.py", "path"), ("results/animation.py", "str(path)")}


def test_every_output_of_the_package_goes_through_analogy_files():
    """No module writes a file at its final path: a write_text, a savefig, an animation's save
    or an open for writing whose target is not a temporary path (``tmp``) or a buffer is a
    file a signal could leave half-written or a symlink could redirect."""
    found = set()
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.Call) or not node.args:
                continue
            f = node.func
            method = f.attr if isinstance(f, ast.Attribute) else None
            if method in ("write_text", "write_bytes"):
                target = ast.unparse(f.value)
            elif method == "savefig" or (method == "save" and ast.unparse(f.value) == "anim"):
                target = ast.unparse(node.args[0])
            elif getattr(f, "id", None) == "open" and len(node.args) > 1 and "w" in str(
                    getattr(node.args[1], "value", "")):
                target = ast.unparse(node.args[0])
            else:
                continue
            if target not in ("tmp", "buffer"):
                found.add((path.relative_to(PACKAGE).as_posix(), target))
    assert found == SCRATCH_WRITES
