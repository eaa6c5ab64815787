"""Scenes: simulation jobs as pure data with a content key, built-in and from TOML files."""

__all__: list[str] = []
