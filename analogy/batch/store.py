"""A sweep's results store: a Parquet dataset with one row per scene, written group by group, resumable."""

from __future__ import annotations

import json
import os
import uuid
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import numpy as np

from ..errors import AnalogyError, InputError

try:
    import fcntl
except ImportError:             # not on POSIX
    fcntl = None

if TYPE_CHECKING:
    import pandas
    import pyarrow

__all__ = ["ResultStore", "StoreError", "STATUSES", "RESERVED_COLUMNS", "manifest", "read", "read_trajectories",
           "status_counts"]

#: Row status: solved within the bound, outside it, a solver failed, the scene is invalid, its run is
#: past the work budget (refused before it starts), its worker died.
STATUSES = ("ok", "inaccurate", "failed", "invalid", "refused", "worker-died")

_MANIFEST = "_sweep.json"
_PENDING = "_pending"
_LOCK = "_lock"
_TRAJECTORIES = "_trajectories"
# Pending groups are merged into one Parquet file once this many scenes wait.
_COMPACT_ROWS = 50_000


#: Columns every row has besides its axes and solvers: no sweep axis may take these names.
RESERVED_COLUMNS = ("key", "scene", "status", "message")


class StoreError(AnalogyError):
    """The store cannot be written (a full disk, a read-only folder): what is stored is kept."""


def _damaged(path: Path, exc: BaseException) -> InputError:
    detail = " ".join(str(exc).split())[:160] or type(exc).__name__
    return InputError(f"{path} is damaged ({detail}): move it out of {path.parent}; running the sweep "
                      "again solves its scenes anew")


def _own_file(path: Path) -> Path:
    if path.is_symlink():
        raise InputError(f"{path} is a symlink, not a file of this store: remove it (running the sweep again "
                         "solves its scenes anew)")
    return path


