"""Circuit and mechanism diagrams: valid SVG and PNG files, one labelled symbol per element and source."""

import re
import xml.etree.ElementTree as ET
from collections import Counter

import matplotlib.image
import pytest

pytest.importorskip("schemdraw")
pytest.importorskip("matplotlib")

import analogy  # noqa: E402
from analogy.circuit import diagram  # noqa: E402
from analogy.circuit.description import circuit  # noqa: E402
from analogy.circuit.elements import ZERO_TOL, elements  # noqa: E402
from analogy.errors import InputError  # noqa: E402

SCENES = ["redundant", "serial2", "parallel2", "serial3", "parallel3", "random10"]
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
CIRCUIT_NAME = re.compile(r"^[CRLI]\d+(_n?\d+)?$")
MECHANISM_NAME = re.compile(r"^(m\u2032|MP p\u2032|b\u2032|k\u2032|f)\d+(_n?\d+)?$")


def circuit_names(system):
    """Element names and current-source names of the netlist (one source per joint force, not per waveform)."""
    names = [e.name for e in elements(system)]
    sources = []
    for line in (f"{src.name} " for src in circuit(system).sources):
        # I<joint>[_<waveform>] between two nodes, or I<joint>[_<waveform>]_n<node> to ground.
        joint, node = re.fullmatch(r"I(\d+)(?:_\d+)?(_n\d+)?", line.split()[0]).groups()
        name = f"I{joint}{node or ''}"
        if name not in sources:
            sources.append(name)
    return names + sources


def mechanism_name(circuit_name, floating):
    kind, suffix = circuit_name[0], circuit_name[1:]
    if kind == "C":
        return ("MP p\u2032" if floating else "m\u2032") + suffix
    return {"R": "b\u2032", "L": "k\u2032", "I": "f"}[kind] + suffix


def mechanism_names(system):
    floating = {e.name: e.floating for e in elements(system)}
    return [mechanism_name(n, floating.get(n, False)) for n in circuit_names(system)]


def svg_texts(path):
    root = ET.parse(path).getroot()
    assert root.tag.endswith("svg")
    return ["".join(t.itertext()).strip() for t in root.iter() if t.tag.endswith("}text") or t.tag == "text"]


def labelled(path, pattern):
    return Counter(t for t in svg_texts(path) if pattern.match(t))


def assert_png(path):
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    import matplotlib.image
    image = matplotlib.image.imread(path)
    assert image.shape[0] > 100 and image.shape[1] > 100


class _Systems(dict):
    def __missing__(self, name):
        self[name] = analogy.scene(name).system()
        return self[name]


@pytest.fixture(scope="module")
def systems():
    return _Systems()


@pytest.mark.parametrize("name", [n for n in SCENES if n != "random10"])      # random10: the element map
def test_both_diagrams_label_every_element_and_source_once(name, systems, tmp_path):
    system = systems[name]
    paths = diagram.draw(system, tmp_path, name, schematic=True)
    assert [p.name for p in paths] == [f"{name}_circuit.svg", f"{name}_circuit.png",
                                       f"{name}_mechanism.svg", f"{name}_mechanism.png"]
    for p in paths:
        assert p.is_file() and p.stat().st_size > 0
    assert_png(paths[1])
    assert_png(paths[3])
    expected = circuit_names(system)
    assert len(expected) == len(set(expected))
    assert labelled(paths[0], CIRCUIT_NAME) == Counter(expected)
    assert labelled(paths[2], MECHANISM_NAME) == Counter(mechanism_names(system))
    nodes = set(svg_texts(paths[0]))
    assert {f"n{k}" for k in range(1, system.dof + 1)} <= nodes


def test_a_dropped_element_is_detected(systems, tmp_path, monkeypatch):
    system = systems["serial2"]
    full = diagram.circuit

    def short(s, tol):          # the description with its first element missing
        c = full(s, tol)
        return type(c)(c.nodes, c.elements[1:], c.sources, c.initial, c.t_stop)
    monkeypatch.setattr(diagram, "circuit", short)
    diagram.draw_circuit(system, tmp_path / "short.svg")
    assert labelled(tmp_path / "short.svg", CIRCUIT_NAME) != Counter(circuit_names(system))


def test_negative_mp_capacitance_is_shown(systems, tmp_path):
    system = systems["serial2"]
    c12 = next(e for e in elements(system) if e.name == "C1_2")
    assert c12.value < 0
    diagram.draw_circuit(system, tmp_path / "c.svg")
    diagram.draw_mechanism(system, tmp_path / "m.svg")
    shown = f"= \u2212{abs(c12.value):.3g}"
    assert shown + " F" in svg_texts(tmp_path / "c.svg")
    assert shown + " kg\u00b7m\u00b2" in svg_texts(tmp_path / "m.svg")     # revolute joints: an inertia


