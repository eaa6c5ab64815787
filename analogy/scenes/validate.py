"""A parsed scene checked against its own system: node and element names made canonical."""

from __future__ import annotations

from ..circuit.currents import check_element_names
from ..circuit.description import circuit
from ..errors import InputError, located
from .build import COMMAND_LINE, placed
from .scene import Scene

__all__ = ["validated"]


def _check_nodes(system, names) -> tuple[str, ...]:
    nodes = system.nodes
    out = []
    for name in names:
        if not isinstance(name, str) or name not in nodes:
            raise InputError(f"unknown node {name!r}: nodes are {', '.join(nodes)}")
        out.append(name)
    if not out:
        raise InputError("name at least one node (or write true for all)")
    return tuple(dict.fromkeys(out))


def validated(scene: Scene) -> Scene:
    """*scene* with its outputs checked against its system (built here) and names made canonical.

    ``node_voltages = true`` becomes every node and ``element_currents = true`` every
    element; an unknown name is an :class:`InputError` naming the key.

    Parameters
    ----------
    scene : Scene
        A parsed scene.
    """
    system = scene.system()
    changes = {}
    with located(scene.source if scene.source not in (None, COMMAND_LINE) else None):
        with located("[outputs] node_voltages"):
            nv = scene.node_voltages
            changes["node_voltages"] = tuple(system.nodes) if nv is True else \
                (_check_nodes(system, nv) if nv else ())
        with located("[outputs] element_currents"):
            ec = scene.element_currents
            if ec and system.kind != "linear":
                raise InputError("element currents need the linear circuit (dynamics = \"linear\")")
            if ec is True:
                changes["element_currents"] = tuple(e.name for e in circuit(system).parts)
            else:
                changes["element_currents"] = check_element_names(system, ec) if ec else ()
        if scene.motors and (ec or nv):
            raise InputError("a drive's outputs are its joint rates and winding currents: node_voltages "
                             "and element_currents do not apply to it")
    if scene.motors:                # each table's joint and each motor's voltage, before any run
        from ..study.drive_run import scene_drive
        with placed(scene):
            scene_drive(scene)
    return scene.replace(**changes)
