"""Readers of ngspice's output: raw files (``ngspice -b -r FILE``) and the tables ``.print`` writes."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["read_raw", "read_printed"]


def read_raw(path) -> dict[str, np.ndarray]:
    """Read the first real-valued plot of a raw file into ``{vector name: values}``.

    Node voltages are keyed by node name (``v(n1)`` becomes ``n1``).

    Parameters
    ----------
    path : str or Path
        A raw file.
    """
    data = Path(path).read_bytes()
    header = {}
    names: list[str] = []
    pos = 0
    while True:
        end = data.find(b"\n", pos)
        if end < 0:
            raise InputError(f"{path}: truncated raw file")
        line = data[pos:end].decode("latin-1").rstrip("\r")
        pos = end + 1
        key, _, value = line.partition(":")
        key = key.strip().lower()
        if key == "variables":
            count = int(header["no. variables"])
            for _ in range(count):
                end = data.find(b"\n", pos)
                fields = data[pos:end].decode("latin-1").split()
                pos = end + 1
                name = fields[1].lower()
                if name.startswith("v(") and name.endswith(")"):
                    name = name[2:-1]
                names.append(name)
            continue
        if key in ("values", "binary"):
            kind = key
            break
        header[key] = value.strip()
    if "complex" in header.get("flags", "").lower():
        raise InputError(f"{path}: complex raw files are not supported")
    nvar, npts = int(header["no. variables"]), int(header["no. points"])
    if kind == "binary":
        arr = np.frombuffer(data, dtype="<f8", count=nvar * npts, offset=pos).reshape(npts, nvar)
    else:
        tokens = data[pos:].decode("latin-1").split()
        # each point: index, then nvar values
        values = [float(tok) for i, tok in enumerate(tokens[: npts * (nvar + 1)]) if i % (nvar + 1)]
        arr = np.array(values).reshape(npts, nvar)
    return {name: arr[:, k].copy() for k, name in enumerate(names)}


def read_printed(text: str) -> dict[str, np.ndarray]:
    """The tables ``.print tran`` writes to ``ngspice -b``'s standard output, as ``{vector: values}``.

    ngspice splits many vectors over several tables, each headed ``Index time v(n1) …``
    and continued over pages; the rows of each vector are joined by index. Node voltages
    are keyed by node name (``v(n1)`` becomes ``n1``), as :func:`read_raw` does.

    Parameters
    ----------
    text : str
        What ``ngspice -b`` printed.
    """
    columns: dict[str, dict[int, float]] = {}
    names: list[str] = []
    for line in text.splitlines():
        words = line.split()
        if words[:1] == ["Index"]:
            names = [w[2:-1] if w.lower().startswith("v(") and w.endswith(")") else w for w in words[1:]]
            for name in names:
                columns.setdefault(name, {})
        elif names and words and words[0].isdigit() and len(words) == len(names) + 1:
            try:
                values = [float(w) for w in words[1:]]
            except ValueError:
                continue
            for name, value in zip(names, values):
                columns[name][int(words[0])] = value
        elif words and not words[0].startswith("-"):
            names = names if words[0].isdigit() else []
    if "time" not in columns or not columns["time"]:
        raise InputError("no .print table in ngspice's output")
    size = len(columns["time"])
    out = {}
    for name, rows in columns.items():
        if len(rows) != size:
            raise InputError(f"ngspice printed {len(rows)} rows of {name} and {size} of time")
        out[name] = np.array([rows[k] for k in sorted(rows)])
    return out
