"""Node systems of one size as one batch axis: M', B', K' and v(0) stacked, each row one system."""

from __future__ import annotations

from typing import TYPE_CHECKING, Iterator, Sequence, overload

import numpy as np

if TYPE_CHECKING:
    from ..model.dynamics import NodeDynamics

__all__ = ["NodeStack"]


class NodeStack(Sequence):
    """Linear node systems of one size, their matrices stacked along a leading batch axis.

    A stack is a sequence of its systems; :attr:`mass`, :attr:`damping`,
    :attr:`stiffness` and :attr:`initial_voltages` are the (count, n, n) and (count, n)
    arrays, given when the stack was built as one (``analogy.node_systems``)
    and stacked on first use otherwise.

    Parameters
    ----------
    systems : sequence of linear NodeDynamics
        The rows, all with the same number of nodes.
    arrays : mapping of str to ndarray, optional
        Stacked ``mass``, ``damping``, ``stiffness``, ``initial_voltages`` already at hand.
    shared_inputs : bool
        The caller knows that every row has the same topology, forces and t_stop.
    """

    __slots__ = ("systems", "_arrays", "_shared", "_scales")

    def __init__(self, systems: Sequence["NodeDynamics"], arrays: dict | None = None, shared_inputs: bool = False):
        self.systems = tuple(systems)
        if not self.systems:
            raise ValueError("a node stack needs at least one system")
        if any(s.dof != self.systems[0].dof for s in self.systems):
            raise ValueError("the systems of a node stack must have one size")
        self._arrays = dict(arrays or {})
        self._shared = shared_inputs or len(self.systems) == 1
        self._scales = None         # the combined scales of one circuit running them all (analogy.circuit.scales)

    @classmethod
    def of(cls, systems: Sequence["NodeDynamics"]) -> "NodeStack":
        """*systems* as a stack: itself when it is one.

        Parameters
        ----------
        systems : sequence of linear NodeDynamics
            Systems of one size.
        """
        return systems if isinstance(systems, NodeStack) else cls(systems)

    def __len__(self) -> int:
        return len(self.systems)

    @overload
    def __getitem__(self, index: int) -> "NodeDynamics": ...

    @overload
    def __getitem__(self, index: slice) -> "NodeStack": ...

    def __getitem__(self, index):
        if isinstance(index, slice):
            return self.take(range(len(self))[index])
        return self.systems[index]

    def __iter__(self) -> Iterator["NodeDynamics"]:
        return iter(self.systems)

    def __repr__(self) -> str:
        return f"NodeStack({len(self)} systems, {self.dof} nodes)"

    @property
    def dof(self) -> int:
        """Nodes per system."""
        return self.systems[0].dof

    @property
    def springless(self) -> bool:
        """True when some row has no springs (then :attr:`stiffness` is None)."""
        return any(s.stiffness is None for s in self.systems)

    @property
    def shares_inputs(self) -> bool:
        """True when every row has the same topology, forces and t_stop."""
        if not self._shared:
            first = self.systems[0].inputs_key
            self._shared = all(s.inputs_key == first for s in self.systems[1:])
        return self._shared

    def _stacked(self, attr: str) -> np.ndarray:
        value = self._arrays.get(attr)
        if value is None:
            value = self._arrays[attr] = np.stack([getattr(s, attr) for s in self.systems])
        return value

    @property
    def mass(self) -> np.ndarray:
        """M' of every row, shape (count, n, n)."""
        return self._stacked("mass")

    @property
    def damping(self) -> np.ndarray:
        """B' of every row, shape (count, n, n)."""
        return self._stacked("damping")

    @property
    def stiffness(self) -> np.ndarray | None:
        """K' of every row, shape (count, n, n); None when some row has no springs."""
        return None if self.springless else self._stacked("stiffness")

    @property
    def initial_voltages(self) -> np.ndarray:
        """v(0) = T·R(0) of every row, shape (count, n)."""
        return self._stacked("initial_voltages")

    @property
    def current_map(self) -> np.ndarray:
        """T⁻ᵀ of every row, shape (count, n, n) (a broadcast view when the rows share T)."""
        first = self.systems[0].topology
        if all(s.topology.key == first.key for s in self.systems[1:]):
            return np.broadcast_to(first.current_map, (len(self), self.dof, self.dof))
        return self._stacked("current_map")

    def driven(self, forces=None, t_stop: "float | Sequence[float] | None" = None) -> "NodeStack":
        """Every row under other joint forces or over another horizon (see ``the system's ``driven````).

        Parameters
        ----------
        forces : sequence, optional
            One entry per joint, the same for every row.
        t_stop : float or sequence of float, optional
            End of the simulated interval [s]: one for every row, or one per row.
        """
        if t_stop is None or np.ndim(t_stop) == 0:
            return NodeStack([s.driven(forces, t_stop) for s in self.systems], self._arrays, self._shared)
        ends = [float(t) for t in t_stop]
        if len(ends) != len(self.systems):
            raise ValueError(f"{len(ends)} horizons for a stack of {len(self.systems)} systems")
        return NodeStack([s.driven(forces, t) for s, t in zip(self.systems, ends)], self._arrays,
                         self._shared and len(set(ends)) == 1)

    def take(self, rows: Sequence[int]) -> "NodeStack":
        """The stack of *rows*, in that order (this stack when they are all of it, in order).

        Parameters
        ----------
        rows : sequence of int
            Row indices.
        """
        return self._take(list(rows), self._shared)

    def _take(self, rows: list[int], shared: bool) -> "NodeStack":
        if rows == list(range(len(self))):
            return self
        index = np.asarray(rows, dtype=int)
        arrays = {k: v[index] for k, v in self._arrays.items()}
        return NodeStack([self.systems[k] for k in rows], arrays, shared)

    def partition(self, by_inputs: bool = True) -> list[tuple[list[int], "NodeStack"]]:
        """Rows grouped into sub-stacks that share springs (all or none) and, with *by_inputs*, inputs.

        Parameters
        ----------
        by_inputs : bool
            Also split by topology, forces and t_stop (:attr:`~analogy.circuit.node_system.NodeCoordinates.inputs_key`).
        """
        springs = [s.stiffness is not None for s in self.systems]
        if all(springs) or not any(springs):
            if not by_inputs or self.shares_inputs:
                return [(list(range(len(self))), self)]
        groups: dict = {}
        for k, s in enumerate(self.systems):
            groups.setdefault((springs[k], s.inputs_key if by_inputs else None), []).append(k)
        return [(rows, self._take(rows, by_inputs)) for rows in groups.values()]
