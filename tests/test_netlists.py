"""The committed netlists: a fresh generation has their lines, and their values to rounding.

(tests/test_plain_ngspice.py runs every built-in robot's netlist in the ngspice executable.)
"""

from pathlib import Path

import numpy as np

from analogy.scenes.builtin import scene, write_netlists

NETLISTS = Path(__file__).resolve().parent.parent / "netlists"


def _tokens(text):
    return [line.split() for line in text.splitlines()]


def _number(token):
    try:
        return float(token)
    except ValueError:
        return None


def test_committed_netlists_are_up_to_date(tmp_path):
    """A fresh generation has the committed lines, word for word, and values that differ by
    rounding only: M' = T⁻ᵀ·M·T⁻¹ and the tolerances are sums of n² products, so two
    processors (or libm versions) may differ by n²·ε of the largest value on a line's kind.
    The tolerance values (abstol …) are written to 3 digits and compared as written."""
    eps = np.finfo(float).eps
    fresh = write_netlists(tmp_path)
    for path in fresh:
        committed = NETLISTS / path.name
        assert committed.exists(), f"{committed} is missing: run analogy.scenes.builtin.write_netlists('netlists')"
        old, new = _tokens(committed.read_text()), _tokens(path.read_text())
        assert len(old) == len(new), f"{path.name} has other lines than a fresh generation"
        n = scene(path.stem).system().dof
        scale: dict = {}
        for line in old:
            for token in line[1:]:
                if (x := _number(token)) is not None:
                    scale[line[0][0]] = max(scale.get(line[0][0], 0.0), abs(x))
        for a, b in zip(old, new):
            assert len(a) == len(b) and [_number(t) is None for t in a] == [_number(t) is None for t in b], (a, b)
            for x, y in zip(a, b):
                if _number(x) is None or x.startswith("."):
                    assert x == y, (path.name, a, b)
                else:
                    assert abs(float(x) - float(y)) <= 4 * n * n * eps * scale[a[0][0]], (path.name, a, b)
    assert sorted(p.name for p in NETLISTS.glob("*.cir")) == sorted(p.name for p in fresh)


def test_a_comment_spells_symbols_and_accented_names_in_ascii_and_stays_one_line():
    """Netlists are ASCII for every SPICE: the package's own symbols are spelled out, accents
    dropped, and what has no spelling becomes "?"; no character can start a new line."""
    from analogy.circuit.netlist import comment_text
    assert comment_text("cond(Φ_p) = 44.7 · M′ ≤ 1e-6, T⁻¹, 68 µs") == "cond(Phi_p) = 44.7 * M' <= 1e-6, T^-1, 68 us"
    assert comment_text("gelenk_ä épaule 肩") == "gelenk_a epaule ?"
    assert comment_text("a\n.control\r\u2028shell") == "a?.control??shell"


def test_a_summed_source_is_described_by_its_forces_and_no_comment_names_a_missing_device():
    """With gravity, joint 1's step and its gravity load into n1 are one PWL device In1: its comment
    lists the two waveforms, and every I-device a comment names is a line of the file."""
    import re
    from analogy.solvers.transient import netlist
    text = netlist(scene("serial2").replace(parameters=(("g", 9.81),), q=(0.3, 0.2)).system())
    assert "* In1 sums the forces into n1: step(1) (joint 1) + step(-35.0028) (joint 1)" in text
    devices = {line.split()[0] for line in text.splitlines() if line and line[0] in "IVBCREFLG"}
    named = set(re.findall(r"\bI[A-Za-z0-9_]+", "\n".join(line for line in text.splitlines() if line.startswith("*"))))
    assert named <= devices, named - devices
