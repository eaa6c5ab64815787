"""A URDF file read and checked before a parser builds a robot from it: size, encoding, DTD, nesting, numbers."""

from __future__ import annotations

import io
import os
import re
import warnings
from pathlib import Path
from typing import TYPE_CHECKING
from xml.etree import ElementTree

import numpy as np

from ..errors import InputError

if TYPE_CHECKING:
    import yourdfpy

__all__ = ["MAX_URDF_BYTES", "MOVING_JOINTS", "read_urdf", "parse_urdf", "transmissions", "urdf_number",
           "urdf_triple"]

#: A URDF larger than this is refused before it is parsed (the Panda's is 20 kB).
MAX_URDF_BYTES = 10_000_000
MOVING_JOINTS = {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic"}
#: The largest number a URDF may hold: M sums products m·l² and G products g·m·l, which stay
#: inside the floating-point range (1.8e308) below this.
_LARGEST = 1e100


def read_urdf(path) -> str:
    """The text of the URDF file at *path*, or one sentence.

    At most MAX_URDF_BYTES + 1 bytes are read from any file: a device such as /dev/zero has
    no size to check beforehand, and a pipe's is unknown until it ends.

    Parameters
    ----------
    path : str or Path
        The file.
    """
    p = Path(path)
    if "\x00" in str(p):
        raise InputError(f"{str(p)!r} contains a NUL byte, which no file name may hold", field="robot")
    try:
        # a FIFO without a writer would block the open itself: open without waiting, then read
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        with os.fdopen(fd, "rb") as file:
            if hasattr(os, "O_NONBLOCK"):
                os.set_blocking(fd, True)
            data = file.read(MAX_URDF_BYTES + 1)
    except FileNotFoundError:
        raise InputError(f"no URDF file {p}", field="robot") from None
    except OSError as exc:
        raise InputError(f"cannot read {p}: {exc.strerror or exc}", field="robot") from None
    if len(data) > MAX_URDF_BYTES:
        raise InputError(f"{p} is larger than {MAX_URDF_BYTES:,} bytes: not a URDF this reads", field="robot")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{p} is not UTF-8 text (byte {exc.start:,} is not): a URDF is read as UTF-8 "
                         "(convert it, e.g. with iconv)", field="robot") from None
    return text.replace("\r\n", "\n").replace("\r", "\n")     # as a text-mode read gives it


def urdf_triple(text: str | None, what: str, default=(0.0, 0.0, 0.0)) -> tuple:
    """Three finite numbers of at most 1e100 from a URDF attribute (*default* where it is absent), or one sentence.

    Parameters
    ----------
    text : str or None
        The attribute's text.
    what : str
        Where it is, for the sentence.
    default : tuple of float
        The value of an absent attribute.
    """
    if text is None:
        return default
    parts = text.split()
    try:
        values = tuple(float(x) for x in parts)
    except ValueError:
        raise InputError(f"{what} is not three numbers: {text!r}", field="robot") from None
    if len(values) != 3 or not all(abs(v) <= _LARGEST for v in values):
        raise InputError(f"{what} must be three finite numbers of at most 1e100, got {text!r}", field="robot")
    return values


def _check_document(root) -> None:
    """What the recovering parser would let through: the structure, names and numbers of the XML."""
    if root.tag != "robot" or not root.get("name"):
        raise InputError("not a URDF: its root element must be <robot name=\"...\">", field="robot")
    for kind in ("link", "joint"):
        seen: set = set()
        for e in root.findall(kind):
            name = e.get("name")
            if not name:
                raise InputError(f"a <{kind}> has no name", field="robot")
            if name in seen:
                raise InputError(f"two {kind}s are named {name!r}", field="robot")
            seen.add(name)
    if not any(j.get("type") in MOVING_JOINTS for j in root.findall("joint")):
        raise InputError("the URDF has no movable joint (revolute, continuous or prismatic): nothing to model",
                         field="robot")
    for link in root.findall("link"):
        for inertial in link.findall("inertial"):
            where = f"link {link.get('name')}"
            mass = inertial.find("mass")
            if mass is None or mass.get("value") is None:
                raise InputError(f"{where}: its <inertial> has no <mass value=...>", field="robot")
            inertia = inertial.find("inertia")
            missing = [a for a in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
                       if inertia is None or inertia.get(a) is None]
            if missing:
                raise InputError(f"{where}: its <inertia> has no {missing[0]} (all six are needed)", field="robot")
            for a in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
                urdf_number(inertia.get(a), f"{where}: {a}")
            urdf_number(mass.get("value"), f"{where}: mass")
            origin = inertial.find("origin")
            if origin is not None:
                urdf_triple(origin.get("xyz"), f"{where}: inertial origin xyz")
                urdf_triple(origin.get("rpy"), f"{where}: inertial origin rpy")
    for joint in root.findall("joint"):
        where = f"joint {joint.get('name')}"
        for end in ("parent", "child"):
            e = joint.find(end)
            if e is None or not e.get("link"):
                raise InputError(f"{where} has no <{end} link=...>", field="robot")
        origin = joint.find("origin")
        if origin is not None:
            urdf_triple(origin.get("xyz"), f"{where}: origin xyz")
            urdf_triple(origin.get("rpy"), f"{where}: origin rpy")
        axis = joint.find("axis")
        if axis is not None:
            urdf_triple(axis.get("xyz"), f"{where}: axis", (1.0, 0.0, 0.0))


