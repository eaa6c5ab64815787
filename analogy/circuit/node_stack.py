"""Node systems of one size as one batch axis: M', B', K' and v(0) stacked, each row one system."""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable, Iterator, Sequence, overload

import numpy as np

if TYPE_CHECKING:
    from ..model.dynamics import NodeDynamics

__all__ = ["NodeStack", "shared_row"]


class NodeStack(Sequence):
    """Linear node systems of one size, their matrices stacked along a leading batch axis.

    A stack is a sequence of its systems; :attr:`mass`, :attr:`damping`,
    :attr:`stiffness` and :attr:`initial_voltages` are the (count, n, n) and (count, n)
    arrays, given when the stack was built as one (``analogy.node_systems``)
    and stacked on first use otherwise. A stack built as one makes each row's system
    only when it is asked for (:meth:`lazy`): a batch that reads the arrays makes none.

    Parameters
    ----------
    systems : sequence of linear NodeDynamics
        The rows, all with the same number of nodes.
    arrays : mapping of str to ndarray, optional
        Stacked ``mass``, ``damping``, ``stiffness``, ``initial_voltages`` already at hand.
    shared_inputs : bool
        The caller knows that every row has the same topology, forces and t_stop.
    """

    __slots__ = ("_rows", "_row", "_arrays", "_shared", "_scales", "_springs", "_rowwise", "_parent", "checked")

    def __init__(self, systems: Sequence["NodeDynamics"], arrays: dict | None = None, shared_inputs: bool = False):
        rows = list(systems)
        if not rows:
            raise ValueError("a node stack needs at least one system")
        if any(s.dof != rows[0].dof for s in rows):
            raise ValueError("the systems of a node stack must have one size")
        self._rows: list = rows
        self._row: Callable[[int], "NodeDynamics"] | None = None
        self._arrays = dict(arrays or {})
        self._shared = shared_inputs or len(rows) == 1
        self._scales = None         # the combined scales of one circuit running them all (analogy.circuit.scales)
        self._springs: np.ndarray | None = None
        self._rowwise: dict = {}
        self._parent: tuple | None = None       # (stack, rows) of a take whose rows share inputs and springs
        #: What the work guard passed it under, (preset, spice), so that it is not estimated twice.
        self.checked: tuple | None = None

    @classmethod
    def lazy(cls, row: Callable[[int], "NodeDynamics"], arrays: dict, springs: np.ndarray,
             shared_inputs: bool) -> "NodeStack":
        """A stack whose row *k* is ``row(k)``, made when first asked for and kept.

        Parameters
        ----------
        row : callable
            The system of a row, from its index.
        arrays : mapping of str to ndarray
            Stacked ``mass``, ``damping`` and ``initial_voltages`` (and ``stiffness`` where every row has
            springs), of which the rows' matrices are views.
        springs : ndarray of bool
            Per row, whether it has springs.
        shared_inputs : bool
            Every row has the same topology, forces and t_stop.
        """
        obj = cls.__new__(cls)
        obj._rows = [None] * len(springs)
        obj._row, obj._arrays, obj._scales, obj.checked = row, dict(arrays), None, None
        obj._springs = np.asarray(springs, dtype=bool)
        obj._shared = shared_inputs or len(springs) == 1
        obj._rowwise, obj._parent = {}, None
        return obj

    def __reduce__(self):
        # a lazy stack's row function is local to the code that built it: pickled, its rows are made
        return NodeStack, (self.systems, self._arrays, self._shared)

    def _alike(self) -> Sequence["NodeDynamics"]:
        """The rows that answer for all in what is not stacked: one alone where one function made every
        row (:meth:`lazy`; :func:`shared_row`), else each."""
        return [shared_row(self)] if self._row is not None else self

    @property
    def linear(self) -> bool:
        """True when every row is linear."""
        return all(getattr(s, "kind", "linear") == "linear" for s in self._alike())

    @property
    def systems(self) -> tuple:
        """Every row's system (each made now if not yet)."""
        return tuple(self[k] for k in range(len(self)))

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
        return len(self._rows)

    @overload
    def __getitem__(self, index: int) -> "NodeDynamics": ...

    @overload
    def __getitem__(self, index: slice) -> "NodeStack": ...

    def __getitem__(self, index):
        if isinstance(index, slice):
            return self.take(range(len(self))[index])
        system = self._rows[index]
        if system is None:
            system = self._rows[index] = self._row(range(len(self._rows))[index])
        return system

    def __iter__(self) -> Iterator["NodeDynamics"]:
        return (self[k] for k in range(len(self)))

    def __repr__(self) -> str:
        return f"NodeStack({len(self)} systems, {self.dof} nodes)"

    @property
    def dof(self) -> int:
        """Nodes per system."""
        mass = self._arrays.get("mass")
        return mass.shape[1] if mass is not None else self[0].dof

    @property
    def inputs_row(self) -> "NodeDynamics":
        """A system with the inputs (topology, forces, t_stop) every row shares: for a :meth:`take` of a
        stack whose rows share them, that stack's first row, one system for all its takes, so that what
        the inputs derive (breakpoints, sources) is derived once. Only for a stack that :attr:`shares_inputs`."""
        return self._parent[0][0] if self._parent is not None else self[0]

    @property
    def first_made(self) -> "NodeDynamics | None":
        """The first row's system if it has been made, else None (a lazy stack's rows are made when asked for)."""
        return self._rows[0]

    @property
    def springs(self) -> np.ndarray:
        """Per row, whether it has springs."""
        if self._springs is None:
            self._springs = np.array([s.stiffness is not None for s in self])
        return self._springs

    @property
    def springless(self) -> bool:
        """True when some row has no springs (then :attr:`stiffness` is None)."""
        return not self.springs.all()

    @property
    def realizable(self) -> bool:
        """True when some row is to be simulated as its realizable circuit."""
        return any(getattr(s, "realizable", False) for s in self._alike())

    @property
    def t_stops(self) -> np.ndarray:
        """Per row, its t_stop."""
        return np.full(len(self), self.inputs_row.t_stop) if self._shared else np.array([s.t_stop for s in self])

    @property
    def shares_inputs(self) -> bool:
        """True when every row has the same topology, forces and t_stop."""
        if not self._shared:
            first = self[0].inputs_key
            self._shared = all(s.inputs_key == first for s in self.systems[1:])
        return self._shared

    def _stacked(self, attr: str) -> np.ndarray:
        value = self._arrays.get(attr)
        if value is None:
            value = self._arrays[attr] = np.stack([getattr(s, attr) for s in self])
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
        first = shared_row(self).topology
        if self._shared or all(s.topology.key == first.key for s in self.systems[1:]):
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
        # consecutive rows (a batch's circuits) are read as views, which the take may not write into
        consecutive = rows and 0 <= rows[0] and rows[-1] < len(self) and rows == list(range(rows[0], rows[-1] + 1))
        index = slice(rows[0], rows[-1] + 1) if consecutive else np.asarray(rows, dtype=int)
        arrays = {k: _read_only(v[index]) for k, v in self._arrays.items()}
        made = self._rows[index] if isinstance(index, slice) else [self._rows[k] for k in rows]
        if self._row is None:
            picked = NodeStack(made, arrays, shared)
        else:
            picked = self.lazy(lambda j: self[rows[j]], arrays, self.springs[index], shared)
            picked._rows = made         # the rows already made are shared
        springs = self.springs
        if shared and self.shares_inputs and (springs.all() or not springs.any()):
            # what rows sharing their inputs and springs derive is made once, for the whole stack
            picked._parent = (self, index)
        return picked

    def rowwise(self, key: str, make: Callable[["NodeStack"], tuple]) -> tuple:
        """``make(self)``, made once and kept under *key*: values derived row by row. Each array or list
        in it has one entry per row (anything else is shared by all). A :meth:`take` of a stack whose rows
        share their inputs and springs (all or none) reads its rows' entries of the whole stack's, made once.

        Parameters
        ----------
        key : str
            What the values are.
        make : callable
            Makes them from the stack.
        """
        value = self._rowwise.get(key)
        if value is None:
            value = None if self._parent is None else self._parent[0]._whole(key, make)
            # made for the stack this was taken from, and kept there for its other takes; where that
            # failed, made for these rows alone, so that it fails only where they do
            value = make(self) if value is None else _rows_of(value, self._parent[1], len(self._parent[0]))
            self._rowwise[key] = value
        return value

    def _whole(self, key: str, make: Callable[["NodeStack"], tuple]) -> tuple | None:
        """:meth:`rowwise` for a take of this stack: None where making it for the whole stack failed."""
        if key in self._rowwise:
            return self._rowwise[key]
        try:
            return self.rowwise(key, make)
        except Exception:       # noqa: BLE001 - whatever it is, the take makes its own and meets it there
            self._rowwise[key] = None
            return None

    def partition(self, by_inputs: bool = True) -> list[tuple[list[int], "NodeStack"]]:
        """Rows grouped into sub-stacks that share springs (all or none) and, with *by_inputs*, inputs.

        Parameters
        ----------
        by_inputs : bool
            Also split by topology, forces and t_stop (:attr:`~analogy.circuit.node_system.NodeCoordinates.inputs_key`).
        """
        springs = self.springs.tolist()
        if all(springs) or not any(springs):
            if not by_inputs or self.shares_inputs:
                return [(list(range(len(self))), self)]
        groups: dict = {}
        for k, s in enumerate(self.systems):
            groups.setdefault((springs[k], s.inputs_key if by_inputs else None), []).append(k)
        return [(rows, self._take(rows, by_inputs)) for rows in groups.values()]


