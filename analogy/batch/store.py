"""A sweep's results store: a Parquet dataset with one row per scene, written group by group, resumable."""

from __future__ import annotations

import json
import os
import uuid
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import numpy as np

from ..errors import InputError

if TYPE_CHECKING:
    import pandas
    import pyarrow

__all__ = ["ResultStore", "STATUSES", "manifest", "read", "read_trajectories"]

#: Row status: solved within the bound, outside it, a solver failed, the scene is invalid, its run is
#: past the work budget (refused before it starts), its worker died.
STATUSES = ("ok", "inaccurate", "failed", "invalid", "refused", "worker-died")

_MANIFEST = "_sweep.json"
_PENDING = "_pending"
_TRAJECTORIES = "_trajectories"
# Pending groups are merged into one Parquet file once this many scenes wait.
_COMPACT_ROWS = 50_000


def _pa():
    try:
        import pyarrow as pa
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        raise InputError("the results store needs pyarrow: pip install pyarrow") from None
    return pa


def _atomic(path: Path, write) -> None:
    """Write through a hidden temporary file and rename it into place, so no reader sees half a file."""
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


class ResultStore:
    """The folder of a sweep's results: ``part-*.parquet`` rows, a manifest, groups still to be merged.

    ``pandas.read_parquet(folder)`` reads the rows (names starting with ``_`` or ``.``
    are not part of the dataset). A group's rows are written at once, through a
    temporary file renamed into place, and merged into a part later; a scene whose
    index is stored is never written again, so a killed run loses only its groups in
    flight and a resumed one writes no duplicate.

    Parameters
    ----------
    directory : str or Path
        The folder (made if missing).
    manifest : mapping
        The sweep's description (:meth:`analogy.batch.sweep.Sweep.describe`); a folder
        holding another sweep is refused.
    schema : pyarrow.Schema
        Columns of a row.
    """

    def __init__(self, directory, manifest: Mapping, schema: "pyarrow.Schema"):
        pa = _pa()
        self.directory = Path(directory)
        self.manifest = dict(manifest)
        self.schema = schema
        self._pa = pa
        if self.directory.exists() and not self.directory.is_dir():
            raise InputError(f"cannot store results in {self.directory}: it is a file")
        try:
            (self.directory / _PENDING).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"cannot create {self.directory}: {exc.strerror or exc}") from None
        path = self.directory / _MANIFEST
        if path.exists():
            try:
                old = json.loads(path.read_text())
            except (OSError, ValueError):
                raise InputError(f"{path} is not a sweep manifest: use an empty folder") from None
            if old.get("key") != self.manifest["key"]:
                raise InputError(f"{self.directory} holds the results of another sweep "
                                 f"({old.get('scene', '?')}, key {str(old.get('key'))[:12]}): "
                                 "use another folder, or the same sweep to resume it")
        else:
            stray = [p for p in self.directory.glob("part-*.parquet")]
            if stray:
                raise InputError(f"{self.directory} holds Parquet parts but no manifest: use an empty folder")
            _atomic(path, lambda p: p.write_text(json.dumps(self.manifest, indent=1, default=str)))
        for tmp in self.directory.rglob(".*.tmp"):     # from a run killed while writing
            tmp.unlink(missing_ok=True)
        self._parts = len(list(self.directory.glob("part-*.parquet")))
        self._pending_rows = 0

    # --------------------------------------------------------------- reading

    def stored_indices(self) -> np.ndarray:
        """Indices of the scenes already stored, merging any groups left pending first."""
        self.compact()
        return self._index_column()

    def _index_column(self) -> np.ndarray:
        import pyarrow.parquet as pq
        parts = sorted(self.directory.glob("part-*.parquet"))
        if not parts:
            return np.empty(0, dtype=np.int64)
        return np.concatenate([pq.read_table(p, columns=["index"]).column("index").to_numpy() for p in parts])

    # --------------------------------------------------------------- writing

    def add(self, columns: Mapping[str, object], trajectories: "pyarrow.Table | None" = None) -> None:
        """Store one group's rows (column name to values), as one pending file.

        Parameters
        ----------
        columns : mapping
            The group's columns, every one of :attr:`schema`.
        trajectories : pyarrow.Table, optional
            Its downsampled trajectories.
        """
        pa = self._pa
        table = pa.table({name: columns[name] for name in self.schema.names}, schema=self.schema)
        if not table.num_rows:
            return
        first = int(table.column("index")[0].as_py())
        stem = f"g{first:012d}"
        if trajectories is not None and trajectories.num_rows:
            _atomic(self.directory / _PENDING / f"{stem}.traj.arrow", lambda p: _write_ipc(p, trajectories))
        _atomic(self.directory / _PENDING / f"{stem}.arrow", lambda p: _write_ipc(p, table))
        self._pending_rows += table.num_rows
        if self._pending_rows >= _COMPACT_ROWS:
            self.compact()

    def compact(self) -> None:
        """Merge the pending groups into one new part (and their trajectories into the second table)."""
        import pyarrow.parquet as pq
        pa = self._pa
        pending = sorted((self.directory / _PENDING).glob("g*[0-9].arrow"))
        if not pending:
            self._pending_rows = 0
            return
        stored = np.sort(self._index_column()) if self._parts else np.empty(0, dtype=np.int64)
        tables, done = [], []
        for p in pending:
            t = _read_ipc(p)
            done.append(p)
            first = int(t.column("index")[0].as_py())
            at = np.searchsorted(stored, first)
            if at < stored.size and stored[at] == first:
                continue        # merged before a kill stopped the clean-up
            tables.append(t)
            traj = p.with_name(p.name.replace(".arrow", ".traj.arrow"))
            if traj.exists():
                tp = self.directory / _TRAJECTORIES
                tp.mkdir(exist_ok=True)
                name = f"part-{p.stem}.parquet"
                _atomic(tp / name, lambda q, t=_read_ipc(traj): pq.write_table(t, q))
        if tables:
            merged = pa.concat_tables(tables).cast(self.schema)
            name = f"part-{self._parts:06d}.parquet"
            _atomic(self.directory / name, lambda q: pq.write_table(merged, q, compression="zstd"))
            self._parts += 1
        for p in done:
            p.with_name(p.name.replace(".arrow", ".traj.arrow")).unlink(missing_ok=True)
            p.unlink(missing_ok=True)
        self._pending_rows = 0


