"""Fuzzing hostile input: every outcome is a value or one sentence, no code runs and no netlist line is injected.

Profiles: the default runs about 2,000 cases in all; ``ANALOGY_FUZZ=deep`` runs 10,000 per
target and prints the counts (``pytest -s tests/test_fuzz.py``).
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import stat
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from hang_guard import finishes
from analogy import InputError, SimulationError, node_system
from analogy.solvers.transient import netlist
from analogy.circuit.topology import serial
from analogy.cli import main
from analogy.model.expressions import FUNCTION_NAMES, parse_expression, parse_number
from analogy.model.joint import JointSpace
from analogy.scenes.toml import parse_scene
from analogy.solvers.exact import solve_exact
from analogy.waveforms import parse_waveform

DEEP = os.environ.get("ANALOGY_FUZZ") == "deep"
#: Cases per target: about 2,000 in all by default, 10,000 each in the deep profile.
CASES = {"expressions": 500, "matrices": 300, "waveforms": 400, "scenes": 250, "cli": 250, "netlist_text": 300,
         "units": 400, "sweeps": 200, "store": 60, "manifest": 60, "paths": 150, "options": 300, "urdf": 300}
if DEEP:
    CASES = dict.fromkeys(CASES, 10_000)
COUNTS: Counter = Counter()
REFUSED: Counter = Counter()
SLOWEST: dict = {}
#: No input may create this file: every payload below tries to.
CANARY = Path(tempfile.gettempdir()) / f"analogy-fuzz-canary-{os.getpid()}"
SYMBOLS = {name: sp.Symbol(name, real=True) for name in ("a", "b", "q1", "q2")}


def profile(target: str):
    # A case slower than 5 s is a hang; the default profile is the same every run.
    return settings(max_examples=CASES[target], deadline=5_000, derandomize=not DEEP, database=None,
                    suppress_health_check=list(HealthCheck))


PAYLOADS = [f"__import__('os').system('touch {CANARY}')", f"open('{CANARY}', 'w').write('x')",
            f"exec(\"open('{CANARY}', 'w')\")", "eval('1')", f"$(touch {CANARY})", f"`touch {CANARY}`",
            f"\nshell touch {CANARY}\n", f"\n.control\nshell touch {CANARY}\n.endc\n",
            f".include {CANARY}", "lambda: 0", "[x for x in ()]", "().__class__", "a.b", "a[0]", "f'{1}'"]
BREAKS = ["\n", "\r", "\r\n", "\x0b", "\x0c", "\x1c", "\x1d", "\x1e", "\x85", "\u2028", "\x00"]
HOSTILE = PAYLOADS + BREAKS + [".control", ".endc", ".include x", "shell rm -rf x", "{", "}", "'", '"',
                               ";", "*", "$", "\\", "é", "\u202e"]

hostile_text = st.one_of(st.sampled_from(HOSTILE),
                         st.lists(st.one_of(st.sampled_from(HOSTILE), st.text(max_size=8)), max_size=5).map("".join))
floats = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                   st.sampled_from([0.0, 1.0, -1.0, 1e308, -1e308, 1.7976931348623157e308, 5e-324, 1e-300,
                                    1e300, 2.2e-308, 1e-12, 1e12]))
plain = st.floats(0.01, 100.0)
plain_text = st.one_of(plain.map(lambda x: f"{x:.4g}"), st.sampled_from(["1", "2", "0.5", "pi/4", "2^3", "1e-3"]))
number_text = st.one_of(plain_text, plain_text, floats.map(repr), st.integers(-10 ** 20, 10 ** 20).map(str),
                        st.sampled_from(["9" * 400, "1" + "0" * 5000, "1e999", "-0", "0x10", "1_0", "1j"]))
name_text = st.sampled_from(["a", "b", "q1", "q2", "q9", "pi", "e", "sin", "arcsin", "x0", "numpy", "nan",
                             "inf", "__import__", "_x", "os", "Dummy", "lambda"])
function_name = st.sampled_from(FUNCTION_NAMES + ("arcsin", "eval", "open", "getattr", "__import__"))


def _expressions():
    atoms = st.one_of(number_text, name_text, st.sampled_from(PAYLOADS))

    def grow(children):
        return st.one_of(
            st.tuples(children, st.sampled_from(["+", "-", "*", "/", "**", "^", "%", "//", "@", "<"]), children)
            .map(lambda t: f"({t[0]} {t[1]} {t[2]})"),
            st.tuples(function_name, st.lists(children, max_size=3)).map(lambda t: f"{t[0]}({', '.join(t[1])})"),
            children.map(lambda x: f"-{x}"),
            st.tuples(children, st.integers(1, 4)).map(lambda t: "^".join([t[0]] * (t[1] + 1))))
    deep = st.integers(1, 140).map(lambda k: "(" * k + "q1" + ")" * k)
    chains = st.tuples(st.sampled_from(["-", "exp(", "sin("]), st.integers(50, 200)).map(
        lambda t: t[0] * t[1] + "q1" + (")" * t[1] if "(" in t[0] else ""))
    return st.one_of(st.recursive(atoms, grow, max_leaves=25), st.text(max_size=40), hostile_text, deep, chains)


expressions = _expressions()

#: Every line the netlist writer means to emit: comments, elements, and its own directives.
_LINE = re.compile(r"^(\*[ -~]*|[CRLIVEFGB][A-Za-z0-9_]* [ -~]*|\.(ic|options|tran|save|print|end)( [ -~]*)?)$")
_CONTROL = re.compile(r"\b(shell|include|lib|control|endc|exec|system)\b|^\s*\.", re.I)


def check_netlist(text: str) -> None:
    """Every line (split as the loader splits it) is one the writer meant; values are finite."""
    assert text.isascii()
    # the one control block allowed is the printing one, word for word, before .end
    for block in ("\n.control\nset numdgt=15\n.endc\n.end\n", "\n.control\nset numdgt=15\noption interp\n.endc\n.end\n"):
        text = text.replace(block, "\n.end\n")
    for line in text.splitlines():      # splitlines also breaks at \r, \x0b, \x0c, \x1c-\x1e
        assert _LINE.match(line), f"unexpected netlist line {line!r}"
        if not line.startswith(("*", ".")):
            assert not _CONTROL.search(line) and not re.search(r"\b(inf|nan)\b", line, re.I), line


def refused(target: str, exc: Exception) -> None:
    """A refusal is one sentence on one line."""
    assert str(exc) and not any(b in str(exc) for b in ("\n", "\r", "Traceback")), str(exc)
    REFUSED[target] += 1


def check_canary() -> None:
    assert not CANARY.exists(), "an input ran code: the canary file exists"


@contextlib.contextmanager
def case(target: str):
    start = time.perf_counter()
    yield
    check_canary()
    COUNTS[target] += 1
    SLOWEST[target] = max(SLOWEST.get(target, 0.0), time.perf_counter() - start)


@pytest.fixture(scope="module", autouse=True)
def report():
    CANARY.unlink(missing_ok=True)
    yield
    check_canary()
    print("\nfuzz cases per target: " + ", ".join(f"{k} {v} ({REFUSED[k]} refused, slowest "
                                                 f"{SLOWEST.get(k, 0):.2f} s)" for k, v in COUNTS.items()))


@given(expressions)
@profile("expressions")
def test_expressions_give_a_bounded_value_or_one_sentence(text):
    with case("expressions"):
        try:
            value = finishes(lambda: parse_expression(text, SYMBOLS))
        except InputError as exc:
            refused("expressions", exc)
        else:
            assert all(math.isfinite(float(x)) for x in value.atoms(sp.Number))
        try:
            assert math.isfinite(finishes(lambda: parse_number(text)))
        except InputError:
            pass


def _symmetric(n: int):
    return st.lists(floats, min_size=n * (n + 1) // 2, max_size=n * (n + 1) // 2).map(
        lambda v: _fill(n, v))


def _fill(n: int, values) -> list:
    m = [[0.0] * n for _ in range(n)]
    it = iter(values)
    for i in range(n):
        for j in range(i, n):
            m[i][j] = m[j][i] = next(it)
    return m


@st.composite
def systems(draw):
    n = draw(st.integers(1, 4))
    def definite(values):
        b = np.reshape(values, (n, n))
        return b @ b.T + np.eye(n) * draw(st.sampled_from([1e-300, 1e-9, 1.0, 1e9, 1e300]))
    spd = st.lists(st.floats(-1e3, 1e3), min_size=n * n, max_size=n * n).map(definite)
    diagonal = st.lists(st.one_of(plain, floats), min_size=n, max_size=n).map(np.diag)
    mass = draw(st.one_of(spd, spd, _symmetric(n), diagonal))
    damping = draw(st.one_of(diagonal, spd, _symmetric(n)))
    stiffness = draw(st.one_of(st.none(), diagonal, spd))
    top = draw(st.one_of(st.sampled_from(["serial", "parallel"]),
                         st.lists(floats, min_size=n * n, max_size=n * n).map(lambda v: np.reshape(v, (n, n)))))
    return mass, damping, stiffness, top, draw(st.lists(st.one_of(plain, floats), min_size=n, max_size=n))


@given(systems())
# a mass of 1e-300 on an unstable spring: its rate's phase error overflows (no step holds it)
@example((np.array([[1e-300]]), np.diag([1.0]), np.diag([-1.0]), "serial", [1.0]))
@profile("matrices")
def test_matrices_give_a_clean_netlist_and_a_finite_solution_or_one_sentence(parts):
    mass, damping, stiffness, top, forces = parts
    with case("matrices"):
        try:
            s = node_system(JointSpace(mass, damping, stiffness), forces=forces, topology=top, t_stop=1.0)
            text = netlist(s, "fast")
        except InputError as exc:
            refused("matrices", exc)
            return
        check_netlist(text)
        try:
            y = solve_exact(s, np.linspace(0, 1, 5)).voltages
        except SimulationError:
            return
        assert np.all(np.isfinite(y))


_WAVES = ("step", "pulse", "sine", "pwl", "exec", "__import__", "open")
valid_waveform = st.one_of(
    st.tuples(plain_text, plain_text, plain_text).map(lambda t: f"step({t[0]}, {t[1]}/100, {t[2]}/1000)"),
    st.tuples(plain_text, plain_text, plain_text).map(lambda t: f"sine({t[0]}, {t[1]}, {t[2]})"),
    st.tuples(plain_text, plain_text).map(lambda t: f"pulse(0, {t[0]}, 0.1, 1e-3, 1e-3, {t[1]}/1000, 0.5)"),
    st.lists(plain, min_size=2, max_size=12).map(
        lambda v: "pwl(" + ", ".join(f"{k / len(v):.4g}, {x:.4g}" for k, x in enumerate(v)) + ")"),
    plain_text)
waveform_text = st.one_of(valid_waveform, valid_waveform,
    st.tuples(st.sampled_from(_WAVES), st.lists(st.one_of(number_text, expressions), max_size=8),
              st.lists(st.tuples(st.sampled_from(["delay", "rise", "width", "period", "x", "__class__"]),
                                 number_text), max_size=2))
    .map(lambda t: f"{t[0]}({', '.join(t[1] + [f'{k}={v}' for k, v in t[2]])})"),
    hostile_text, st.text(max_size=30))


@given(waveform_text, st.sampled_from([1e-9, 1e-3, 1.0, 1.0, 10.0, 1e3, 1e9]))
@profile("waveforms")
def test_force_specs_give_a_waveform_and_a_clean_netlist_or_one_sentence(spec, t_stop):
    with case("waveforms"):
        try:
            w = parse_waveform(spec)
            s = node_system(JointSpace([[1.0]], [[1.0]]), forces=[w], t_stop=t_stop)
            text = netlist(s, "fast")
        except InputError as exc:
            refused("waveforms", exc)
            return
        check_netlist(text)
        assert np.all(np.isfinite(s.breakpoints()))


def toml_string(text: str) -> str:
    """A TOML basic string holding *text* exactly (control characters as escapes)."""
    out = []
    for ch in text:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7f:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


toml_value = st.one_of(plain.map(lambda x: f"{x:.4g}"), plain.map(lambda x: f"{x:.4g}"), number_text.filter(lambda x: re.fullmatch(r"-?[0-9]+(\.[0-9]+)?(e-?[0-9]+)?", x) is not None),
                       expressions.map(toml_string), st.booleans().map(str).map(str.lower))
output_names = st.one_of(st.sampled_from(["ok.csv", "sub/ok.csv"]), st.sampled_from(["ok.csv", "sub/ok.csv", "link/escaped.csv", "victim.csv", "../x.csv",
                                          "/etc/passwd", "a\x00b.csv", ".", "sub/../../x.csv", "x.png"]),
                         hostile_text)


@st.composite
def scene_files(draw):
    n = draw(st.integers(1, 3))
    rows = [[draw(toml_value) for _ in range(n)] for _ in range(n)]
    if draw(st.booleans()):             # half the scenes have a usable mass matrix
        rows = [[f"{draw(plain) + 200:.4g}" if i == j else f"{draw(plain):.4g}" for j in range(n)] for i in range(n)]
        rows = [[rows[min(i, j)][max(i, j)] for j in range(n)] for i in range(n)]
    params = draw(st.one_of(st.just({}), st.dictionaries(name_text, toml_value, max_size=3)))
    lines = [f"name = {toml_string(draw(st.one_of(st.just('s'), st.just('s'), hostile_text)))}",
             f"description = {toml_string(draw(hostile_text))}", "[model]",
             f"mass = [{', '.join('[' + ', '.join(r) + ']' for r in rows)}]",
             f"damping = [{', '.join(draw(toml_value) for _ in range(n))}]", "[parameters]"]
    lines += [f"{k} = {v}" for k, v in params.items()]
    forces = [toml_string(draw(waveform_text)) if draw(st.booleans()) else draw(toml_value) for _ in range(n)]
    t_stop = draw(st.one_of(st.sampled_from(["1.0", "10"]), toml_value))
    lines += ["[inputs]", f"forces = [{', '.join(forces)}]", f"t_stop = {t_stop}",
              "[outputs]", "joint_rates = true", f"csv = {toml_string(draw(output_names))}"]
    text = "\n".join(lines) + "\n"
    return draw(st.one_of(st.just(text), st.just(text), st.text(max_size=60).map(lambda junk: text + junk)))


@pytest.fixture(scope="module")
def scene_folder(tmp_path_factory):
    root = tmp_path_factory.mktemp("fuzz-scene")
    elsewhere = tmp_path_factory.mktemp("fuzz-elsewhere")
    (elsewhere / "victim.csv").write_text("precious")
    os.symlink(elsewhere, root / "link")
    os.symlink(elsewhere / "victim.csv", root / "victim.csv")
    yield root
    assert sorted(p.name for p in elsewhere.iterdir()) == ["victim.csv"]
    assert (elsewhere / "victim.csv").read_text() == "precious"


@given(scene_files())
@profile("scenes")
def test_scene_files_give_a_scene_inside_its_folder_or_one_sentence(scene_folder, text):
    with case("scenes"):
        try:
            sc = parse_scene(text, source=scene_folder / "s.toml")
            title = f"analogy scene {sc.name}: {sc.description}"
            check_netlist(netlist(sc.system(), "fast", title=title))
            path = sc.path(sc.csv_file, scene_folder)
        except InputError as exc:
            refused("scenes", exc)
            return
        real = Path(os.path.realpath(path))
        assert Path(os.path.realpath(scene_folder)) in real.parents and not path.is_symlink()


def _matrix(n: int):
    return st.lists(st.lists(st.one_of(number_text, expressions), min_size=n, max_size=n), min_size=n,
                    max_size=n).map(lambda rows: "[" + ", ".join("[" + ", ".join(r) + "]" for r in rows) + "]")


@st.composite
def cli_arguments(draw):
    args = ["netlist"]
    n = draw(st.integers(1, 3))
    options = {
        "--mass": _matrix(n), "--damping": st.one_of(_matrix(n), st.lists(expressions, max_size=3).map(", ".join)),
        "--stiffness": _matrix(n), "--q": st.lists(number_text, max_size=3).map(", ".join),
        "--topology": st.one_of(st.sampled_from(["serial", "parallel", "ring"]), _matrix(n)),
        "--force": waveform_text, "--t-stop": st.one_of(number_text, expressions),
        "--save": st.one_of(st.sampled_from(["n1", "n1, C1_2", "R1"]), hostile_text),
        "--param": st.tuples(name_text, st.one_of(number_text, expressions)).map(lambda t: f"{t[0]}={t[1]}"),
        "--preset": st.sampled_from(["fast", "accurate", "bogus"]),
        "--robot": st.sampled_from(["serial2", "parallel3", "serial40000", "random3", "flex"]),
        "--dynamics": st.sampled_from(["linear", "nonlinear"]),
    }
    for flag in draw(st.lists(st.sampled_from(sorted(options)), max_size=4)):
        args += [flag, draw(options[flag])]
    if draw(st.booleans()):
        args.append("--realizable")
    return args


@given(cli_arguments())
@profile("cli")
def test_cli_arguments_give_a_netlist_or_one_sentence_with_exit_2(args):
    with case("cli"):
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(args)
        lines = err.getvalue().splitlines()
        if code == 2:
            REFUSED["cli"] += 1
            assert len(lines) == 1 and lines[0].startswith("analogy: error: "), lines
            assert out.getvalue() == ""
        else:
            assert code == 0 and all(line.startswith("analogy: warning: ") for line in lines) and len(lines) <= 1
            check_netlist(out.getvalue())


@given(hostile_text, st.lists(st.one_of(st.sampled_from(["n1", "n2", "C1_2", "R1"]), hostile_text), max_size=3),
       st.booleans())
@profile("netlist_text")
def test_titles_and_saved_names_never_add_netlist_lines(title, save, realizable):
    system = node_system(JointSpace([[2, -0.3], [-0.3, 1]], np.eye(2), np.eye(2)), forces=["step(1)", "sine(0, 1, 2)"],
                         topology=serial(2), info={"robot": title, "parameters": {title: 1.0}})
    with case("netlist_text"):
        try:
            text = netlist(system, "fast", save=save or None, title=title, realizable=realizable)
        except InputError as exc:
            refused("netlist_text", exc)
            return
        check_netlist(text)


# ------------------------------------------------------------------ units, sweep files, the store

UNIT_NAMES = ["m", "mm", "km", "s", "ms", "kg", "g", "N", "deg", "rad", "turn", "Hz", "J", "W", "µm", "°",
              "Ω", "degC", "blorb", "e", "pi", "k", "M"]
unit_text = st.one_of(
    st.lists(st.one_of(st.sampled_from(UNIT_NAMES), st.sampled_from(["^", "**", "*", "/", "·", " ", "(", ")", "-"]),
                       st.integers(-30, 30).map(str), st.sampled_from(["2", "2^2", "^2^2^2^2^2^2", "1e300"])),
             min_size=1, max_size=12).map("".join),
    st.text(alphabet="mskgN^*/·() 0123456789-µ°", max_size=40))


@given(st.sampled_from(["1", "0", "2.5", "-3", "pi/6"]), unit_text)
@profile("units")
def test_numbers_with_units_give_a_finite_si_value_or_one_sentence(number, unit):
    with case("units"):
        try:
            value = finishes(lambda: parse_number(f"{number} {unit}"), 5.0)
        except InputError as exc:
            refused("units", exc)
        else:
            assert math.isfinite(value)


SWEEP_HEAD = ('name = "fuzz"\n[model]\nrobot = "serial2"\n[inputs]\nforces = [1, 0]\nt_stop = 1\n'
              '[solvers]\nuse = ["spice", "exact"]\npreset = "fast"\n')
# mostly axes a sweep takes, so that the valid path is fuzzed as well as the refusals
axis_names = st.one_of(st.sampled_from(["q1", "q2", "d1", "l2", "b1", "t_stop"]),
                       st.sampled_from(["q3", "q0", "rate1", "force2", "g", "dd1", "preset", "topology", "dynamics",
                                        "key", "index", "status", "message", "error_spice", "seconds_exact",
                                        "__class__", "q2 ", ""]))
axis_values = st.one_of(
    st.lists(st.floats(0.1, 5.0), min_size=1, max_size=4).map(lambda xs: "[" + ", ".join(map(str, xs)) + "]"),
    st.lists(st.one_of(st.floats(-1e3, 1e3), st.integers(-10, 10), st.sampled_from(['"fast"', '"serial"', '"x"'])),
             min_size=0, max_size=4).map(lambda xs: "[" + ", ".join(str(x) for x in xs) + "]"),
    st.tuples(st.floats(-10, 10), st.floats(-10, 10), st.integers(-5, 10 ** 12), st.sampled_from(["linear", "log", "x"]))
    .map(lambda t: f'{{ low = {t[0]}, high = {t[1]}, count = {t[2]}, scale = "{t[3]}" }}'))
sweep_design = st.tuples(st.sampled_from(["grid", "random", "lhs", "sobol", "halton"]),
                         st.one_of(st.none(), st.integers(1, 1000), st.integers(-5, 2 ** 70), st.sampled_from([1e12, 0])),
                         st.one_of(st.none(), st.integers(0, 100), st.integers(-2 ** 64, 2 ** 64)),
                         st.one_of(st.none(), st.integers(1, 100), st.integers(-3, 200_000)))


@given(sweep_design, st.dictionaries(axis_names, axis_values, min_size=1, max_size=4))
@profile("sweeps")
def test_sweep_files_give_a_bounded_sweep_or_one_sentence(design, axes):
    from analogy.batch.sweep import MAX_SCENES, load_sweep
    method, count, seed, group = design
    body = SWEEP_HEAD + f'[sweep]\nmethod = "{method}"\n'
    body += "".join(f"{k} = {v}\n" for k, v in (("count", count), ("seed", seed), ("group_size", group))
                    if v is not None)
    body += "[sweep.axes]\n" + "".join(f'"{name}" = {value}\n' for name, value in axes.items())
    with case("sweeps"), tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "s.toml"
        path.write_text(body)
        try:
            sweep = finishes(lambda: load_sweep(path), 5.0)
            first = next(sweep.chunks(), None)          # its first design points come at once
        except InputError as exc:
            refused("sweeps", exc)
        else:
            assert 1 <= sweep.size <= MAX_SCENES and first is not None


@pytest.fixture(scope="module")
def small_store(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz-store")
    (folder / "s.toml").write_text(SWEEP_HEAD + '[sweep]\nmethod = "random"\ncount = 20\nseed = 1\n'
                                                'group_size = 10\n[sweep.axes]\nq2 = [-1.0, 1.0]\n')
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["batch", str(folder / "s.toml"), "-o", str(folder / "base"), "--no-progress"]) == 0
    return folder


@given(st.sampled_from(["part", "manifest"]), st.lists(st.tuples(st.floats(0, 1), st.integers(0, 255)),
                                                       min_size=1, max_size=4), st.one_of(st.none(), st.floats(0, 1)))
@profile("store")
def test_a_corrupted_store_reads_or_says_what_is_damaged(small_store, target, flips, cut):
    import shutil
    from analogy.batch.store import read
    with case("store"), tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "store"
        shutil.copytree(small_store / "base", folder)
        victim = sorted(folder.glob("part-*.parquet"))[0] if target == "part" else folder / "_sweep.json"
        data = bytearray(victim.read_bytes())
        for where, byte in flips:
            data[min(int(where * len(data)), len(data) - 1)] = byte
        if cut is not None:
            data = data[:int(cut * len(data))]
        victim.write_bytes(bytes(data))
        try:
            frame = finishes(lambda: read(folder), 5.0)
        except InputError as exc:
            refused("store", exc)
        else:
            assert len(frame) <= 20 and frame["scene"].is_unique


_SEGMENTS = ["sub", "missing", "link_file", "link_dir", "fifo", "plain.cir", "a" * 300, "..", ".", "x\x00y", ""]


@given(st.lists(st.sampled_from(_SEGMENTS), max_size=3), st.sampled_from(["n.cir", "link_file", "fifo", "plain.cir",
                                                                          "b" * 250 + ".cir", "sub", ".hidden"]),
       st.booleans())
@example(folders=["missing", "..", "a" * 300], name="n.cir", device=False)     # a long name past a missing folder
@profile("paths")
def test_an_output_path_gets_the_whole_file_or_one_sentence_and_nothing_outside_its_folder(folders, name, device):
    """``netlist -o PATH`` over symlinks to files outside, pipes, missing folders, names too long
    and NUL bytes: exit 0 with a regular file at PATH (a symlink there replaced), or exit 2 in one
    sentence; the folder outside is never written unless PATH itself goes through a folder link,
    and no temporary file is left anywhere."""
    with case("paths"), tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        inside, outside = root / "inside", root / "outside"
        (inside / "sub").mkdir(parents=True)
        outside.mkdir()
        (outside / "target.cir").write_text("untouched\n")
        (inside / "plain.cir").write_text("old\n")
        (inside / "link_file").symlink_to(outside / "target.cir")
        (inside / "link_dir").symlink_to(outside)
        os.mkfifo(inside / "fifo")
        path = os.devnull if device else os.path.join(str(inside), *folders, name)
        err = io.StringIO()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            code = finishes(lambda: main(["netlist", "-o", path]), 30.0)
        said = err.getvalue().strip().splitlines()
        if code == 2:
            refused("paths", InputError(said[-1]))
            assert len(said) == 1 and said[0].startswith("analogy: error: "), said
        else:
            assert code == 0, said
            written = Path(path)
            assert device or (written.is_file() and not written.is_symlink()
                              and written.read_text().startswith("* analogy"))
        through_link = "link_dir" in folders and "\x00" not in path
        if not through_link:
            assert sorted(p.name for p in outside.iterdir()) == ["target.cir"]
        assert (outside / "target.cir").read_text() == "untouched\n"
        leftovers = [p for p in root.rglob(".*") if p.is_file() and p.resolve() != Path(path).resolve()]
        assert not leftovers, leftovers
        assert stat.S_ISCHR(os.stat(os.devnull).st_mode)


json_value = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(-5, 10**20), st.floats(allow_nan=False),
                                     st.text(max_size=8)),
                           lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                   st.dictionaries(st.sampled_from(["name", "values", "low", "high",
                                                                                    "log", "x"]), inner, max_size=4)),
                           max_leaves=8)


@given(st.lists(st.tuples(st.sampled_from(["schema", "key", "scene", "method", "count", "seed", "group_size", "axes",
                                           "solvers", "preset", "source", "joint_units", "isolated", "axes.0",
                                           "axes.0.name", "axes.0.values", "axes.0.low"]), json_value),
                min_size=1, max_size=3))
@profile("manifest")
def test_a_manifest_with_fields_of_any_type_reports_or_says_it_is_not_a_manifest(small_store, changes):
    """The store's _sweep.json edited by hand: a report and a resume either work or refuse in one sentence."""
    import json
    import shutil
    from analogy.batch.report import batch_report
    from analogy.batch.store import read
    with case("manifest"), tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "store"
        shutil.copytree(small_store / "base", folder)
        data = json.loads((folder / "_sweep.json").read_text())
        for where, value in changes:
            parts, node = where.split("."), data
            for part in parts[:-1]:
                node = node[int(part)] if isinstance(node, list) and part.isdigit() and int(part) < len(node) \
                    else node.get(part) if isinstance(node, dict) else None
            if isinstance(node, dict):
                node[parts[-1]] = value
            elif isinstance(node, list) and parts[-1].isdigit() and int(parts[-1]) < len(node):
                node[int(parts[-1])] = value
        (folder / "_sweep.json").write_text(json.dumps(data))
        try:
            report = finishes(lambda: batch_report(folder), 5.0)
            assert report.summary() and report.html()
            assert len(read(folder)) == 20
        except InputError as exc:
            refused("manifest", exc)