def _read_manifest(path: Path) -> dict:
    """The manifest at *path*: a JSON object with the sweep's key, or one sentence."""
    try:
        data = json.loads(_own_file(path).read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        data = None
    if not isinstance(data, dict) or not isinstance(data.get("key"), str) or \
            not isinstance(data.get("size", 0), int) or not isinstance(data.get("scene", ""), str):
        raise InputError(f"{path} is not a sweep manifest (a JSON object with the sweep's key): restore it, "
                         "or use an empty folder")
    if (wrong := _wrong_field(data)) is not None:
        raise InputError(f"{path} is not a sweep manifest: its field {wrong} is not what a sweep writes; "
                         "restore it, or use an empty folder")
    return data


def _is(value, kinds: tuple, optional: bool = False) -> bool:
    """Whether *value* is one of *kinds* (a bool only where *kinds* names bool), or None where *optional*."""
    if value is None:
        return optional
    return bool in kinds if isinstance(value, bool) else isinstance(value, kinds)


#: A manifest's fields and their types, as :meth:`~analogy.batch.sweep.Sweep.describe` writes them
#: (an older store may lack some: only those present are judged).
_FIELDS = {"schema": (str,), "base_key": (str,), "method": (str,), "count": (int,), "seed": (int,),
           "group_size": (int,), "preset": (str,), "source": (str, type(None)), "isolated": (bool,)}


def _wrong_field(data: dict) -> str | None:
    """The first field of a manifest that does not have the type a sweep writes, or None."""
    for name, kinds in _FIELDS.items():
        if name in data and not _is(data[name], kinds):
            return repr(name)
    for name in ("solvers", "joint_units"):
        if name in data and not (isinstance(data[name], list) and all(isinstance(x, str) for x in data[name])):
            return repr(name)
    axes = data.get("axes", [])
    if not isinstance(axes, list):
        return "'axes'"
    for k, axis in enumerate(axes):
        numbers = (int, float)
        if not (isinstance(axis, dict) and isinstance(axis.get("name"), str)
                and _is(axis.get("values"), (list,), True) and _is(axis.get("low"), numbers, True)
                and _is(axis.get("high"), numbers, True) and isinstance(axis.get("log", False), bool)):
            return f"'axes'[{k}]"
    return None


def _parts(directory: Path) -> list[Path]:
    return [_own_file(p) for p in sorted(directory.glob("part-*.parquet"))]


def _read_part(path: Path, columns=None):
    """One part's rows (with its page checksums verified), or one sentence naming the damaged file."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    try:
        names = pq.read_schema(path).names
    except (OSError, pa.ArrowException, ValueError) as exc:
        raise _damaged(path, exc) from None
    # A part written before the scene number's column was renamed from 'index' (which pandas shadows).
    old = "index" in names and "scene" not in names
    names = ["scene" if old and n == "index" else n for n in names]
    missing = [c for c in (columns or RESERVED_COLUMNS) if c not in names]
    if missing:
        raise InputError(f"{path} is not a part of a sweep store (it has no {missing[0]!r} column): move it "
                         "out of the folder")
    wanted = None if columns is None else ["index" if old and c == "scene" else c for c in columns]
    try:
        table = pq.read_table(path, columns=wanted, page_checksum_verification=True)
    except (OSError, pa.ArrowException, ValueError) as exc:
        raise _damaged(path, exc) from None
    return _scene_column(table)


def status_counts(directory) -> dict[str, int]:
    """Rows of the store by status, merged parts and pending groups alike: every run's, not one run's.

    Parameters
    ----------
    directory : str or Path
        The store.
    """
    directory = Path(directory)
    statuses = [_read_part(p, ["status"]).column("status") for p in _parts(directory)]
    for p in sorted((directory / _PENDING).glob("g*[0-9].arrow")):
        try:
            statuses.append(_read_ipc(_own_file(p)).column("status"))
        except (OSError, ValueError, KeyError) as exc:
            raise _damaged(p, exc) from None
    counts: dict[str, int] = {}
    for column in statuses:
        for v in column.to_pylist():
            counts[v] = counts.get(v, 0) + 1
    return counts


def _computed(directory: Path) -> bool:
    """Whether the store holds a scene that was computed: any status but ``invalid``."""
    return any(status != "invalid" for status in status_counts(directory))


def _write(path: Path, write) -> None:
    """:func:`_atomic`, with a failed write (full disk, read-only folder) said in one sentence."""
    try:
        _atomic(path, write)
    except OSError as exc:
        raise StoreError(f"cannot write {path}: {exc.strerror or exc}: free space or make the folder writable, "
                         "then run the same command to resume (what is stored is kept)") from None


def _writer_lock(directory: Path):
    """An exclusive lock on the store, held while this process writes it, or one sentence.

    Two writers would each merge the pending groups and remove what the other wrote; the
    lock is the kernel's (flock), so a writer killed even with SIGKILL releases it.
    """
    if fcntl is None:           # not on POSIX: one writer at a time is the user's to keep
        return None
    try:
        handle = open(directory / _LOCK, "a+")
    except OSError as exc:
        raise StoreError(f"cannot write to {directory}: {exc.strerror or exc}") from None
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.close()
        raise InputError(f"another analogy batch is writing to {directory}: wait for it to end, or use "
                         "another folder") from None
    return handle


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
        self._lock = _writer_lock(self.directory)
        #: The sweep whose store this one replaced: it held no computed scene (none, or invalid ones only).
        self.replaced: str | None = None
        path = self.directory / _MANIFEST
        if path.exists() or path.is_symlink():
            old = _read_manifest(path)
            if old.get("key") != self.manifest["key"]:
                if not _computed(self.directory):
                    # every stored scene was invalid, so nothing computed is lost: the corrected sweep takes it
                    self._clear()
                    self.replaced = str(old.get("scene", "?"))
                    _write(path, lambda tmp: tmp.write_text(json.dumps(self.manifest, indent=1, default=str)))
                else:
                    raise InputError(f"{self.directory} holds the results of another sweep "
                                     f"({old.get('scene', '?')}, key {str(old.get('key'))[:12]}): "
                                     "use another folder, or the same sweep to resume it")
        else:
            stray = [p for p in self.directory.glob("part-*.parquet")]
            if stray:
                raise InputError(f"{self.directory} holds Parquet parts but no manifest: use an empty folder")
            _write(path, lambda tmp: tmp.write_text(json.dumps(self.manifest, indent=1, default=str)))
        for tmp in self.directory.rglob(".*.tmp"):     # from a run killed while writing
            tmp.unlink(missing_ok=True)
        names = [p.name for p in _parts(self.directory)]
        self._parts = len(names)
        # the next part's number follows the highest, so a copied-in or removed part is never overwritten
        self._next = 1 + max((int(n[5:11]) for n in names if n[5:11].isdigit()), default=-1)
        self._pending_rows = 0

    def _clear(self) -> None:
        """Remove every part, pending group and trajectory (under the writer lock)."""
        for folder, pattern in ((self.directory, "part-*.parquet"), (self.directory / _PENDING, "g*.arrow"),
                                (self.directory / _TRAJECTORIES, "part-*.parquet")):
            for p in folder.glob(pattern):
                try:
                    p.unlink()
                except OSError as exc:
                    raise StoreError(f"cannot remove {p}: {exc.strerror or exc}") from None

    def close(self) -> None:
        """Let another writer have the folder (the lock also ends with the process, however it ends)."""
        if self._lock is not None:
            self._lock.close()
            self._lock = None

    # --------------------------------------------------------------- reading

    def stored_indices(self) -> np.ndarray:
        """Indices of the scenes already stored, merging any groups left pending first."""
        self.compact()
        return self._index_column()

    def _index_column(self) -> np.ndarray:
        parts = _parts(self.directory)
        if not parts:
            return np.empty(0, dtype=np.int64)
        return np.unique(np.concatenate([_read_part(p, ["scene"]).column("scene").to_numpy() for p in parts]))

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
        first = int(table.column("scene")[0].as_py())
        stem = f"g{first:012d}"
        if trajectories is not None and trajectories.num_rows:
            _write(self.directory / _PENDING / f"{stem}.traj.arrow", lambda p: _write_ipc(p, trajectories))
        _write(self.directory / _PENDING / f"{stem}.arrow", lambda p: _write_ipc(p, table))
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
            try:
                t = _read_ipc(_own_file(p))
            except (OSError, self._pa.ArrowException, ValueError) as exc:
                raise _damaged(p, exc) from None
            done.append(p)
            first = int(t.column("scene")[0].as_py())
            at = np.searchsorted(stored, first)
            if at < stored.size and stored[at] == first:
                continue        # merged before a kill stopped the clean-up
            tables.append(t)
            traj = p.with_name(p.name.replace(".arrow", ".traj.arrow"))
            if traj.exists():
                tp = self.directory / _TRAJECTORIES
                tp.mkdir(exist_ok=True)
                name = f"part-{p.stem}.parquet"
                _write(tp / name, lambda q, t=_read_ipc(traj): pq.write_table(t, q))
        if tables:
            merged = pa.concat_tables(tables).cast(self.schema)
            name = f"part-{self._next:06d}.parquet"
            _write(self.directory / name, lambda q: pq.write_table(merged, q, compression="zstd",
                                                                   write_page_checksum=True))
            self._parts += 1
            self._next += 1
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
        return _scene_column(pa.ipc.open_file(source).read_all())


def _scene_column(table):
    """*table* with an older store's 'index' column named 'scene', as it is now."""
    names = table.column_names
    if "index" in names and "scene" not in names:
        return table.rename_columns(["scene" if n == "index" else n for n in names])
    return table


def read(directory) -> "pandas.DataFrame":
    """A results store as a pandas DataFrame, one row per scene, in scene order.

    Parameters
    ----------
    directory : str or Path
        The folder ``analogy batch`` wrote.
    """
    import pandas as pd
    pa = _pa()
    path = Path(directory)
    if not (path / _MANIFEST).exists():
        raise InputError(f"{path} is not a results store (no {_MANIFEST}): run analogy batch -o {path} first")
    _read_manifest(path / _MANIFEST)
    tables = [_read_part(p) for p in _parts(path)]
    if not tables:
        return pd.DataFrame()
    try:
        frame = pa.concat_tables(tables, promote_options="permissive").to_pandas()
    except (pa.ArrowException, ValueError) as exc:
        raise InputError(f"the parts of {path} do not share one schema ({' '.join(str(exc).split())[:120]}): "
                         "move the foreign part out of the folder") from None
    frame = frame.sort_values("scene", kind="stable")
    # a part copied in twice holds the same scenes again: each scene counts once
    frame = frame[~frame.duplicated(["scene", "key"])]
    if frame["scene"].duplicated().any():
        raise InputError(f"{path} holds two different scenes under one index: a part of another store was "
                         "copied in; move it out of the folder")
    return frame.reset_index(drop=True)


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
    frame = pd.read_parquet(path)
    # a store written before the rates were named r1 …, as everywhere else, called them rate1 …
    return frame.rename(columns={c: "r" + c[4:] for c in frame.columns if c.startswith("rate") and c[4:].isdigit()})


def manifest(directory) -> dict:
    """The sweep description a store was written for.

    Parameters
    ----------
    directory : str or Path
        The folder.
    """
    path = Path(directory) / _MANIFEST
    if not path.exists():
        raise InputError(f"{directory} is not a results store (no {_MANIFEST})")
    return _read_manifest(path)