def _write_ipc(path: Path, table) -> None:
    import pyarrow as pa
    with pa.OSFile(str(path), "wb") as sink, pa.ipc.new_file(sink, table.schema) as writer:
        writer.write_table(table)


def _read_ipc(path: Path):
    import pyarrow as pa
    with pa.memory_map(str(path)) as source:
        return pa.ipc.open_file(source).read_all()


def read(directory) -> "pandas.DataFrame":
    """A results store as a pandas DataFrame, one row per scene, in scene order.

    Parameters
    ----------
    directory : str or Path
        The folder ``analogy batch`` wrote.
    """
    import pandas as pd
    _pa()
    path = Path(directory)
    if not (path / _MANIFEST).exists():
        raise InputError(f"{path} is not a results store (no {_MANIFEST}): run analogy batch -o {path} first")
    parts = sorted(path.glob("part-*.parquet"))
    if not parts:
        return pd.DataFrame()
    frame = pd.read_parquet(path)
    return frame.sort_values("index", kind="stable").reset_index(drop=True)


def read_trajectories(directory) -> "pandas.DataFrame":
    """The downsampled trajectories of a store (``analogy batch --trajectories N``), long form.

    Parameters
    ----------
    directory : str or Path
        The folder ``analogy batch`` wrote.
    """
    import pandas as pd
    path = Path(directory) / _TRAJECTORIES
    if not path.is_dir() or not any(path.glob("part-*.parquet")):
        raise InputError(f"{directory} holds no trajectories: the sweep was run without keeping any",
                         field="trajectories")
    return pd.read_parquet(path)


def manifest(directory) -> dict:
    """The sweep description a store was written for.

    Parameters
    ----------
    directory : str or Path
        The folder.
    """
    path = Path(directory) / _MANIFEST
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        raise InputError(f"{directory} is not a results store (no readable {_MANIFEST})") from None
