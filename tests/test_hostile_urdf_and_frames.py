"""Nothing silent, nothing lost: URDFs a parser would read otherwise than checked, files without a
size, and animation pages that would hold fewer frames than asked."""

import os
import re
from pathlib import Path

import numpy as np
import pytest

from analogy import InputError
from analogy.cli import main
from analogy.model import urdf_file
from analogy.model.urdf import UrdfModel
from analogy.model.urdf_file import MAX_URDF_BYTES, read_urdf
from analogy.results import animation as animation_module
from analogy.results.animation import Motion
from hang_guard import finishes

_INERTIAL = ('<inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'
             '</inertial>')


def two_joints(nested: int = 0, before: bool = False, kind: str = "revolute") -> str:
    """A two-joint arm; *nested* elements inside a <gazebo> after its first joint (or before both)."""
    links = "".join(f'<link name="{n}">{_INERTIAL}</link>' for n in ("base", "upper", "fore"))
    joint = [f'<joint name="{n}" type="{kind}"><parent link="{p}"/><child link="{c}"/>'
             f'<origin xyz="0.1 0 0"/><axis xyz="0 0 1"/></joint>' for n, p, c in
             (("q1", "base", "upper"), ("q2", "upper", "fore"))]
    deep = "<gazebo>" + "<a>" * nested + "</a>" * nested + "</gazebo>" if nested else ""
    body = deep + links + "".join(joint) if before else links + joint[0] + deep + joint[1]
    return f'<robot name="arm">{body}</robot>'


def refused(capsys, *args) -> str:
    """Run the CLI in process; return its one stderr line after checking exit code 2."""
    code = finishes(lambda: main(list(args)))
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("analogy: error: ") and "Traceback" not in err, err
    return lines[0]


def write(tmp_path, content, name="robot.urdf") -> str:
    path = tmp_path / name
    (path.write_bytes if isinstance(content, bytes) else path.write_text)(content)
    return str(path)


# deep nesting: lxml, which builds the robot, stops at 256 levels and drops the rest silently

@pytest.mark.parametrize("before", [False, True])
def test_nesting_deeper_than_the_builder_reads_is_refused(tmp_path, capsys, before):
    message = refused(capsys, "netlist", "--urdf", write(tmp_path, two_joints(300, before)))
    assert "nests elements more than 256 deep" in message


def test_nesting_the_builder_reads_keeps_every_joint():
    # robot, gazebo and 254 <a>: 256 levels, the deepest read whole
    assert UrdfModel(two_joints(254)).joint_names == ("q1", "q2")
    with pytest.raises(InputError, match="more than 256 deep"):
        UrdfModel(two_joints(255))


def test_a_joint_the_builder_loses_is_named_not_dropped(monkeypatch):
    """Past the depth check, whatever else the recovering parser skips is still said."""
    monkeypatch.setattr(urdf_file, "_MOST_DEPTH", 10_000)
    with pytest.raises(InputError, match="joint q2 is lost by its parser"):
        urdf_file.parse_urdf(two_joints(300))


def test_a_robot_without_a_movable_joint_is_one_sentence(tmp_path, capsys):
    message = refused(capsys, "netlist", "--urdf", write(tmp_path, two_joints(kind="fixed")))
    assert "the URDF has no movable joint" in message


# encodings: the DTD check reads the text both parsers read, or the file is refused

def test_utf16_without_a_byte_order_mark_cannot_carry_a_dtd_past_the_check(tmp_path, capsys):
    text = '<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY n "q1">]>' + two_joints()
    for codec in ("utf-16-le", "utf-16-be"):
        assert "NUL characters (is it UTF-16?)" in refused(
            capsys, "netlist", "--urdf", write(tmp_path, text.encode(codec)))
    with pytest.raises(InputError, match="NUL characters"):
        UrdfModel(text.encode("utf-16-le").decode("utf-8"))


@pytest.mark.parametrize("declared", ["UTF-7", "utf-16", "ISO-8859-1", "ebcdic-cp-us"])
def test_an_encoding_other_than_utf8_is_refused_in_one_sentence(tmp_path, capsys, declared):
    for quote in ('"', "'"):
        text = f"<?xml version='1.0' encoding = {quote}{declared}{quote} ?>\n" + two_joints()
        message = refused(capsys, "netlist", "--urdf", write(tmp_path, text))
        assert f"declares the encoding {declared!r}" in message


@pytest.mark.parametrize("declared", ["UTF-8", "utf8", "US-ASCII"])
def test_utf8_and_ascii_declarations_are_read(declared):
    text = f'<?xml version="1.0" encoding="{declared}"?>\n' + two_joints()
    assert UrdfModel(text).joint_names == ("q1", "q2")


