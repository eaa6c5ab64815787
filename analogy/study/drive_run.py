"""A drive run: the motors' netlist in ngspice beside the exact solution of the whole, per output, with its power balance."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError, SimulationError
from ..files import write_figure
from ..presets import Preset
from ..results.metrics import output_errors
from ..results.output import Tabular
from ..solvers.drive import Drive, drive_netlist, drive_settings, exact_drive, power_balance
from ..solvers.spice import run_netlist

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["DriveRun", "run_drive"]


@dataclass(frozen=True, eq=False)
class DriveRun(Tabular):
    """The joint rates and winding currents of a drive's netlist as ngspice ran it, against the exact
    solution where the voltages are steps, and its power balance.

    Attributes
    ----------
    drive : Drive
        What ran.
    netlist : str
        The netlist ngspice ran (what ``analogy drive -o`` writes).
    time : ndarray, shape (N,)
        ngspice's own points.
    rates, currents : ndarray, shape (N, n)
        Joint rates and winding currents (zero for a joint without a motor).
    exact_rates, exact_currents : ndarray or None
        The exact solution at the same points (None: the voltages are not steps).
    errors : dict of str to float
        Each output's largest error over its own peak (``r1``, ``i1`` …); empty without the exact solution.
    balance : ndarray, shape (N,)
        :func:`~analogy.solvers.drive.power_balance` of the run [W].
    bound : float
        The preset's bound.
    note : str
        How the run was retried after its step collapsed, if it was.
    """

    drive: Drive
    netlist: str
    time: np.ndarray
    rates: np.ndarray
    currents: np.ndarray
    exact_rates: np.ndarray | None
    exact_currents: np.ndarray | None
    errors: dict
    balance: np.ndarray
    bound: float
    note: str = ""

    @property
    def system(self):
        """The robot's circuit."""
        return self.drive.system

    def __repr__(self) -> str:
        worst = f", worst {max(self.errors.values()):.2g} of its peak" if self.errors else ""
        return (f"<DriveRun {self.system.provenance.robot}: {len(self.drive.driven)} motors, "
                f"{len(self.time)} points{worst}>")

    @property
    def power_in(self) -> np.ndarray:
        """Σ V·i, the power the drives put in [W]."""
        volts = np.column_stack([w(self.time) if w is not None else np.zeros_like(self.time)
                                 for w in self.drive.voltages])
        return np.sum(volts * self.currents, axis=1)

    @property
    def balance_error(self) -> float:
        """The power balance's largest residual over the largest power put in."""
        peak = float(np.max(np.abs(self.power_in)))
        return float(np.max(np.abs(self.balance))) / peak if peak > 0 else 0.0

    def over_limits(self) -> dict[str, str]:
        """Each motor whose winding carried more than its current limit, and by how much."""
        out = {}
        for j in self.drive.driven:
            limit, peak = self.drive.motors[j].current_limit, float(np.max(np.abs(self.currents[:, j])))
            if peak > limit:
                out[f"i{j + 1}"] = f"{peak:.3g} A, past its limit of {limit:g} A"
        return out

    def outside_bound(self) -> dict[str, float]:
        """The outputs past the preset's bound, with their errors."""
        return {k: e for k, e in self.errors.items() if e > self.bound}

    def table(self) -> str:
        """One line per output: its peak, and its error over its own peak against the exact solution."""
        joints = self.system.provenance.joints or [f"q{j + 1}" for j in range(self.system.dof)]
        lines = [f"{'output':<28}{'peak':>12}{'error / peak':>16}"]
        for j in range(self.system.dof):
            for key, values, unit in ((f"r{j + 1}", self.rates[:, j], "rate"), (f"i{j + 1}", self.currents[:, j], "A")):
                if key.startswith("i") and j not in self.drive.driven:
                    continue
                what = f"{key} ({joints[j]} {'rate' if unit == 'rate' else 'winding'})"
                err = f"{self.errors[key]:.2e}" if key in self.errors else "no exact"
                lines.append(f"{what:<28}{np.max(np.abs(values)):>12.4g}{err:>16}")
        lines.append(f"power balance: largest residual {self.balance_error:.2e} of the largest power put in "
                     f"({np.max(np.abs(self.power_in)):.4g} W)")
        return "\n".join(lines)

    def columns(self) -> dict[str, np.ndarray]:
        """``time``, each joint's rate ``r<j>_spice`` and each winding's current ``i<j>_spice``, and the exact ones."""
        cols: dict[str, np.ndarray] = {"time": self.time}
        for j in range(self.system.dof):
            cols[f"r{j + 1}_spice"] = self.rates[:, j]
            if self.exact_rates is not None:
                cols[f"r{j + 1}_exact"] = self.exact_rates[:, j]
        for j in self.drive.driven:
            cols[f"i{j + 1}_spice"] = self.currents[:, j]
            if self.exact_currents is not None:
                cols[f"i{j + 1}_exact"] = self.exact_currents[:, j]
        return cols

    def plot(self, path=None) -> "Figure":
        """Joint rates and winding currents, SPICE over the exact solution.

        Parameters
        ----------
        path : str or Path, optional
            Write it as PNG or SVG.
        """
        from matplotlib.figure import Figure
        fig = Figure(figsize=(10.0, 6.0), layout="constrained")
        rates, currents = fig.subplots(2, 1, sharex=True)
        for ax, values, exact, label, which in ((rates, self.rates, self.exact_rates, "joint rate", range(self.system.dof)),
                                                (currents, self.currents, self.exact_currents, "winding current [A]",
                                                 self.drive.driven)):
            for j in which:
                line, = ax.plot(self.time, values[:, j], lw=1.0, label=f"{j + 1}: spice")
                if exact is not None:
                    ax.plot(self.time, exact[:, j], lw=4.0, alpha=0.3, color=line.get_color(), label=f"{j + 1}: exact")
            ax.set_ylabel(label)
            ax.legend(fontsize=7, ncol=4)
        currents.set_xlabel("t [s]")
        fig.suptitle(f"{self.system.provenance.robot} driven by its motors", fontsize=10)
        if path is not None:
            write_figure(fig, path)
        return fig


