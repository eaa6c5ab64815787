"""Exception types that carry one clear, user-facing sentence, and the exit codes they map to."""

from contextlib import contextmanager
from typing import Iterator, Literal, Mapping

__all__ = ["AnalogyError", "InputError", "one_line", "SimulationError", "SpiceError", "AccuracyError", "InputField", "concerning",
           "located", "rendered", "EXIT_OK", "EXIT_FAILED", "EXIT_USAGE", "EXIT_ACCURACY", "EXIT_INTERRUPTED"]

#: The parts of a job an input error can concern; each front end names them its own way
#: (``--mass`` on the command line, ``[model] mass`` in a scene file).
InputField = Literal["robot", "urdf", "joints", "mass", "damping", "stiffness", "gravity", "parameters", "q",
                     "topology", "forces", "initial_rates", "t_stop", "step", "preset", "dynamics", "link_modes",
                     "joint_frame", "geometric_stiffness", "model", "inputs", "budget", "output", "trajectories",
                     "motors", "voltages"]

#: Exit codes of the command line: success, a simulation failed, bad input, a result outside its
#: accuracy bound, and stopped by SIGINT or SIGTERM.
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_ACCURACY, EXIT_INTERRUPTED = 0, 1, 2, 3, 130


class AnalogyError(Exception):
    """Base class: the message is a single sentence meant for the user."""


class InputError(AnalogyError, ValueError):
    """The user's input (matrix, vector, expression, option) is invalid.

    Parameters
    ----------
    message : str
        One sentence for the user.
    field : InputField, optional
        The part of the job it concerns, where the raiser knows it.
    """

    def __init__(self, message: str = "", field: InputField | None = None):
        super().__init__(one_line(message))
        self.field = field
        #: The message already says where, in a front end's words (:func:`located`).
        self.located = False


def one_line(text: str) -> str:
    """*text* on one line: a control character (a user's string may bring one in) shown escaped.

    Parameters
    ----------
    text : str
        A message.
    """
    text = str(text)
    return text if text.isprintable() else "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in text)


@contextmanager
def concerning(field: InputField) -> Iterator[None]:
    """An :class:`InputError` raised inside, and not yet placed, concerns *field*.

    Parameters
    ----------
    field : InputField
        The part of the job the enclosed work checks.
    """
    try:
        yield
    except InputError as exc:
        if exc.field is None:
            exc.field = field
        raise


@contextmanager
def located(label: str | None) -> Iterator[None]:
    """An :class:`InputError` raised inside is prefixed with *label*, a front end's words for
    where it is (``--mass``, ``scene.toml: [model] mass``); its field is kept.

    Parameters
    ----------
    label : str or None
        The place; None leaves the message alone.
    """
    try:
        yield
    except InputError as exc:
        if label is None:
            raise
        placed = InputError(f"{label}: {' '.join(str(exc).split())}", field=exc.field)
        placed.located = True
        raise placed from None


@contextmanager
def rendered(labels: Mapping[str, str]) -> Iterator[None]:
    """An :class:`InputError` raised inside that names its field and is not yet placed is placed
    in a front end's words: *labels* maps each field to them.

    Parameters
    ----------
    labels : mapping of str to str
        A front end's words for each field (``CLI_KEYS``, ``TOML_KEYS``).
    """
    try:
        yield
    except InputError as exc:
        if exc.located or exc.field not in labels:
            raise
        with located(labels[exc.field]):
            raise exc from None


class SimulationError(AnalogyError, RuntimeError):
    """A solver could not produce a solution."""


class SpiceError(SimulationError):
    """ngspice failed: parse error, singular matrix or collapsed time step."""


class AccuracyError(AnalogyError):
    """A result is outside the accuracy bound it was promised to keep (exit code 3)."""
