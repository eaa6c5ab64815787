"""The batch planner: scenes split into groups solved together, and one group's solve through the orchestrator."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple, Sequence

import numpy as np

from ..circuit.node_stack import NodeStack
from ..errors import AnalogyError, InputError
from ..presets import Preset
from ..scenes.scene import _PLAIN_REALS, Scene
from ..study.comparison import compare_many
from ..study.work import check_work, check_works

if TYPE_CHECKING:
    from ..model.dynamics import NodeDynamics

__all__ = ["as_system", "Group", "GroupResult", "plan_groups", "solve_group", "solve_group_isolated",
           "HORIZON_SPREAD"]

#: Longest over shortest horizon of a group: one ngspice run goes to the longest, so a
#: member is simulated for at most this many times its own span. For small circuits one
#: run of many systems costs less than that (40 serial2 systems with horizons in [1, 2] s
#: at accurate: one run took a third of the time of forty); past it, the extra span dominates.
HORIZON_SPREAD = 2.0


def as_system(item) -> "NodeDynamics":
    """The node system of a batch item: a NodeSystem as it is, a Scene built.

    Parameters
    ----------
    item : Scene or NodeSystem
        A batch member.
    """
    return item.system() if isinstance(item, Scene) else item


@dataclass(frozen=True, eq=False)
class Group:
    """Scenes or systems solved together: a family built as one stack, or items built one by one.

    Attributes
    ----------
    rows : tuple of int
        Indices of the group's members in the batch.
    items : tuple
        The members (Scenes or NodeSystems), when not a family.
    base : Scene or None
        A family's first scene; its members differ from it only in q and parameter values.
    configurations : ndarray or None
        A family's q per member, shape (count, n).
    parameters : dict of str to ndarray
        A family's parameter values per member, where they vary.
    horizons : ndarray or None
        A family's t_stop per member, where they vary.
    runs : tuple of int
        How many members each SPICE circuit holds, in order (empty: one circuit of all): a family's
        consecutive circuits built and solved by one call.
    """

    rows: tuple
    items: tuple = ()
    base: Scene | None = None
    configurations: np.ndarray | None = None
    parameters: dict = field(default_factory=dict)
    horizons: np.ndarray | None = None
    runs: tuple = ()

    def members(self) -> list:
        """The scenes or systems of the group, one by one."""
        if self.base is None:
            return list(self.items)
        base = self.base
        ends = [base.t_stop] * len(self.rows) if self.horizons is None else self.horizons.tolist()
        return [base.replace(q=tuple(row), t_stop=ends[i],
                             parameters={**dict(base.parameters), **{k: float(v[i]) for k, v in self.parameters.items()}})
                for i, row in enumerate(np.asarray(self.configurations).tolist())]

    def circuits(self) -> list["Group"]:
        """The group as one group per SPICE circuit (itself where it is one)."""
        if not self.runs:
            return [self]
        ends = np.cumsum((0,) + self.runs).tolist()
        return [Group(self.rows[a:b], base=self.base, configurations=self.configurations[a:b],
                      parameters={k: v[a:b] for k, v in self.parameters.items()},
                      horizons=None if self.horizons is None else self.horizons[a:b])
                for a, b in zip(ends[:-1], ends[1:])]

    def stack(self) -> NodeStack:
        """A family's members as one stack; raises :class:`~analogy.errors.AnalogyError` where a row does not build."""
        stack = self.base.systems(self.configurations, parameters=self.parameters)
        return stack if self.horizons is None else stack.driven(None, self.horizons)

    def build(self) -> tuple[list, dict]:
        """The members' node systems (None where a build failed) and the failures (position to reason).

        A family is built as one stack; if a row is bad, row by row, so that the others are kept.
        """
        if self.base is not None:
            try:
                return self.stack(), {}
            except AnalogyError:
                pass
        systems, failures = [], {}
        for k, item in enumerate(self.members()):
            try:
                systems.append(as_system(item))
            except AnalogyError as exc:
                systems.append(None)
                failures[k] = str(exc)
        return systems, failures


class GroupResult(NamedTuple):
    """Per member of a group (by position): errors and seconds per solver, and what went wrong.

    Attributes
    ----------
    errors : dict of str to ndarray
        Worst error of each output relative to its own peak, per solver (NaN where not measured).
    seconds : dict of str to ndarray
        Solver time per member.
    failures : dict of int to str
        Members that could not be built or solved, with the reason.
    invalid : set of int
        Members that could not be built.
    refused : set of int
        Members the work guard refused.
    rates : list or None
        Per member and solver, (time, joint rates), when kept.
    """

    errors: dict
    seconds: dict
    failures: dict
    invalid: set
    refused: set
    rates: list | None


