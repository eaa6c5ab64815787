"""Running a scene: exactly what its outputs need, through the one orchestrator, and its files."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..files import write_text
from ..solvers.transient import netlist as make_netlist
from ..errors import InputError, located
from ..study.comparison import Comparison, compare
from ..results.metrics import output_errors
from ..results.output import Tabular, html_table
from .build import placed
from .scene import Scene

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..study.drive_run import DriveRun

__all__ = ["SceneResult", "run_scene", "save_names"]


def save_names(scene: Scene, system) -> list[str]:
    """Node and element names for the netlist's ``.save``: exactly what the outputs need.

    Parameters
    ----------
    scene : Scene
        A validated scene (names canonical).
    system : NodeSystem
        Its system.
    """
    if not scene.needs_solver:
        return list(system.nodes)
    nodes = list(system.nodes) if scene.joint_rates else list(scene.node_voltages)
    return nodes + list(scene.element_currents)


def run_scene(scene: Scene, output_dir=None, progress=None) -> "SceneResult":
    """Compute exactly what *scene*'s outputs require and write its files.

    Relative file names go to *output_dir* if given, else next to the scene file. A
    failing solver is recorded in :attr:`SceneResult.failures`; the others still run.

    Parameters
    ----------
    scene : Scene
        A validated scene (:func:`~analogy.scenes.toml.load_scene` gives one).
    output_dir : str or Path, optional
        Folder for the scene's output files.
    progress : callable, optional
        Told of each solver as it starts (see :func:`~analogy.study.comparison.compare`).
    """
    if not isinstance(scene, Scene):
        raise InputError(f"run_scene takes a Scene, got {type(scene).__name__}: read a file with load_scene(path)")
    # Every output path is checked before any work, so a refused one costs nothing.
    for key, name in (("netlist", scene.netlist_file), ("csv", scene.csv_file), ("plot", scene.plot_file)):
        if name:
            with located(scene.source), located(f"[outputs] {key}"):
                scene.path(name, output_dir)
    p = scene.settings
    if scene.motors:
        return _run_drive(scene, output_dir)
    system = scene.system()
    result = SceneResult(scene, system)
    save = save_names(scene, system)
    title = f"analogy scene {scene.name}" + (f": {scene.description}" if scene.description else "")

    def write_netlist(settings=None) -> None:
        text = make_netlist(system, p, save=save, title=title, settings=settings)
        if text == result.netlist:
            return
        result.netlist = text
        if scene.netlist_file:
            path = _write_text(scene.path(scene.netlist_file, output_dir), result.netlist)
            if path not in result.written:
                result.written.append(path)
    if scene.netlist:
        write_netlist()             # written before any run, so a failing solver loses nothing
    if not scene.solvers:
        return result
    reference = "auto" if scene.errors else ("exact" if "exact" in scene.solvers else None)
    currents = list(scene.element_currents)
    comparison = compare(system, p, scene.solvers, reference=reference, step=scene.step,
                         save=currents, positions=bool(currents), progress=progress, estimate=scene.estimate,
                         refine=scene.refine)
    spice = comparison.results.get("spice")
    if scene.netlist and spice is not None and spice.settings is not None:
        write_netlist(spice.settings)   # what ran, where it differs: a retry's settings, or a refined run's
    result.solved = comparison
    _write_outputs(scene, output_dir, result, result)
    return result


def _write_outputs(scene: Scene, output_dir, result: "SceneResult", source) -> None:
    """The scene's CSV and plot of *source* (its result, or its drive's run), in *result*'s written files."""
    try:
        if scene.csv_file:          # a scene's files may sit in subfolders of its output folder
            path = scene.path(scene.csv_file, output_dir)
            path.parent.mkdir(parents=True, exist_ok=True)
            result.written.append(Path(source.to_csv(path)))
        if scene.plot_file:
            path = scene.path(scene.plot_file, output_dir)
            path.parent.mkdir(parents=True, exist_ok=True)
            source.plot(path)
            result.written.append(path)
    except OSError as exc:
        raise InputError(f"cannot write output: {exc}") from None