@pytest.mark.parametrize("name", ["serial3", "parallel3", "random10"])
def test_every_part_is_wired_to_its_own_nodes(name, systems):
    system = systems[name]
    parts = diagram._parts(system, ZERO_TOL)
    layout = diagram._layout(parts, system.dof)
    assert sorted(item.part.name for item in layout.placed) == sorted(p.name for p in parts)

    def on_bar(x, node):
        x0, x1 = layout.bars[node - 1]
        return x0 - 1e-9 <= x <= x1 + 1e-9

    for item in layout.placed:
        p = item.part
        if p.b == 0:                       # hangs from its node down to ground
            assert item.hanging and item.ground is not None and on_bar(item.dots[0][0], p.a)
        elif item.dots:                    # a bridge: a riser from each of its two bars
            (xa, ya), (xb, yb) = item.dots
            assert ya == yb == 0.0 and on_bar(xa, p.a) and on_bar(xb, p.b)
        else:                              # on the rail between adjacent bars
            assert p.b == p.a + 1
            assert sorted([item.start[0], item.end[0]]) == [layout.bars[p.a - 1][1], layout.bars[p.b - 1][0]]


def test_sources_follow_the_netlist(systems):
    serial = {p.name: p for p in diagram._parts(systems["serial3"], ZERO_TOL) if p.kind == "I"}
    assert [(p.name, p.a, p.b) for p in serial.values()] == [("I1", 1, 0), ("I2", 1, 2), ("I3", 2, 3)]
    assert not serial["I2"].into_a              # 'I2 n1 n2': current out of n1, into n2
    parallel = [(p.name, p.a, p.b) for p in diagram._parts(systems["parallel3"], ZERO_TOL) if p.kind == "I"]
    assert parallel == [("I1", 1, 0), ("I2", 2, 0), ("I3", 3, 0)]


def test_suffix_selects_the_format(systems, tmp_path):
    system = systems["redundant"]
    d = diagram.draw_circuit(system, tmp_path / "only.png")
    assert (tmp_path / "only.png").is_file() and not (tmp_path / "only.svg").exists()
    assert d.elements
    diagram.draw_mechanism(system, tmp_path / "both")
    assert (tmp_path / "both.svg").is_file() and (tmp_path / "both.png").is_file()
    with pytest.raises(InputError):
        diagram.draw_circuit(system, tmp_path / "x.pdf")
    assert diagram.draw_circuit(system).elements   # no path: nothing written


def test_past_six_nodes_the_element_map_shows_every_element_once_with_its_sign(systems, tmp_path):
    """The map's cells carry every element's mechanical value; a schematic is not drawn."""
    system = systems["random10"]
    assert system.dof > diagram.MAX_SCHEMATIC_NODES
    paths = diagram.draw(system, tmp_path, "r10")
    assert [p.name for p in paths] == ["r10_elements.svg", "r10_elements.png"]
    assert_png(paths[1])
    image = matplotlib.image.imread(paths[1])
    assert max(image.shape[:2]) < 2000              # readable at full size, not a poster
    cells = [t for t in svg_texts(paths[0]) if re.fullmatch(r"[\u2212-]?[0-9.]+(e[\u2212+-]?\d+)?", t)]
    values = sorted(float(t.replace("\u2212", "-")) for t in cells)
    expected = sorted(float(f"{e.coefficient:.3g}" if not e.floating else f"{e.coefficient:.2g}")
                      for e in elements(system))
    assert len(values) >= len(expected)
    assert all(min(abs(v - x) for v in values) <= 1e-12 + 1e-9 * abs(x) for x in expected)
    assert any(v < 0 for v in values)               # negative MP capacitances are there, with their sign


def test_a_waveform_label_is_drawn_whole_over_lines_never_cut(tmp_path):
    forces = ("pulse(0, 2.5, 0.25, 0.1, 0.1, 1.5, 4)", "sine(0, 0.3, 1.5, 0.2, 0.1, 30)",
              "pwl(0, 0, 1, 0.5, 2, 0.25, 3, 1, 4, 0)")
    system = analogy.scene("serial3").replace(forces=forces).system()
    paths = diagram.draw(system, tmp_path, "long", schematic=True)
    for path in (paths[0], paths[2]):            # circuit and mechanism
        texts = [t.replace(" ", "") for t in svg_texts(path)]
        for force in forces:                    # on one line, or wrapped over two (in either order in the SVG)
            whole = force.replace(" ", "")
            assert any(whole in t for t in texts) or any(whole in a + b for a in texts for b in texts), force
        assert not [t for t in texts if "..." in t]


def test_with_gravity_each_source_is_labelled_with_its_own_term(tmp_path):
    """Gravity adds a step to each joint's force: a source per term, each labelled with its own
    waveform as a term of f_k, never with the whole force (which would count it twice)."""
    system = analogy.scene("serial2").replace(parameters=(("g", 9.81),), q=(0.3, 0.2)).system()
    paths = diagram.draw(system, tmp_path, "g", schematic=True)
    texts = svg_texts(paths[0]) + svg_texts(paths[2])
    for name, term in (("1", "step(1)"), ("1", "step(-35.0028)"), ("2", "sine(0, 0.5, 0.5)"), ("2", "step(-6.88727)")):
        assert sum(f"= {term} " in t and f"a term of f{name}" in t for t in texts) == 2, term     # circuit, mechanism
    assert not [t for t in texts if "= f1 =" in t or "= f2 =" in t]
    assert labelled(paths[0], CIRCUIT_NAME) == Counter([e.name for e in elements(system)]
                                                       + [src.name for src in circuit(system).sources])
