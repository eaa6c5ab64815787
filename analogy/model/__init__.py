"""Mechanical models: M(q), B, K, G(q) and velocity terms, symbolic or numeric (the data path's start)."""

__all__: list[str] = []
