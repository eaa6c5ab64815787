"""A netlist as a KiCad schematic: each element a symbol carrying its own SPICE line, the nets by label."""

from __future__ import annotations

import math
import uuid

from .netlist_lines import NetlistLine, netlist_lines

__all__ = ["kicad_schematic"]

#: KiCad 9's schematic file version (``kicad-cli`` 9 reads it; KiCad 8 refuses newer files).
_VERSION = 20250114
_GRID = 2.54                    # KiCad's 100 mil grid [mm]
_FONT = "(effects (font (size 1.27 1.27)))"
_HIDDEN = "(effects (font (size 1.27 1.27)) hide)"
_LEFT = "(effects (font (size 1.27 1.27)) (justify left))"
#: Each kind's drawing, in KiCad's symbol coordinates (y up, mm), between pins at y = ±5.08.
_BODIES = {
    "R": "(rectangle (start -1.016 -2.54) (end 1.016 2.54) (stroke (width 0.254) (type default)) (fill (type none)))",
    "C": ("(polyline (pts (xy -2.032 0.762) (xy 2.032 0.762)) (stroke (width 0.508) (type default)) (fill (type none)))"
          "(polyline (pts (xy -2.032 -0.762) (xy 2.032 -0.762)) (stroke (width 0.508) (type default)) "
          "(fill (type none)))(polyline (pts (xy 0 2.54) (xy 0 0.762)) (stroke (width 0) (type default)) "
          "(fill (type none)))(polyline (pts (xy 0 -2.54) (xy 0 -0.762)) (stroke (width 0) (type default)) "
          "(fill (type none)))"),
    "L": "".join(f"(arc (start 0 {y + 1.27:g}) (mid 0.635 {y + 0.635:g}) (end 0 {y:g}) (stroke (width 0) "
                 "(type default)) (fill (type none)))" for y in (1.27, 0.0, -1.27, -2.54)),
    "source": ("(circle (center 0 0) (radius 2.54) (stroke (width 0.254) (type default)) (fill (type none)))"
               "(polyline (pts (xy 0 -1.524) (xy 0 1.524)) (stroke (width 0) (type default)) (fill (type none)))"
               "(polyline (pts (xy -0.762 0.508) (xy 0 1.524) (xy 0.762 0.508)) (stroke (width 0) "
               "(type default)) (fill (type none)))"),
    "V": ("(circle (center 0 0) (radius 2.54) (stroke (width 0.254) (type default)) (fill (type none)))"
          f"(text \"+\" (at 0 1.27 0) {_FONT})(text \"-\" (at 0 -1.27 0) {_FONT})"),
    "dependent": ("(polyline (pts (xy 0 2.54) (xy 2.54 0) (xy 0 -2.54) (xy -2.54 0) (xy 0 2.54)) "
                  "(stroke (width 0.254) (type default)) (fill (type none)))"),
    "ground": ("(polyline (pts (xy 0 0) (xy 0 -1.27) (xy 1.27 -1.27) (xy 0 -2.54) (xy -1.27 -1.27) (xy 0 -1.27)) "
               "(stroke (width 0) (type default)) (fill (type none)))"),
}
_KIND_OF = {"R": "R", "C": "C", "L": "L", "I": "source", "B": "source", "V": "V",
            "E": "dependent", "F": "dependent", "G": "dependent", "H": "dependent"}