class _Reached(BaseException):
    """Raised where a command's work would start: its options were all accepted."""


#: Where each command's work starts, wrapped to check what it is given and then stop.
_WORK = {"stress": ("analogy.diagnostics.stress.report", "cases"), "bench": ("analogy.diagnostics.bench", "bench_scenes"),
         "memory": ("analogy.diagnostics.memory", "scene"), "throughput": ("analogy.diagnostics.throughput", "scene")}
option_value = st.one_of(number_text, hostile_text, st.integers(-3, 5).map(str), st.sampled_from(
    ["abc", "xyz", "a", "spice", "ode", "exact", "reference", "odd", "default", "serial2", "flex2", "fast", "bogus"]))
_OPTIONS = {
    "stress": ["--families", "--timeout", "--quick", "-o"], "bench": ["--repeats", "--quick", "--full"],
    "memory": ["--runs", "--solver", "--preset", "--scene"],
    "throughput": ["-n", "--workers", "--group-size", "--baseline", "--repeats", "--preset"],
}
_FLAGS = {"--quick", "--full"}


@st.composite
def command_options(draw):
    command = draw(st.sampled_from(sorted(_OPTIONS)))
    args = [command]
    for flag in draw(st.lists(st.sampled_from(_OPTIONS[command]), max_size=4)):
        args += [flag] if flag in _FLAGS else [flag, draw(option_value) if flag != "-o" else
                                               draw(st.sampled_from(["out", "a-file", "sub/dir"]))]
    return args


