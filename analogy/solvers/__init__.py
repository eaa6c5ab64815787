"""Registered solvers (spice, ode, exact, …) that turn node dynamics into trajectories."""

__all__: list[str] = []
