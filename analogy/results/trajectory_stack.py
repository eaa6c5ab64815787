"""One solver's results for a stack of systems: a sequence of Trajectories, and (count, N, n) arrays on a shared grid."""

from __future__ import annotations

from typing import Iterator, Sequence, overload

import numpy as np

from .trajectory import SolverStats, Trajectory

__all__ = ["TrajectoryStack"]


class TrajectoryStack(Sequence):
    """A solver's :class:`Trajectory` for each row of a node stack, in order.

    A stack solved as one (one ngspice circuit, stacked linear algebra) keeps its
    shared :attr:`time` and its (count, N, n) :attr:`voltages` and :attr:`rates`,
    of which the rows are views; errors are then measured on the whole stack at once.

    Parameters
    ----------
    rows : sequence of Trajectory
        One result per system.
    time : ndarray, optional
        The grid every row is on, when solved as one.
    voltages, rates : ndarray, optional
        The rows' node voltages and joint rates, shape (count, N, n), when solved as one.
    """

    __slots__ = ("_rows", "time", "_voltages", "_rates", "_made", "_parent")

    def __init__(self, rows: Sequence[Trajectory], time: np.ndarray | None = None,
                 voltages: np.ndarray | None = None, rates: np.ndarray | None = None):
        self._rows: list = list(rows)
        self.time, self._voltages, self._rates = time, voltages, rates
        self._made: tuple | None = None     # (solver, stats) of rows made from the arrays when asked for
        self._parent: tuple | None = None   # (stack, its rows) whose rows these are, made there and shared

    @classmethod
    def solved_as_one(cls, solver: str, time: np.ndarray, voltages: np.ndarray, rates: np.ndarray,
                      stats: SolverStats) -> "TrajectoryStack":
        """Rows that are views of one solution of every system on *time*.

        Parameters
        ----------
        solver : str
            The solver's name.
        time : ndarray, shape (N,)
            The shared time points.
        voltages, rates : ndarray, shape (count, N, n)
            Node voltages and joint rates of every system.
        stats : SolverStats
            Statistics of each row (the shared run's time divided among them).
        """
        obj = cls([None] * len(voltages), time, voltages, rates)
        obj._made = (solver, stats)         # a row's Trajectory is made when it is asked for
        return obj

    @classmethod
    def of(cls, rows: Sequence[Trajectory]) -> "TrajectoryStack":
        """*rows* as a stack: itself when it is one.

        Parameters
        ----------
        rows : sequence of Trajectory
            One result per system.
        """
        return rows if isinstance(rows, TrajectoryStack) else cls(rows)

    def __len__(self) -> int:
        return len(self._rows)

    @property
    def rows(self) -> tuple:
        """Every row's :class:`Trajectory` (each made now if not yet)."""
        return tuple(self[k] for k in range(len(self)))

    @overload
    def __getitem__(self, index: int) -> Trajectory: ...

    @overload
    def __getitem__(self, index: slice) -> "TrajectoryStack": ...

    def __getitem__(self, index):
        if isinstance(index, slice):
            return self.take(range(len(self))[index])
        tr = self._rows[index]
        if tr is None:
            k = range(len(self._rows))[index]
            if self._parent is not None:    # one object per row, whichever stack asks first
                parent, rows = self._parent
                tr = parent[rows[k]]
            else:
                solver, stats = self._made
                tr = Trajectory(solver, self.time, self._voltages[k], self._rates[k], stats=stats)
            self._rows[k] = tr
        return tr

    def __iter__(self) -> Iterator[Trajectory]:
        return (self[k] for k in range(len(self)))

    @property
    def solver(self) -> str:
        """The solver's name ("?" for an empty stack)."""
        return self._made[0] if self._made is not None else self[0].solver if len(self) else "?"

    @property
    def successes(self) -> np.ndarray:
        """Per row, whether its run succeeded."""
        if self._made is not None:
            return np.ones(len(self), dtype=bool)
        return np.array([tr.success for tr in self._rows], dtype=bool)

    @property
    def run_times(self) -> np.ndarray:
        """Per row, its seconds in the solver."""
        if self._made is not None:
            return np.full(len(self), self._made[1].wall_time)
        return np.array([tr.run_time for tr in self._rows], dtype=float)

    def __repr__(self) -> str:
        ok = int(self.successes.sum())
        name = self.solver
        grid = f", one grid of {self.time.size} points" if self.time is not None else ""
        return f"TrajectoryStack({name}: {ok} of {len(self)} succeeded{grid})"

    @property
    def whole(self) -> bool:
        """True when the stack was solved as one: every row on :attr:`time`, arrays at hand."""
        return self.time is not None

    def take(self, rows: Sequence[int]) -> "TrajectoryStack":
        """The stack of *rows*, in that order (this stack when they are all of it, in order).

        Parameters
        ----------
        rows : sequence of int
            Row indices.
        """
        rows = list(rows)
        if rows == list(range(len(self))):
            return self
        if not self.whole:
            return TrajectoryStack([self[k] for k in rows])
        index = np.asarray(rows, dtype=int)
        picked = TrajectoryStack([self._rows[k] for k in rows], self.time, self._voltages[index], self._rates[index])
        picked._made = self._made
        if self._made is not None:
            picked._parent = (self, rows)
        return picked

    @property
    def rates(self) -> np.ndarray:
        """Joint rates of every row, shape (count, N, n): rows of one grid only."""
        if self._rates is None:
            self._rates = np.stack([tr.rates for tr in self.rows])
        return self._rates

    @property
    def voltages(self) -> np.ndarray:
        """Node voltages of every row, shape (count, N, n): rows of one grid only."""
        if self._voltages is None:
            self._voltages = np.stack([tr.voltages for tr in self.rows])
        return self._voltages

    def by_grid(self) -> list[list[int]]:
        """Indices of the successful rows, grouped by equal time points (by value)."""
        if self.whole and self.successes.all():
            return [list(range(len(self)))]
        groups: dict = {}
        for k, tr in enumerate(self):
            if tr.success:
                groups.setdefault(tr.time.tobytes(), []).append(k)
        return list(groups.values())