def _quoted(text: str) -> str:
    """*text* as an S-expression string."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _pins(count: int) -> list[tuple[float, float]]:
    """Pin ends in symbol coordinates: + above, − below; a controlling pair to the right."""
    ends = [(0.0, 5.08), (0.0, -5.08)]
    return ends if count == 2 else ends + [(5.08, 5.08), (5.08, -5.08)]


def _symbol_definition(kind: str, count: int) -> str:
    pins = "".join(f"(pin passive line (at {x:g} {y:g} {270 if y > 0 else 90}) (length 2.54) "
                   f"(name \"~\" {_FONT}) (number \"{k + 1}\" {_FONT}))" for k, (x, y) in enumerate(_pins(count)))
    name = f"{kind}{count}"
    return (f"(symbol \"analogy:{name}\" (pin_numbers hide) (pin_names (offset 0) hide) (exclude_from_sim no) "
            f"(in_bom no) (on_board no) (property \"Reference\" \"{kind[0].upper()}\" (at 3.81 1.27 0) {_LEFT}) "
            f"(property \"Value\" \"\" (at 3.81 -1.27 0) {_LEFT}) (property \"Footprint\" \"\" (at 0 0 0) {_HIDDEN}) "
            f"(property \"Datasheet\" \"\" (at 0 0 0) {_HIDDEN}) (symbol \"{name}_0_1\" {_BODIES[kind]}) "
            f"(symbol \"{name}_1_1\" {pins}))")


def _ground_definition() -> str:
    return ("(symbol \"analogy:ground\" (power) (pin_names (offset 0) hide) (exclude_from_sim no) (in_bom no) "
            f"(on_board no) (property \"Reference\" \"#GND\" (at 0 -6.35 0) {_HIDDEN}) "
            f"(property \"Value\" \"0\" (at 0 -3.81 0) {_FONT}) (property \"Footprint\" \"\" (at 0 0 0) {_HIDDEN}) "
            f"(property \"Datasheet\" \"\" (at 0 0 0) {_HIDDEN}) (symbol \"ground_0_1\" {_BODIES['ground']}) "
            f"(symbol \"ground_1_1\" (pin power_in line (at 0 0 270) (length 0) hide (name \"0\" {_FONT}) "
            f"(number \"1\" {_FONT}))))")


def _shown(model: str, limit: int = 28) -> str:
    """A part's value as drawn: numbers to 6 digits, long expressions cut (the SPICE line keeps all)."""
    words = []
    for word in model.split():
        try:
            words.append(f"{float(word):.6g}")
        except ValueError:
            words.append(word)
    text = " ".join(words)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _kept(model: str) -> str:
    """*model* as KiCad keeps it: KiCad 9 rewrites a bare negative number to six digits (-764.269m),
    so a negative value goes in braces, which SPICE reads as the same number."""
    try:
        negative = float(model) < 0
    except ValueError:
        return model
    return f"{{{model}}}" if negative else model


class _Sheet:
    """Placed symbols, labels and texts, with fresh identifiers under one root sheet."""

    def __init__(self, project: str, netlist: str):
        # identifiers from the netlist's content, rising in its order: the same netlist gives the
        # same file, and KiCad, which lists the parts by identifier, lists them in the netlist's order
        self.stem = uuid.uuid5(uuid.NAMESPACE_URL, f"analogy:{project}:{netlist}").hex[:20]
        self.count, self.project, self.items, self.grounds = 0, project, [], 0
        self.root = self.uuid()

    def uuid(self) -> str:
        """The next identifier."""
        self.count += 1
        h = f"{self.stem}{self.count:012x}"
        return f"{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:]}"

    def net(self, name: str, x: float, y: float, above: bool) -> None:
        if name == "0":             # the SPICE ground: KiCad's power symbol of that name
            self.grounds += 1
            at = f"{x:g} {y:g} {0 if not above else 180}"
            self.items.append(f"(symbol (lib_id \"analogy:ground\") (at {at}) (unit 1) (exclude_from_sim no) "
                              f"(in_bom no) (on_board no) (dnp no) (uuid \"{self.uuid()}\") "
                              f"(property \"Reference\" \"#GND{self.grounds:04d}\" (at {x:g} {y:g} 0) {_HIDDEN}) "
                              f"(property \"Value\" \"0\" (at {x:g} {y:g} 0) {_HIDDEN}) "
                              f"(pin \"1\" (uuid \"{self.uuid()}\")) (instances (project {_quoted(self.project)} "
                              f"(path \"/{self.root}\" (reference \"#GND{self.grounds:04d}\") (unit 1)))))")
            return
        self.items.append(f"(global_label {_quoted(name)} (shape passive) (at {x:g} {y:g} {90 if above else 270}) "
                          f"(effects (font (size 1.27 1.27)) (justify {'left' if above else 'right'})) "
                          f"(uuid \"{self.uuid()}\"))")

    def part(self, line: NetlistLine, kind: str, x: float, y: float) -> None:
        count = len(line.nodes)
        params = f'type="{line.name[0].upper()}" model={_quoted(_kept(line.model))} lib=""'
        pins = " ".join(f"{k}={k}" for k in range(1, count + 1))
        fields = [("Reference", line.name, _LEFT, 3.81, -1.27), ("Value", _shown(line.model), _LEFT, 3.81, 1.27),
                  ("Footprint", "", _HIDDEN, 0, 0), ("Datasheet", "", _HIDDEN, 0, 0),
                  ("Sim.Device", "SPICE", _HIDDEN, 0, 0), ("Sim.Params", params, _HIDDEN, 0, 0),
                  ("Sim.Pins", pins, _HIDDEN, 0, 0)]
        props = " ".join(f"(property \"{k}\" {_quoted(v)} (at {x + dx:g} {y + dy:g} 0) {look})"
                         for k, v, look, dx, dy in fields)
        self.items.append(f"(symbol (lib_id \"analogy:{kind}{count}\") (at {x:g} {y:g} 0) (unit 1) "
                          f"(exclude_from_sim no) (in_bom no) (on_board no) (dnp no) (uuid \"{self.uuid()}\") "
                          f"{props} " + " ".join(f"(pin \"{k}\" (uuid \"{self.uuid()}\"))" for k in range(1, count + 1))
                          + f" (instances (project {_quoted(self.project)} (path \"/{self.root}\" "
                          f"(reference {_quoted(line.name)}) (unit 1)))))")
        for node, (px, py) in zip(line.nodes, _pins(count)):
            self.net(node, x + px, y - py, py > 0)      # the sheet's y runs down

    def text(self, body: str, x: float, y: float) -> None:
        self.items.append(f"(text {_quoted(body)} (exclude_from_sim no) (at {x:g} {y:g} 0) "
                          f"(effects (font (size 1.27 1.27)) (justify left top)) (uuid \"{self.uuid()}\"))")