def plan_groups(items: Sequence, group_size: int, circuits: int = 1) -> list[Group]:
    """Split *items* (Scenes or NodeSystems) into circuits of at most *group_size* that run together.

    Scenes that differ only in their configuration, a robot's parameter values and t_stop
    form one family, built as a stack. Scenes of different presets never share a group. A circuit's
    horizons lie within :data:`HORIZON_SPREAD` of each other, so that one ngspice run serves them all.
    Up to *circuits* consecutive circuits of one family and one horizon make one group
    (:attr:`Group.runs`): what a group costs besides its members (building a stack, checking it) is
    then paid once for them all.

    Parameters
    ----------
    items : sequence of Scene or NodeSystem
        The batch.
    group_size : int
        Most members per SPICE circuit.
    circuits : int
        Most circuits of a family per group.
    """
    kinds: dict = {}
    last: tuple = (None, None)          # the last scene of a family and its key's members
    for k, item in enumerate(items):
        if getattr(item, "estimate", False) or getattr(item, "refine", False):
            raise InputError("a batch measures errors against the reference and does not estimate them: "
                             "run a scene with estimate = true or refine = true by itself (analogy run)")
        scene = isinstance(item, Scene)
        if scene and _same_family(item, last[0]):       # made from the last by replace(q=…, t_stop=…): its key
            last[1].append(k)
            continue
        family = item.family() if scene else None
        preset = item.preset if scene else None      # a group runs at one preset
        key = ("family", family, preset) if family is not None else \
            ("single", item.dynamics if scene else item.kind, preset)
        members = kinds.setdefault(key, [])
        members.append(k)
        if family is not None:
            last = (item, members)
    groups = []
    for (kind, *_), idx in kinds.items():
        chunks = _chunks(idx, [items[k].t_stop for k in idx], group_size)
        if kind != "family":
            groups += [Group(chunk, tuple(items[k] for k in chunk)) for chunk in chunks]
            continue
        # consecutive circuits of one horizon share a group: a stack over several horizons makes every row
        ends = [{items[k].t_stop for k in chunk} for chunk in chunks]
        j = 0
        while j < len(chunks):
            last = j + 1
            while last < min(j + circuits, len(chunks)) and len(ends[j]) == 1 and ends[last] == ends[j]:
                last += 1
            groups.append(_family(items, chunks[j:last]))
            j = last
    return groups


def _same_family(item: Scene, last: Scene | None) -> bool:
    """Whether *item* holds what :meth:`Scene.family` and the preset read of *last* as the same objects, and
    a q of plain reals of its length: then its family and preset are *last*'s, with no key made or hashed."""
    return last is not None and len(item.q) == len(last.q) and _PLAIN_REALS.issuperset(map(type, item.q)) and \
        item.model is last.model and item.parameters is last.parameters and item.topology is last.topology and \
        item.forces is last.forces and item.initial_rates is last.initial_rates and \
        item.dynamics is last.dynamics and item.equilibrium is last.equilibrium and item.preset is last.preset


def _family(items: Sequence, chunks: list[tuple]) -> Group:
    """The group of a family's circuits *chunks* (positions in *items*), one after another."""
    rows = tuple(k for chunk in chunks for k in chunk)
    first = items[rows[0]]
    qs = np.array([items[k].q for k in rows], dtype=float).reshape(len(rows), -1)
    params = {}
    if first.model.robot is not None and first.parameters:
        values = np.array([[v for _, v in items[k].parameters] for k in rows], dtype=float)
        params = {name: values[:, j] for j, (name, _) in enumerate(first.parameters)
                  if np.any(values[:, j] != values[0, j])}
    ends = np.array([items[k].t_stop for k in rows], dtype=float)
    return Group(rows, base=first, configurations=qs, parameters=params,
                 horizons=ends if np.any(ends != ends[0]) else None,
                 runs=tuple(len(chunk) for chunk in chunks) if len(chunks) > 1 else ())


def _chunks(idx: list[int], ends: list[float], size: int) -> list[tuple]:
    """*idx* in runs of at most *size* whose horizons lie within :data:`HORIZON_SPREAD`, in batch order within each."""
    order = sorted(range(len(idx)), key=ends.__getitem__)
    chunks, current = [], []
    for j in order:
        if current and (len(current) == size or ends[j] > HORIZON_SPREAD * ends[current[0]]):
            chunks.append(tuple(idx[i] for i in sorted(current)))
            current = []
        current.append(j)
    if current:
        chunks.append(tuple(idx[i] for i in sorted(current)))
    return chunks


def solve_group(group: Group, preset: Preset, solvers: Sequence[str], reference: str | None,
                keep: bool = False) -> GroupResult:
    """Build a group's systems and compare each of its circuits through :func:`compare_many`.

    SPICE runs each circuit (:attr:`Group.runs`) as one netlist; if that run fails, each member
    runs alone, so that one member's failure is its own. A member past the work budget is refused
    alone. A family's rows are built as one stack for all its circuits; where a row does not build,
    each circuit is built and solved as a group of its own.

    Parameters
    ----------
    group : Group
        What to solve.
    preset : Preset
        Accuracy preset.
    solvers : sequence of str
        Solvers to run.
    reference : str or None
        The yardstick (``"auto"``: exact where it applies; None: no errors).
    keep : bool
        Keep every member's time points and joint rates.
    """
    if group.runs:
        try:
            built, failures = group.stack(), {}
        except AnalogyError:        # only the circuit holding the bad row is built row by row
            return _joined([solve_group(g, preset, solvers, reference, keep) for g in group.circuits()])
    else:
        built, failures = group.build()
    count = len(built)
    out = GroupResult({name: np.full(count, np.nan) for name in solvers},
                      {name: np.zeros(count) for name in solvers}, failures, set(failures), set(),
                      [None] * count if keep else None)
    ends = np.cumsum((0,) + (group.runs or (count,)))
    for start, end in zip(ends[:-1].tolist(), ends[1:].tolist()):
        _solve_run(built, [k for k in range(start, end) if k not in failures], preset, solvers, reference, out)
    return out


