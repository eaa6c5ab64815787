"""A stack of systems' comparisons: each solver's errors, times and failures as columns, a Comparison made when asked."""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable, Iterator, Mapping, Sequence, TypeVar, overload

import numpy as np

from ..results.output import Tabular

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..results.trajectory_stack import TrajectoryStack
    from .measure import MeasuredErrors

__all__ = ["Comparisons"]

#: A system's comparison (:class:`~analogy.study.comparison.Comparison`, which makes these).
_Row = TypeVar("_Row")


class Comparisons(Sequence[_Row], Tabular):
    """What :func:`~analogy.study.comparison.compare_many` found: a sequence of
    :class:`~analogy.study.comparison.Comparison`, one per system, each made when it is asked for,
    and each solver's errors, run times and failures over every system as arrays
    (:meth:`errors`, :meth:`seconds`, :meth:`failures`), read without making one.

    Parameters
    ----------
    row : callable
        System *k*'s Comparison, from *k*.
    runs : mapping of str to TrajectoryStack
        Each solver's runs as shown, in run order.
    measured : MeasuredErrors
        Each solver's errors against the reference, per system.
    skipped : mapping of str to str
        Solvers that do not apply, with the reason.
    reference : str or None
        The reference solver (None: no errors were measured).
    preset : str
        The preset's name.
    bound : float
        The preset's promised worst error / peak.
    """

    def __init__(self, row: Callable[[int], _Row], runs: Mapping[str, "TrajectoryStack"],
                 measured: "MeasuredErrors", skipped: Mapping[str, str], reference: str | None, preset: str,
                 bound: float):
        self._row, self._runs, self._measured = row, dict(runs), measured
        self._made: list = [None] * len(measured)
        self.solvers = tuple(self._runs)       # run order
        self.skipped, self.reference, self.preset, self.bound = dict(skipped), reference, preset, bound

    def __reduce__(self):
        # the row function is local to compare_many: pickled, every Comparison is made and kept
        return _restored, (list(self), self._runs, self._measured, self.skipped, self.reference, self.preset,
                           self.bound)

    def __len__(self) -> int:
        return len(self._made)

    @overload
    def __getitem__(self, index: int) -> _Row: ...

    @overload
    def __getitem__(self, index: slice) -> list: ...

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[k] for k in range(len(self))[index]]
        k = range(len(self))[index]
        if self._made[k] is None:
            self._made[k] = self._row(k)
        return self._made[k]

    def __iter__(self) -> Iterator[_Row]:
        return (self[k] for k in range(len(self)))

    def errors(self, name: str) -> np.ndarray:
        """Solver *name*'s worst error over each output's own peak, per system: NaN where it was not
        measured (it failed, the reference failed, or it is the reference).

        Parameters
        ----------
        name : str
            A solver asked for.
        """
        if name == self.reference or name not in self._runs:
            return np.full(len(self), np.nan)
        return self._measured.relative(name)

    def seconds(self, name: str) -> np.ndarray:
        """Solver *name*'s run time per system (0 where it failed or did not run).

        Parameters
        ----------
        name : str
            A solver asked for.
        """
        runs = self._runs.get(name)
        if runs is None:
            return np.zeros(len(self))
        return np.where(runs.successes, runs.run_times, 0.0)

    def failures(self, name: str) -> dict[int, str]:
        """The systems solver *name* failed on, with the reason.

        Parameters
        ----------
        name : str
            A solver asked for.
        """
        runs = self._runs.get(name)
        if runs is None:
            return {}
        return {k: runs[k].message for k in np.flatnonzero(~runs.successes).tolist()}

    def columns(self) -> dict[str, np.ndarray]:
        """``system``, then each solver's ``error_<solver>`` and ``seconds_<solver>``."""
        cols = {"system": np.arange(len(self))}
        for name in self.solvers:
            cols[f"error_{name}"], cols[f"seconds_{name}"] = self.errors(name), self.seconds(name)
        return cols

    def _worst(self, name: str) -> str:
        e = self.errors(name)
        return f"{np.nanmax(e):.2e}" if np.isfinite(e).any() else "n/a"

    def __repr__(self) -> str:
        failed = len({k for name in self.solvers for k in self.failures(name)})
        worst = ", ".join(f"{n} {self._worst(n)}" for n in self.solvers if n != self.reference)
        ref = f" against {self.reference}" if self.reference else ""
        return f"<Comparisons of {len(self)} systems at {self.preset}: worst error/peak {worst or 'n/a'}{ref}, " \
               f"{failed} failed>"

    def plot(self, path=None) -> "Figure":
        """Each solver's errors over the systems as a histogram (log scale), the bound marked.

        Parameters
        ----------
        path : str or Path, optional
            Image file to write.
        """
        from ..results.plots import plot_error_histogram
        against = f", against {self.reference}" if self.reference else ""
        return plot_error_histogram({n: self.errors(n) for n in self.solvers if n != self.reference},
                                    f"{len(self)} systems at {self.preset}{against}", {self.preset: self.bound},
                                    "systems", path)


def _restored(rows: list, runs, measured, skipped, reference, preset, bound) -> Comparisons:
    """A pickled :class:`Comparisons`, its rows already made."""
    found = Comparisons(rows.__getitem__, runs, measured, skipped, reference, preset, bound)
    found._made = list(rows)
    return found