#: Encodings a URDF may declare: both parsers then read the very text checked here.
_ENCODINGS = {"utf-8", "utf8", "us-ascii", "ascii"}
_DECLARATION = re.compile(r"\A\ufeff?<\?xml\s.*?\?>", re.DOTALL)
_DECLARED = re.compile(r"\sencoding\s*=\s*([\"'])([^\"']*)\1")
#: The deepest nesting of elements read (the root at depth 1): lxml, under yourdfpy, stops
#: there and recovers silently, dropping every element after it.
_MOST_DEPTH = 256


def _document_bytes(text: str) -> bytes:
    """The UTF-8 bytes both parsers read, once they can only be read as the checked text."""
    # a NUL is no XML character; "<\0" at the start makes a parser read UTF-16, past the DTD check
    if "\x00" in text:
        raise InputError("the URDF holds NUL characters (is it UTF-16?): a URDF is read as UTF-8", field="robot")
    if (declaration := _DECLARATION.match(text)) and "encoding" in declaration.group():
        declared = _DECLARED.search(declaration.group())
        name = declared.group(2) if declared else declaration.group()
        if name.lower() not in _ENCODINGS:
            raise InputError(f"the URDF declares the encoding {name!r}: a URDF is read as UTF-8 "
                             "(convert it and declare UTF-8)", field="robot")
    try:
        return text.encode("utf-8")
    except UnicodeEncodeError:
        raise InputError("the URDF's text holds an unpaired surrogate: it is not Unicode text",
                         field="robot") from None


def _deeper_than(root, most: int) -> bool:
    """Whether elements nest more than *most* deep (a loop: the tree may be deeper than Python's stack)."""
    stack = [(root, 1)]
    while stack:
        element, depth = stack.pop()
        if depth > most:
            return True
        stack.extend((child, depth + 1) for child in element)
    return False


def parse_urdf(text: str) -> "yourdfpy.Robot":
    """The robot yourdfpy builds from *text*, once the text is checked (UTF-8, no DTD, nesting its parser
    reads whole, the structure and numbers of a URDF); one sentence otherwise.

    Parameters
    ----------
    text : str
        The URDF.
    """
    data = _document_bytes(text)
    # no DTD: entities could expand without bound or read other files into the names
    if "<!DOCTYPE" in text or "<!ENTITY" in text:
        raise InputError("the URDF has a DTD (<!DOCTYPE or <!ENTITY>): URDF files need none", field="robot")
    try:
        root = ElementTree.fromstring(data)     # well-formed, before a recovering parser
    except ElementTree.ParseError as exc:
        raise InputError(f"not a readable URDF (malformed XML: {exc})", field="robot") from None
    if _deeper_than(root, _MOST_DEPTH):
        raise InputError(f"the URDF nests elements more than {_MOST_DEPTH} deep: its parser would drop "
                         "every element past that depth", field="robot")
    _check_document(root)
    try:
        import yourdfpy
    except ImportError:
        raise InputError("URDF robots need yourdfpy: pip install yourdfpy", field="robot") from None
    yourdfpy.urdf._logger.disabled = True      # its notes on a file are said here, in one sentence, or not at all
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            robot = yourdfpy.URDF.load(io.BytesIO(data), build_scene_graph=False, load_meshes=False,
                                       build_collision_scene_graph=False, load_collision_meshes=False).robot
    except Exception as exc:        # lxml's and yourdfpy's own errors: the file is not a URDF
        detail = " ".join(str(exc).split())[:160] or type(exc).__name__
        raise InputError(f"not a readable URDF ({detail})", field="robot") from None
    # whatever else its parser skips in recovering, no link or joint is lost without a word
    for kind, built in (("link", robot.links), ("joint", robot.joints)):
        names = {b.name for b in built}
        missing = [e.get("name") for e in root.findall(kind) if e.get("name") not in names]
        if missing:
            raise InputError(f"the URDF's {kind} {missing[0]} is lost by its parser ({len(missing)} "
                             f"{kind}(s) in all): is the file damaged?", field="robot")
    return robot


def transmissions(text: str) -> dict[str, float]:
    """Each joint's gear ratio from the URDF's ``<transmission>`` elements: the ``mechanicalReduction`` of
    a transmission that names one joint and one reduction (ROS's simple transmission, in its old and new
    forms); the others are left out.

    Parameters
    ----------
    text : str
        The URDF (checked as :func:`parse_urdf` checks it).
    """
    data = _document_bytes(text)
    if "<!DOCTYPE" in text or "<!ENTITY" in text:
        raise InputError("the URDF has a DTD (<!DOCTYPE or <!ENTITY>): URDF files need none", field="robot")
    try:
        root = ElementTree.fromstring(data)
    except ElementTree.ParseError as exc:
        raise InputError(f"not a readable URDF (malformed XML: {exc})", field="robot") from None
    out = {}
    for element in root.findall("transmission"):
        joints = [j.get("name") for j in element.findall("joint")]
        reductions = [r.text for r in element.iter("mechanicalReduction")]
        if len(joints) == 1 and len(reductions) == 1 and joints[0]:
            out[joints[0]] = urdf_number(reductions[0], f"transmission {element.get('name')}'s mechanicalReduction")
    return out


def urdf_number(value, what: str) -> float:
    """A URDF attribute as a finite number of at most 1e100, or one sentence.

    Parameters
    ----------
    value : str or float
        The attribute.
    what : str
        Where it is, for the sentence.
    """
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{what} is not a number: {value!r}", field="robot") from None
    if not abs(x) <= _LARGEST:
        raise InputError(f"{what} is {'not finite' if not np.isfinite(x) else f'{x:g}, past any physical scale'}",
                         field="robot")
    return x