def run_drive(d: Drive, preset: Preset) -> DriveRun:
    """Run *d*'s netlist in ngspice and measure it against the exact solution (where its voltages are steps).

    Parameters
    ----------
    d : Drive
        The drive.
    preset : Preset
        The accuracy preset.
    """
    n = d.system.dof
    names = ["time"] + [f"v(p{j + 1})" for j in range(n)] + [f"vs{j + 1}#branch" for j in d.driven]
    ladder, note = drive_settings(d, preset).retries(), ""
    for k, settings in enumerate(ladder):       # a collapsed step: the next settings, said in the note
        text = drive_netlist(d, preset, settings=settings)
        try:
            data = run_netlist(text, names)
            break
        except SimulationError as exc:
            if "time step too small" not in str(exc) or k == len(ladder) - 1:
                raise
            note = f"retried with {'gear' if ladder[k + 1].method != settings.method else 'looser abstol and vntol'} ({exc})"
    r0 = d.system.joint_rates(d.system.initial_voltages)
    t = np.concatenate([[0.0], data["time"]]) if data["time"][0] > 0 else data["time"]
    first = len(t) - len(data["time"])         # t = 0 added where ngspice's points start after it
    rates = np.column_stack([np.concatenate([r0[j:j + 1]] * first + [data[f"v(p{j + 1})"]]) for j in range(n)])
    currents = np.zeros_like(rates)
    for j in d.driven:
        m = d.motors[j]
        at_start = 0.0 if m.inductance else (float(d.voltages[j](0.0)) - m.ratio * r0[j]) / m.resistance
        currents[:, j] = np.concatenate([[at_start]] * first + [data[f"vs{j + 1}#branch"]])
    try:
        exact_r, exact_i = exact_drive(d, t)
    except InputError:                      # voltages that are not steps: no exact solution here
        exact_r = exact_i = None
    errors = {}
    if exact_r is not None:
        for key, got, want in [(f"r{j + 1}", rates[:, j], exact_r[:, j]) for j in range(n)] + \
                [(f"i{j + 1}", currents[:, j], exact_i[:, j]) for j in d.driven]:
            errors[key] = float(output_errors(got[:, None], want[:, None])[1][0])
    return DriveRun(d, text, t, rates, currents, exact_r, exact_i, errors, power_balance(d, t, rates, currents),
                    preset.bound, note)
