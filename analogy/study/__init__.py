"""Studies of solved systems: solvers compared on shared grids, horizons, mobility checks, the work guard."""

__all__: list[str] = []
