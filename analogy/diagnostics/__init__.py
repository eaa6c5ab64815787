"""The diagnostics, in one place: run time against error, stress families, throughput, memory and the calibration."""

__all__: list[str] = []
