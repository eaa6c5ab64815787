"""The circuit where students work: a KiCad schematic and an LTspice netlist and schematic of what ngspice runs.

The KiCad schematic carries each netlist line whole, so KiCad's own netlist of it (``kicad-cli``)
holds our lines and analysis, and with its lines in our order runs in ngspice to our result: the
same matrix, the same steps; 1e-12 of each output's peak leaves room for the braces KiCad needs
around a negative value, which SPICE reads as the same number. (KiCad lists the parts in its
spatial index's order. The reordered matrix rounds differently, ngspice's step control then takes
other steps, and the outputs part by up to its tolerance: 2.4e-6 on the realizable serial3.)
An LTspice netlist of a linear circuit is plain SPICE with ngspice's own option words dropped,
so ngspice runs it to our result; the nonlinear lines take LTspice's words (x, no braces).
"""

import re
import shutil
import subprocess
from collections import Counter
from dataclasses import replace

import numpy as np
import pytest

import analogy
from analogy.circuit.kicad import kicad_schematic
from analogy.circuit.ltspice import ltspice_netlist, ltspice_schematic
from analogy.circuit.netlist_lines import netlist_lines
from analogy.cli import main
from analogy.scenes.builtin import scene

SAME_RUN = 1e-12        # of each output's peak: the same circuit, its elements listed in another order


def _tokens(text: str):
    return re.findall(r'"(?:\\.|[^"\\])*"|[()]|[^\s()"]+', text)


def _sexpr(text: str):
    """A KiCad file as nested lists of atoms (strings unquoted)."""
    stack = [[]]
    for tok in _tokens(text):
        if tok == "(":
            stack.append([])
        elif tok == ")":
            done = stack.pop()
            stack[-1].append(done)
        else:
            stack[-1].append(re.sub(r'\\(.)', lambda m: "\n" if m.group(1) == "n" else m.group(1), tok[1:-1])
                             if tok.startswith('"') else tok)
    return stack[0][0]


def _children(node, head: str):
    return [c for c in node if isinstance(c, list) and c and c[0] == head]


def _netlist(name: str) -> str:
    sc = scene("default")
    systems = {"default": lambda: sc.system(),
               "serial3 realizable": lambda: scene("serial3").system().realized(),
               "nonlinear default": lambda: replace(sc, dynamics="nonlinear").system()}
    system = systems[name]()
    return analogy.netlist(system), system


CASES = ["default", "serial3 realizable", "nonlinear default"]


@pytest.mark.parametrize("case", CASES)
def test_the_kicad_schematic_holds_every_element_line_its_nets_and_the_analysis(case):
    text, _ = _netlist(case)
    parts = netlist_lines(text)
    sheet = _sexpr(kicad_schematic(text, "lab"))
    symbols = [s for s in _children(sheet, "symbol") if s[1][1] != "analogy:ground"]
    lines = {}
    for s in symbols:
        props = {p[1]: p[2] for p in _children(s, "property")}
        kind, model = re.fullmatch(r'type="(\w)" model="(.*)" lib=""', props["Sim.Params"], re.S).groups()
        assert props["Sim.Device"] == "SPICE" and kind == props["Reference"][0].upper()
        lines[props["Reference"]] = model
    # each line whole: negative numbers in braces, which SPICE reads as the same number
    assert lines == {e.name: (f"{{{e.model}}}" if re.fullmatch(r"-[\d.e+-]+", e.model) else e.model)
                     for e in parts.elements}
    labels = Counter(g[1] for g in _children(sheet, "global_label"))
    grounds = sum(1 for s in _children(sheet, "symbol") if s[1][1] == "analogy:ground")
    pins = Counter(n for e in parts.elements for n in e.nodes)
    assert labels == Counter({n: k for n, k in pins.items() if n != "0"}) and grounds == pins["0"]
    texts = [t[1] for t in _children(sheet, "text")]
    assert texts[1:] == parts.directives          # the analysis, after the header note
    assert all(line.startswith("* ") for line in texts[0].splitlines())      # the note is comments only


@pytest.mark.ngspice
@pytest.mark.deep           # the deep pass is where setup.sh installs KiCad 9
@pytest.mark.parametrize("case", CASES)
def test_kicad_cli_netlists_the_schematic_to_our_lines_which_ngspice_runs_to_our_result(case, tmp_path):
    if shutil.which("kicad-cli") is None:
        pytest.skip("kicad-cli (KiCad 9) is not installed: bash setup.sh test -m deep installs it")
    from analogy.solvers.spice import session
    text, system = _netlist(case)
    (tmp_path / "lab.kicad_sch").write_text(kicad_schematic(text, "lab"))
    subprocess.run(["kicad-cli", "sch", "export", "netlist", "--format", "spice", "-o", str(tmp_path / "lab.cir"),
                    str(tmp_path / "lab.kicad_sch")], check=True, capture_output=True, timeout=120)
    theirs = (tmp_path / "lab.cir").read_text()
    ours_parts, their_parts = netlist_lines(text), netlist_lines(theirs)
    bare = {e.name: e._replace(model=re.sub(r"^\{(-[\d.e+-]+)\}$", r"\1", e.model)) for e in their_parts.elements}
    assert sorted(bare.values()) == sorted(ours_parts.elements)         # our lines, each whole
    assert sorted(d for d in their_parts.directives if not d.startswith(".title")) == sorted(ours_parts.directives)
    # KiCad lists the parts in its own order (its spatial index's); in ours, its lines run as ours do
    order = {e.name: k for k, e in enumerate(ours_parts.elements)}
    lines = theirs.splitlines()
    slots = [k for k, line in enumerate(lines) if line.split(" ", 1)[0] in order]
    for k, line in zip(slots, sorted((lines[k] for k in slots), key=lambda li: order[li.split(" ", 1)[0]])):
        lines[k] = line
    ours, kicad = session().run(text, list(system.nodes)), session().run("\n".join(lines) + "\n", list(system.nodes))
    assert np.array_equal(ours["time"], kicad["time"])
    for node in system.nodes:
        assert np.max(np.abs(ours[node] - kicad[node])) <= SAME_RUN * np.max(np.abs(ours[node]))


