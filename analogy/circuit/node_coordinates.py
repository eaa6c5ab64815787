"""What every node system shares: node names, v = T·r, its forces in time, and immutability once built."""

from __future__ import annotations

import copy
from functools import cached_property
from typing import Iterator, TypeVar

import numpy as np

from ..errors import InputError, concerning
from ..model.joint import check_vector
from .joint_forces import force_breakpoints, joint_forces, waveforms

__all__ = ["NodeCoordinates", "check_t_stop", "output_times"]


_System = TypeVar("_System", bound="NodeCoordinates")


def _cached_names(cls: type) -> list[str]:
    """The names of *cls*'s cached properties: what a system derives from its inputs."""
    return [name for klass in cls.__mro__ for name, value in vars(klass).items() if isinstance(value, cached_property)]


def check_t_stop(t_stop) -> float:
    """*t_stop* as a float, refused in one sentence outside 1 ns to 1e9 s.

    Parameters
    ----------
    t_stop : float
        End of the simulated interval [s].
    """
    try:
        t = float(t_stop)
    except (TypeError, ValueError):
        t = float("nan")
    if not (np.isfinite(t) and 1e-9 <= t <= 1e9):
        raise InputError("t_stop must be a time between 1e-9 s and 1e9 s", field="t_stop")
    return t


class NodeCoordinates:
    """What every node system shares: node names, v = T·r, the forces and their segments in time.

    A subclass sets ``topology``, ``current_map``, ``forces``, ``t_stop`` and ``dof``, then
    calls :meth:`_seal`. A sealed system is immutable: its attributes cannot be set and its
    arrays are read-only. :meth:`driven` and :meth:`realized` make new systems. What is
    derived from the inputs is a ``cached_property``, and a new system starts without them.
    """

    def __setattr__(self, name: str, value) -> None:
        if "_sealed" in self.__dict__:
            raise AttributeError(f"a {type(self).__name__} is immutable: {name} is changed by making another "
                                 "system (driven(), realized())")
        object.__setattr__(self, name, value)

    def _seal(self) -> None:
        """Make the arrays read-only and refuse any later attribute (constructors end with it)."""
        for value in self.__dict__.values():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
        self.__dict__["_sealed"] = True

    def _replaced(self: _System, **changes) -> _System:
        """A copy of this system with *changes*, and none of the values cached from its inputs."""
        out = copy.copy(self)
        state = out.__dict__
        for name in _cached_names(type(self)):
            state.pop(name, None)
        state.update(changes)
        for value in changes.values():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
        return out

    @cached_property
    def segment_ends(self) -> np.ndarray:
        """Segment ends 0 < t_1 < … < t_stop between which every force is smooth (read-only)."""
        points = force_breakpoints(self.forces, self.t_stop)
        points.setflags(write=False)
        return points

    @cached_property
    def inputs_key(self) -> tuple:
        """What the system is driven by, as a hashable value: topology, forces and t_stop.

        Systems with equal keys share their current sources and time segments, so a solver
        derives those once for all of them.
        """
        return (self.topology.key, tuple(tuple(w.key() for w in ws) for ws in self.forces), self.t_stop)

    @property
    def nodes(self) -> list[str]:
        """SPICE node names, n1 … nN."""
        return [f"n{k + 1}" for k in range(self.dof)]

    def node_currents(self, t) -> np.ndarray:
        """Node currents i(t) = T⁻ᵀ·F(t), shape (len(t), n).

        Parameters
        ----------
        t : float or array_like
            Times.
        """
        return self.force(t) @ self.current_map.T

    def joint_rates(self, node_voltages: np.ndarray) -> np.ndarray:
        """R = T⁻¹·v for node voltages of shape (..., n).

        Parameters
        ----------
        node_voltages : ndarray, shape (..., n)
            Node velocities v.
        """
        return self.topology.joint_rates(node_voltages)

    def time_points(self, times=None, default: int = 1001) -> np.ndarray:
        """Sorted output times in [0, t_stop] (default: uniform); a time a rounding past
        t_stop, as SPICE's last point can be, is taken as t_stop.

        Parameters
        ----------
        times : array_like, optional
            Requested times.
        default : int
            Number of uniform points without *times*.
        """
        return output_times(self.t_stop, times, default)

    def force(self, t) -> np.ndarray:
        """Joint forces F(t), shape (len(t), n) for an array of times.

        Parameters
        ----------
        t : float or array_like
            Times.
        """
        return joint_forces(self.forces, t)

    def breakpoints(self) -> np.ndarray:
        """Segment ends 0 < t_1 < … < t_stop between which every force is smooth (:attr:`segment_ends`)."""
        return self.segment_ends

    def driven(self: _System, forces=None, t_stop: float | None = None, initial_rates=None) -> _System:
        """This system under other joint forces, over another horizon or from other joint rates:
        the solve's own inputs.

        The new system shares every matrix and the configuration; only what is given
        changes, checked as :func:`node_system` checks it. Gravity stays where the
        system holds it (a constant force in a linear system, G(q) in a nonlinear one).

        Parameters
        ----------
        forces : sequence, optional
            One entry per joint, as :func:`node_system` takes them.
        t_stop : float, optional
            End of the simulated interval [s].
        initial_rates : sequence of float, optional
            Joint rates at t = 0.
        """
        changes: dict = {}
        if t_stop is not None:
            changes["t_stop"] = check_t_stop(t_stop)
        if initial_rates is not None:
            with concerning("initial_rates"):
                changes["initial_rates"] = check_vector("initial rates r0", initial_rates, self.dof)
            changes["initial_voltages"] = self.topology.matrix @ changes["initial_rates"]
        if forces is not None:
            with concerning("forces"):
                changes["forces"] = self._with_gravity(waveforms(forces, self.dof))
        out = self._replaced(**changes)
        with concerning("forces"):
            out.breakpoints()       # every waveform checked against the horizon before any solver runs
        return out

    def _with_gravity(self, ws: tuple) -> tuple:
        """Joint waveforms *ws* with the system's constant loads added (none here)."""
        return ws

    def segments(self) -> Iterator[tuple[float, float]]:
        """Yield (t0, t1) intervals on which all forces are given by one closed form."""
        t0 = 0.0
        for t1 in self.breakpoints():
            yield t0, float(t1)
            t0 = float(t1)


def output_times(t_stop: float, times=None, default: int = 1001) -> np.ndarray:
    """Sorted output times in [0, *t_stop*]: *times* checked, or *default* uniform points.

    Parameters
    ----------
    t_stop : float
        End time.
    times : array_like, optional
        Requested times.
    default : int
        Number of uniform points without *times*.
    """
    if times is None:
        return np.linspace(0.0, t_stop, default)
    t = np.asarray(times, dtype=float).reshape(-1)
    if t.size and (np.any(np.diff(t) < 0) or t[0] < 0 or t[-1] > t_stop * (1 + 1e-9)
                   or not np.all(np.isfinite(t))):
        raise InputError("output times must be sorted and within [0, t_stop]")
    return np.minimum(t, t_stop)
