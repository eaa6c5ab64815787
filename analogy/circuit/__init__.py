"""Node coordinates and circuits: topology, node systems, elements, netlists, diagrams."""

__all__: list[str] = []
