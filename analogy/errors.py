"""Exception types that carry one clear, user-facing sentence, and the exit codes they map to."""

__all__ = ["AnalogyError", "InputError", "SimulationError", "SpiceError", "AccuracyError", "EXIT_OK", "EXIT_FAILED",
           "EXIT_USAGE", "EXIT_ACCURACY", "EXIT_INTERRUPTED"]

#: Exit codes of the command line: success, a simulation failed, bad input, a result outside its
#: accuracy bound, and stopped by SIGINT or SIGTERM.
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_ACCURACY, EXIT_INTERRUPTED = 0, 1, 2, 3, 130


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