@given(args=command_options())
@profile("options")
def test_the_options_of_stress_bench_memory_and_throughput_reach_their_work_or_one_sentence(monkeypatch_module,
                                                                                             options_folder, args):
    """Each is refused with one line and exit 2, or reaches the point where the command's work starts
    (stopped there, so a case costs milliseconds), with its checked values in range."""
    import importlib
    module, name = _WORK[args[0]]
    real = getattr(importlib.import_module(module), name)

    def reached(*a, **k):
        real(*a, **k) if args[0] == "memory" else None        # memory's scene name is checked by its lookup
        raise _Reached
    with case("options"), monkeypatch_module.context() as mp:
        mp.setattr(importlib.import_module(module), name, reached)
        mp.chdir(options_folder)
        out, err = io.StringIO(), io.StringIO()
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = finishes(lambda: main(args), 5.0)
        except _Reached:
            assert not err.getvalue().strip(), err.getvalue()
            return
        lines = err.getvalue().splitlines()
        assert code == 2 and len(lines) == 1 and lines[0].startswith("analogy: error: "), (code, lines)
        REFUSED["options"] += 1


@pytest.fixture(scope="module")
def options_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("options")
    (folder / "a-file").write_text("")
    return folder


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as mp:
        yield mp


_BENCH_URDF = (Path(__file__).parent / "urdf" / "bench.urdf").read_text()
#: Every attribute value of the bench URDF, each a place a mutation may land.
_URDF_VALUES = sorted(set(re.findall(r'="([^"]*)"', _BENCH_URDF)))
urdf_value = st.one_of(number_text, hostile_text, st.sampled_from(
    ["0 0 0", "nan 0 1", "1 2", "1 2 3 4", "1e400 0 0", "-1", "0", "floating", "planar", "fixed", "carriage",
     "floor", "", " ", "&#10;.control&#10;shell touch x&#10;.endc"]))


