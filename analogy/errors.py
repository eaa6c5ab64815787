"""Exception types that carry one clear, user-facing sentence."""

__all__ = ["AnalogyError", "InputError", "SimulationError", "SpiceError", "AccuracyError"]


class AnalogyError(Exception):
    """Base class: the message is a single sentence meant for the user."""


class InputError(AnalogyError, ValueError):
    """The user's input (matrix, vector, expression, option) is invalid."""


class SimulationError(AnalogyError, RuntimeError):
    """A solver could not produce a solution."""


class SpiceError(SimulationError):
    """ngspice failed: parse error, singular matrix or collapsed time step."""


class AccuracyError(AnalogyError):
    """A result is outside the accuracy bound it was promised to keep (exit code 3)."""