def kicad_schematic(netlist: str, project: str = "analogy") -> str:
    """The netlist *netlist* as a KiCad 9 schematic (``.kicad_sch``) that simulates as it does.

    Each element is a symbol whose fields carry its SPICE line whole (KiCad's raw SPICE
    model: ``Sim.Device`` = SPICE, ``Sim.Params`` its type and the rest of its line), drawn
    with its value; each node is a global label of the node's name at the pins on it, and
    ground is KiCad's power symbol ``0``. The analysis lines are text directives, which
    KiCad's simulator and ``kicad-cli sch export netlist --format spice`` pass through; the
    comment header is a note. KiCad's netlist of it therefore lists the same elements with
    the same values, nodes and analysis as *netlist* (checked in the deep tests). Every
    line of the note is a SPICE comment, so no text of the header can be read as a directive.

    Parameters
    ----------
    netlist : str
        A netlist as :func:`~analogy.solvers.transient.netlist` writes it.
    project : str
        The project name the symbols' instances are recorded under.
    """
    parsed = netlist_lines(netlist)
    columns = max(4, math.ceil(math.sqrt(len(parsed.elements) * 1.6)))
    pitch_x, pitch_y, line = 10 * _GRID, 12 * _GRID, 0.9 * _GRID        # a text line's height
    sheet = _Sheet(project, netlist)
    if parsed.comments:
        sheet.text("\n".join(f"* {c}" for c in parsed.comments), 10 * _GRID, 8 * _GRID)     # SPICE comments
    top = 16 * _GRID + line * len(parsed.comments)
    for k, part in enumerate(parsed.elements):
        sheet.part(part, _KIND_OF[part.name[0].upper()], 10 * _GRID + pitch_x * (k % columns),
                   top + pitch_y * (k // columns))
    y = top + pitch_y * math.ceil(len(parsed.elements) / columns)
    for block in parsed.directives:
        sheet.text(block, 10 * _GRID, y)
        y += line * (block.count("\n") + 1) + _GRID
    width, height = 20 * _GRID + pitch_x * columns, y + 30 * _GRID     # room for the title block
    used = sorted({(_KIND_OF[line.name[0].upper()], len(line.nodes)) for line in parsed.elements})
    library = " ".join([_symbol_definition(kind, count) for kind, count in used] + [_ground_definition()])
    return "\n".join([f"(kicad_sch (version {_VERSION}) (generator \"analogy\") (generator_version \"1\") "
                      f"(uuid \"{sheet.root}\") (paper \"User\" {max(width, 297):.0f} {max(height, 210):.0f})",
                      f"(title_block (title {_quoted(parsed.comments[0] if parsed.comments else project)}))",
                      f"(lib_symbols {library})", *sheet.items,
                      "(sheet_instances (path \"/\" (page \"1\"))))"]) + "\n"