@given(st.lists(st.tuples(st.sampled_from(_URDF_VALUES), urdf_value), min_size=1, max_size=4),
       st.sampled_from(["", "<!DOCTYPE r [<!ENTITY a 'x'>]>", "<link name='floor'/>", "<joint name='x'/>"]))
@profile("urdf")
def test_urdf_files_give_a_model_with_a_positive_definite_mass_matrix_or_one_sentence(swaps, extra):
    """Attribute values of a valid URDF replaced by hostile ones, and stray elements: a model whose
    M(q) is symmetric positive definite and whose netlist is clean, or one sentence."""
    from analogy.model.urdf import UrdfModel
    text = _BENCH_URDF
    for old, new in swaps:
        text = text.replace(f'="{old}"', f'="{new.replace(chr(34), "")}"', 1)
    text = text.replace("<robot", extra + "<robot", 1) if extra.startswith("<!") else \
        text.replace("</robot>", extra + "</robot>")
    with case("urdf"):
        try:
            model = finishes(lambda: UrdfModel(text), 5.0)
            system = finishes(lambda: node_system(model, [0.1] * model.dof), 5.0)
        except InputError as exc:
            refused("urdf", exc)
        else:
            m = system.mass
            assert np.array_equal(m, m.T) and np.linalg.eigvalsh(m).min() > 0
            check_netlist(netlist(system))