@pytest.mark.parametrize("case", CASES)
def test_spicelib_reads_the_ltspice_netlist_element_by_element(case, tmp_path):
    from spicelib import SpiceEditor
    text, _ = _netlist(case)
    ours = {e.name: e for e in netlist_lines(text).elements}
    path = tmp_path / "lab.net"
    path.write_text(ltspice_netlist(text))
    editor = SpiceEditor(str(path))
    assert sorted(editor.get_components()) == sorted(name.upper() for name in ours)     # SPICE names ignore case
    for name, e in ours.items():
        assert editor.get_component_nodes(name) == list(e.nodes[:2])      # spicelib reads two nodes
        value = editor.get_component_value(name)
        if "{" not in e.model:
            assert value.split() == (list(e.nodes[2:]) + e.model.split()) or value == e.model
        else:           # a behavioural line: LTspice's words, no braces
            assert "{" not in value and value[:2] in ("I=", "V=", "Q=")
            if value.startswith("Q="):
                assert value.endswith("*x") and f"v({e.nodes[0]})" not in value.split("*x")[0][-12:]
    written = path.read_text().lower()
    assert "klu" not in written and ".control" not in written and "numdgt=15" in written


def test_ltspice_expressions_take_if_and_powers_and_the_charge_its_own_voltage():
    netlist = ("* t\nBq1 n1 0 I={v(n1) > 0 ? v(n2)^2 : -(v(n2) < 1 ? 1 : 2)}\n"
               "C1 n1 n2 Q={(3.0 + cos(v(x1)))*(v(n1)-v(n2))}\nC2 n2 0 Q={2.0*v(x1)*v(n2)}\n.end\n")
    lines = ltspice_netlist(netlist).splitlines()
    assert "Bq1 n1 0 I=if(v(n1)>0,v(n2)**2,-(if(v(n2)<1,1,2)))" in lines
    assert "C1 n1 n2 Q=(3.0+cos(v(x1)))*x" in lines and "C2 n2 0 Q=2.0*v(x1)*x" in lines


@pytest.mark.ngspice
@pytest.mark.parametrize("case", ["default", "serial3 realizable"])
def test_a_linear_circuit_s_ltspice_netlist_runs_in_ngspice_to_our_result(case):
    from analogy.solvers.spice import session
    text, system = _netlist(case)
    # LTspice's lines are ours less ngspice's own words; KLU (ngspice 46) solves with other pivots, so
    # ours runs without it too: then nothing but the dialect differs
    sparse = text.replace(" klu\n", "\n")
    ours, theirs = session().run(sparse, list(system.nodes)), session().run(ltspice_netlist(text), list(system.nodes))
    assert np.array_equal(ours["time"], theirs["time"])
    for node in system.nodes:
        assert np.max(np.abs(ours[node] - theirs[node])) <= SAME_RUN * np.max(np.abs(ours[node]))


@pytest.mark.parametrize("case", CASES)
def test_the_asc_schematic_places_each_element_with_a_flag_on_each_of_its_nodes(case):
    text, _ = _netlist(case)
    lt = ltspice_netlist(text)
    parts = netlist_lines(lt)
    asc = ltspice_schematic(lt).splitlines()
    assert asc[0] == "Version 4" and asc[1].startswith("SHEET 1 ")
    names = [line.split(maxsplit=2)[2] for line in asc if line.startswith("SYMATTR InstName")]
    values = [line.split(maxsplit=2)[2] for line in asc if line.startswith("SYMATTR Value")]
    assert names == [e.name for e in parts.elements] and values == [e.model for e in parts.elements]
    flags = Counter(line.split()[3] for line in asc if line.startswith("FLAG"))
    assert flags == Counter(n for e in parts.elements for n in e.nodes)
    directives = [line.split(" ", 5)[5] for line in asc if line.startswith("TEXT") and " !" in line]
    assert [d[1:] for d in directives] == parts.directives


def test_netlist_format_ltspice_writes_the_netlist_and_its_asc_beside_it(tmp_path, capsys):
    out = tmp_path / "arm.cir"
    assert main(["netlist", "--format", "ltspice", "-o", str(out)]) == 0
    assert out.read_text().startswith("* analogy default") and (tmp_path / "arm.asc").read_text().startswith("Version 4")
    assert main(["netlist", "--format", "ltspice", "-o", str(tmp_path / "arm.asc")]) == 2
    assert main(["netlist", "--format", "kicad", "--subckt"]) == 2
    assert "--format kicad does not apply" in capsys.readouterr().err
    assert main(["netlist", "--format", "kicad", "-o", str(tmp_path / "arm.kicad_sch")]) == 0
    assert (tmp_path / "arm.kicad_sch").read_text().startswith("(kicad_sch (version 20250114)")