def _solve_run(built, ok: list[int], preset: Preset, solvers: Sequence[str], reference: str | None,
               out: GroupResult) -> None:
    """One SPICE circuit's members *ok* (positions in *built*) checked and compared, into *out*."""
    if not ok:
        return
    failures, refused, spice = out.failures, out.refused, "spice" in solvers
    stack = isinstance(built, NodeStack)
    systems = built if stack and len(ok) == len(built) else built.take(ok) if stack else [built[k] for k in ok]
    try:
        check_works(systems, preset, spice=spice)       # a stack's rows are not made to be checked
    except InputError:                  # some member is past the work budget: find which, and refuse it alone
        for k in ok:
            try:
                check_work(built[k], preset, spice=spice)
            except InputError as exc:
                failures[k] = str(exc)
                refused.add(k)
        ok = [k for k in ok if k not in refused]
        if not ok:
            return
        systems = built.take(ok) if stack else [built[k] for k in ok]
    found = compare_many(systems, preset, solvers, reference=reference)      # read as columns: no row is made
    for name in found.solvers:          # a later solver's failure is the one said, as records come in run order
        for j, why in found.failures(name).items():
            failures[ok[j]] = f"{name}: {why}" if name != "spice" else why
        if name in out.seconds:
            out.seconds[name][ok], out.errors[name][ok] = found.seconds(name), found.errors(name)   # the yardstick's is NaN
    if out.rates is not None:
        for k, c in zip(ok, found):
            ran = {s: r.trajectory for s, r in c.records.items() if r.ran}
            out.rates[k] = {s: (ran[s].time, ran[s].rates) for s in solvers if s in ran}


def solve_group_isolated(group: Group, preset: Preset, solvers: Sequence[str], reference: str | None,
                         keep: bool = False) -> GroupResult:
    """:func:`solve_group`, and when it raises, each member alone, so that a bug in one member fails only it.

    Parameters
    ----------
    group : Group
        What to solve.
    preset : Preset
        Accuracy preset.
    solvers : sequence of str
        Solvers to run.
    reference : str or None
        The yardstick.
    keep : bool
        Keep every member's time points and joint rates.
    """
    try:
        return solve_group(group, preset, solvers, reference, keep)
    except Exception:       # noqa: BLE001 - one member's bug must not lose the group's others
        if group.runs:      # each circuit on its own first: the others keep their shared runs
            return _joined([solve_group_isolated(g, preset, solvers, reference, keep) for g in group.circuits()])
    items = group.members()
    count = len(items)
    errors = {name: np.full(count, np.nan) for name in solvers}
    seconds = {name: np.zeros(count) for name in solvers}
    failures, invalid, refused, rates = {}, set(), set(), [None] * count
    for k, item in enumerate(items):
        try:
            one = solve_group(Group((group.rows[k],), (item,)), preset, solvers, reference, keep)
        except Exception as exc:        # noqa: BLE001
            failures[k] = f"internal error: {type(exc).__name__}: {' '.join(str(exc).split())[:300]}"
            continue
        for name in solvers:
            errors[name][k], seconds[name][k] = one.errors[name][0], one.seconds[name][0]
        if 0 in one.failures:
            failures[k] = one.failures[0]
        invalid |= {k} if one.invalid else set()
        refused |= {k} if one.refused else set()
        if one.rates is not None:
            rates[k] = one.rates[0]
    return GroupResult(errors, seconds, failures, invalid, refused, rates if keep else None)


def _joined(parts: list[GroupResult]) -> GroupResult:
    """The results of a group's circuits, solved one after another, as the group's."""
    offsets = np.cumsum([0] + [len(next(iter(p.errors.values()))) for p in parts]).tolist()

    def moved(index: dict | set, at: int):
        return {k + at: v for k, v in index.items()} if isinstance(index, dict) else {k + at for k in index}
    kept = all(p.rates is not None for p in parts)
    return GroupResult({name: np.concatenate([p.errors[name] for p in parts]) for name in parts[0].errors},
                       {name: np.concatenate([p.seconds[name] for p in parts]) for name in parts[0].seconds},
                       {k: v for p, at in zip(parts, offsets) for k, v in moved(p.failures, at).items()},
                       set().union(*(moved(p.invalid, at) for p, at in zip(parts, offsets))),
                       set().union(*(moved(p.refused, at) for p, at in zip(parts, offsets))),
                       [r for p in parts for r in p.rates] if kept else None)
