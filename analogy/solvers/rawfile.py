"""Reader for SPICE raw files (ASCII and binary), as written by ``ngspice -b -r FILE``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["read_raw"]


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