def test_a_file_that_is_not_utf8_is_one_sentence(tmp_path, capsys):
    latin = two_joints().replace('name="arm"', 'name="bra\xe7o"').encode("latin-1")
    assert "is not UTF-8 text" in refused(capsys, "netlist", "--urdf", write(tmp_path, latin))
    bom16 = two_joints().encode("utf-16")
    assert "is not UTF-8 text (byte 0 is not)" in refused(capsys, "netlist", "--urdf", write(tmp_path, bom16))


def test_a_utf8_file_reads_as_before(tmp_path):
    text = "\ufeff" + two_joints().replace("><", ">\r\n<").replace('name="arm"', 'name="braço"')
    read = read_urdf(write(tmp_path, text.encode("utf-8")))
    assert read == text.replace("\r\n", "\n") and UrdfModel(read).name == "braço"


# files without a size: devices, pipes, FIFOs

def test_a_device_is_read_only_up_to_the_limit(capsys):
    if not os.path.exists("/dev/zero"):
        pytest.skip("no /dev/zero")
    assert f"is larger than {MAX_URDF_BYTES:,} bytes" in refused(capsys, "netlist", "--urdf", "/dev/zero")


def test_a_regular_file_past_the_limit_is_refused(tmp_path, capsys):
    path = write(tmp_path, two_joints() + " " * MAX_URDF_BYTES)
    assert "is larger than" in refused(capsys, "netlist", "--urdf", path)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_without_a_writer_does_not_block(tmp_path, capsys):
    fifo = tmp_path / "robot.urdf"
    os.mkfifo(fifo)
    assert "--urdf" in refused(capsys, "netlist", "--urdf", str(fifo))


@pytest.mark.skipif(not hasattr(os, "pipe"), reason="no pipes here")
def test_a_pipe_is_read_to_its_end():
    read, written = os.pipe()
    with os.fdopen(written, "w") as end:
        end.write(two_joints())
    try:
        assert read_urdf(f"/proc/self/fd/{read}" if Path("/proc/self/fd").is_dir() else f"/dev/fd/{read}") \
            == two_joints()
    finally:
        os.close(read)


# animation pages: every frame asked for is in the page, or one sentence

def rails(frames: int) -> Motion:
    t = np.linspace(0.0, 1.0, frames)
    v = np.column_stack([np.sin(2 * np.pi * t), np.cos(2 * np.pi * t)])
    return Motion("rails", t, v, ["n1", "n2"], t, None, np.cumsum(v, axis=0) / frames)


def embedded(page: str) -> int:
    return len(re.findall(r'^\s*frames\[\d+\] = "data:image/', page, flags=re.MULTILINE))


def test_a_page_keeps_every_frame_whatever_matplotlibs_embed_limit(tmp_path, monkeypatch):
    import matplotlib
    # 0.05 MB holds two or three frames of this figure: to_jshtml would drop the rest
    monkeypatch.setitem(matplotlib.rcParams, "animation.embed_limit", 0.05)
    shown = rails(12)
    assert embedded(shown.save(tmp_path / "rails.html").read_text()) == 12
    assert embedded(shown.to_jshtml()) == 12


def test_a_page_past_the_stated_maximum_is_refused_not_cut(tmp_path, monkeypatch):
    monkeypatch.setattr(animation_module, "_MOST_PAGE_MB", 0.05)
    with pytest.raises(InputError, match=r"a page of 12 frames would embed more than 0.05 MB \(only \d fit\)"):
        rails(12).save(tmp_path / "rails.html")
    assert not (tmp_path / "rails.html").exists()


def test_animate_writes_every_frame_it_says(tmp_path, capsys, monkeypatch):
    import matplotlib
    monkeypatch.setitem(matplotlib.rcParams, "animation.embed_limit", 0.05)
    page = tmp_path / "a.html"
    assert main(["animate", "--robot", "serial3", "--solver", "ode", "--frames", "10", "-o", str(page)]) == 0
    assert "wrote" in capsys.readouterr().out
    assert embedded(page.read_text()) == 10


def test_animate_past_the_maximum_is_one_sentence(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(animation_module, "_MOST_PAGE_MB", 0.05)
    message = refused(capsys, "animate", "--robot", "serial3", "--solver", "ode", "--frames", "10",
                      "-o", str(tmp_path / "a.html"))
    assert "a page of 10 frames would embed more than 0.05 MB" in message


@pytest.mark.deep               # about a minute: 300 frames drawn
def test_three_hundred_frames_past_twenty_megabytes_are_all_in_the_page(tmp_path, capsys):
    page = tmp_path / "a.html"
    assert main(["animate", "--robot", "serial3", "--frames", "300", "-o", str(page)]) == 0
    assert "300 frames," in capsys.readouterr().out
    assert page.stat().st_size > 20 * 1024 * 1024 and embedded(page.read_text()) == 300