def _rows_of(value: tuple, index: np.ndarray | slice, count: int) -> tuple:
    """The entries of *index* in each item of one of :meth:`NodeStack.rowwise`'s values."""
    return tuple([_item_rows(v, index, count) for v in value])


def _item_rows(value, index: np.ndarray | slice, count: int):
    """The entries of *index* in one item of a :meth:`NodeStack.rowwise` value (itself where it is shared)."""
    if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == count:
        return _read_only(value[index])
    if isinstance(value, list) and len(value) == count:
        return value[index] if isinstance(index, slice) else [value[i] for i in index.tolist()]
    return value


def _read_only(rows: np.ndarray) -> np.ndarray:
    """*rows* of a stack's array, marked read-only where they are a view of it."""
    if rows.base is not None:
        rows.flags.writeable = False
    return rows


def shared_row(systems: Sequence["NodeDynamics"]) -> "NodeDynamics":
    """A system that answers for what all of *systems* share (kind, size, topology, inputs): a stack's
    :attr:`~NodeStack.inputs_row` where its rows share their inputs, so that no row of a take is made
    for it, else the first.

    Parameters
    ----------
    systems : sequence of NodeDynamics
        Systems solved together.
    """
    return systems.inputs_row if isinstance(systems, NodeStack) and systems._shared else systems[0]
