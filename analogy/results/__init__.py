"""Trajectories, the error metric, and comparisons of solvers on shared time points."""

__all__: list[str] = []