def _run_drive(scene: Scene, output_dir) -> "SceneResult":
    """A scene of motors: the drive's run (ngspice, the ODE, the exact solution) and its files."""
    from ..study.drive_run import run_drive, scene_drive
    with placed(scene):
        d = scene_drive(scene)
        run = run_drive(d, scene.settings, tuple(scene.solvers))
    result = SceneResult(scene, d.system)
    result.drive, result.netlist = run, run.netlist
    if scene.netlist_file:
        result.written.append(_write_text(scene.path(scene.netlist_file, output_dir), run.netlist))
    _write_outputs(scene, output_dir, result, run)
    return result


def _write_text(path: Path, text: str) -> Path:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text(path, text)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path


@dataclass(eq=False)
class SceneResult(Tabular):
    """What a scene asked for, computed.

    Attributes
    ----------
    scene : Scene
        The scene that was run.
    system : NodeDynamics
        Its node system.
    solved : Comparison or None
        Every solver the scene ran, one record each; the figures below are read from it.
    netlist : str or None
        The netlist text, when asked for.
    written : list of Path
        Files written.
    drive : DriveRun or None
        A scene of motors: its drive's run (joint rates and winding currents per solver).
    """

    scene: Scene
    system: object = None
    solved: Comparison | None = None
    netlist: str | None = None
    written: list = field(default_factory=list)
    drive: "DriveRun | None" = None

    @property
    def comparison(self) -> Comparison | None:
        """Joint rates of every solver, when the scene asks for them."""
        return self.solved if self.scene.joint_rates else None

    @property
    def time(self) -> np.ndarray | None:
        """Shared time points of every solver (SPICE's own when it ran and no step was set)."""
        return None if self.solved is None else self.solved.time

    @property
    def failures(self) -> dict[str, str]:
        """Solvers that failed, with the reason."""
        return {} if self.solved is None else self.solved.failures

    @property
    def reference(self) -> str | None:
        """The solver errors are measured against."""
        return None if self.solved is None else self.solved.reference

    @property
    def run_times(self) -> dict[str, float]:
        """Seconds per solver that ran."""
        return {} if self.solved is None else {n: tr.run_time for n, tr in self.solved.results.items()}

    @property
    def node_voltages(self) -> dict[str, dict[str, np.ndarray]]:
        """``{solver: {node: values}}`` for the requested nodes."""
        nodes = self.scene.node_voltages
        if self.solved is None or not nodes:
            return {}
        return {s: {n: tr.voltages[:, int(n[1:]) - 1] for n in nodes} for s, tr in self.solved.results.items()}

    @property
    def element_currents(self) -> dict[str, dict[str, np.ndarray]]:
        """``{solver: {element: values}}`` for the requested elements (current from a to b)."""
        names = self.scene.element_currents
        if self.solved is None or not names:
            return {}
        return {s: {e: tr.currents[e] for e in names} for s, tr in self.solved.results.items()}

    @property
    def ok(self) -> bool:
        """True if no solver failed."""
        return not self.failures

    @property
    def solvers(self) -> list[str]:
        """Solvers that produced results, in run order."""
        return list(self.run_times)

    def __repr__(self) -> str:
        files = f", wrote {len(self.written)} file{'s' if len(self.written) > 1 else ''}" if self.written else ""
        failed = f", {len(self.failures)} failed" if self.failures else ""
        return f"<SceneResult {self.scene.name}: {', '.join(self.solvers) or 'no solver'}{failed}{files}>"

    def _repr_html_(self) -> str:
        rows = [[q, s, e, r] for q, by in self.errors().items() for s, (e, r) in by.items()]
        return html_table(["quantity", "solver", "max |error|", "error / peak"], rows)

    def _groups(self) -> list[tuple[str, dict]]:
        """(quantity, {solver: {name: values}}) for every requested quantity."""
        groups = []
        if self.comparison is not None:
            named = self.system.provenance.output_name
            rates = {s: {named(f"r{j + 1}"): tr.rates[:, j] for j in range(self.system.dof)}
                     for s, tr in self.comparison.results.items()}
            groups.append(("joint rates", rates))
        if self.scene.node_voltages:
            groups.append(("node voltages", self.node_voltages))
        for kind in "CRL":
            names = [e for e in self.scene.element_currents if e[0] == kind]
            if names:
                groups.append((f"{kind} currents", {s: {e: vals[e] for e in names}
                                                    for s, vals in self.element_currents.items()}))
        return groups

    def errors(self) -> dict:
        """``{quantity: {solver: (max |x − x_ref|, that / peak |x_ref|)}}``.

        Joint rates are measured on each solver's own points (see
        :class:`~analogy.study.comparison.Comparison`); node voltages and element
        currents on the shared time points. Empty without a reference.
        """
        out: dict = {}
        ref_name = self.reference
        if ref_name is None:
            return out
        for quantity, by_solver in self._groups():
            ref = by_solver.get(ref_name)
            if ref is None:
                continue
            if quantity == "joint rates":
                out[quantity] = self.comparison.errors()
                continue
            names = list(ref)
            y = np.column_stack([ref[k] for k in names])
            out[quantity] = {}
            for s, vals in by_solver.items():       # each output against its own peak, as the joint rates
                err, rel = output_errors(np.column_stack([vals[k] for k in names]), y, self.scene.settings.bound)
                out[quantity][s] = (float(np.max(err)), float(np.max(rel)))
        return out

    def max_relative_error(self, solver: str) -> float:
        """Worst error / peak of *solver* over every requested quantity.

        Parameters
        ----------
        solver : str
            A solver that ran.
        """
        vals = [by[solver][1] for by in self.errors().values() if solver in by]
        return max(vals) if vals else math.nan

    def table(self) -> str:
        """Plain-text summary: solvers, run times, errors against the reference, files."""
        sc, system = self.scene, self.system
        heading = f"scene {sc.name}" + (f": {sc.description}" if sc.description else "")
        lines = [" ".join(heading.split())]         # a name or description prints as one line
        if self.drive is not None:
            return "\n".join(lines + [self.drive.table()])
        referenced = self.comparison is not None and self.reference is not None
        if self.comparison is not None:
            lines.append(self.comparison.table())
        elif sc.solvers:
            n = 0 if self.time is None else self.time.size
            lines.append(f"robot {system.provenance.robot}, topology {system.topology.name}, "
                         f"preset {sc.preset}, {n} time points; "
                         + (f"errors against the {self.reference} solution" if self.reference
                            else "no reference, so no errors measured"))
            lines.append(f"{'solver':<10}{'run time [ms]':>15}")
            for s, seconds in self.run_times.items():
                lines.append(f"{s:<10}{seconds * 1e3:>15.3f}")
            for s, why in self.failures.items():
                lines.append(f"{s:<10}  failed: {why}")
        groups = [g for g in self._groups() if not (referenced and g[0] == "joint rates")]
        if groups:
            errs = self.errors()
            if sc.node_voltages:
                lines.append("node voltages: " + ", ".join(sc.node_voltages))
            if sc.element_currents:
                lines.append("element currents (a to b): " + ", ".join(sc.element_currents))
            lines.append(f"{'quantity':<16}{'solver':<10}{'peak':>12}{'max |error|':>14}{'error / peak':>14}")
            for quantity, by_solver in groups:
                for s, vals in by_solver.items():
                    top = max(float(np.max(np.abs(x))) for x in vals.values())
                    if quantity in errs and s in errs[quantity]:
                        e, r = errs[quantity][s]
                        tail = f"{e:>14.3e}{r:>14.3e}" + ("  (reference)" if s == self.reference else "")
                    else:
                        tail = f"{'-':>14}{'-':>14}"
                    lines.append(f"{quantity:<16}{s:<10}{top:>12.6g}{tail}")
        if sc.netlist:
            count = len(self.netlist.splitlines()) if self.netlist else 0
            lines.append(f"netlist: {count} lines, saves {', '.join(save_names(sc, system))}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()

    def columns(self) -> dict[str, np.ndarray]:
        """``time``, then per solver its joint rates ``r1_spice`` …, node voltages
        ``v_n1_spice`` … and element currents ``i_C1_2_spice`` …"""
        if self.time is None:
            raise InputError("no solver ran: nothing to write")
        cols = {"time": self.time}
        groups = self._groups()
        for s in self.solvers:
            for quantity, by_solver in groups:
                prefix = {"joint rates": "", "node voltages": "v_"}.get(quantity, "i_")
                for name, vals in (by_solver.get(s) or {}).items():
                    cols[f"{prefix}{name}_{s}"] = vals
        return cols

    def plot(self, path=None) -> "Figure":
        """One panel per requested quantity and, with a reference, each solver's error / peak.

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        """
        from ..results.plots import plot_quantities
        return plot_quantities(self.time, self._groups(), self.errors(),
                               f"scene {self.scene.name}: preset {self.scene.preset}", path,
                               self.reference, units=self.system.provenance.units)
