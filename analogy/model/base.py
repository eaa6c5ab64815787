"""The model contract: M, B, K and G at a stack of poses, the single pose derived from it, capabilities declared."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import ClassVar, Mapping, Sequence

import numpy as np

from ..errors import InputError
from .dynamics import MechanicalFunctions
from .joint import JointSpace, JointStack, check_vector

__all__ = ["RobotModel"]


class RobotModel(ABC):
    """What every robot model gives the circuit and the solvers, however it was loaded.

    A model evaluates its joint-space M(q), B, K and G at a stack of poses
    (:meth:`joint_stack`, the one evaluation a subclass writes); the single pose
    (:meth:`joint_space`) is derived from it, as ``scipy.integrate.OdeSolver`` derives its
    forms from one step. What a model can do beyond that is declared as a class attribute,
    never probed:

    - :attr:`nonlinear`: :meth:`mechanical_functions` gives M(q), c(q, q̇) and G(q) for the
      nonlinear circuit and the ODE (symbolic models and rigid trees; a compiled or constant
      model holds only its linear parts);
    - :attr:`closed_chain`: passive joints held by loop constraints (:meth:`assemble`);
    - :attr:`rigid_tree`: a URDF's kinematic tree, whose recursions write the nonlinear circuit.

    Attributes
    ----------
    name : str
        Short identifier, written into netlist headers.
    coordinates : sequence
        The joint coordinates q (names or sympy symbols); empty for a constant model.
    parameters : mapping of str to float
        The parameters' values.
    topology : str
        The default joint-to-node map.
    description : str
        One line for reports.
    joints : sequence of str or None
        Each coordinate's kind (``revolute``, ``prismatic``, ``modal``); None: not declared.
    joint_names : sequence of str or None
        The joints' own names (a URDF's); None: q1 … qn.
    """

    nonlinear: ClassVar[bool] = False
    closed_chain: ClassVar[bool] = False
    rigid_tree: ClassVar[bool] = False
    joints: Sequence[str] | None = None
    joint_names: Sequence[str] | None = None

    @property
    @abstractmethod
    def dof(self) -> int:
        """Number of joint coordinates the circuit has a node for."""

    @abstractmethod
    def joint_stack(self, qs, parameters: Mapping[str, float] | None = None) -> JointStack:
        """M, B, K and G at every row of *qs* at once (unchecked: the node systems check them).

        Parameters
        ----------
        qs : array_like, shape (count, len(coordinates))
            Configurations.
        parameters : mapping, optional
            Parameter overrides by name: one number, or one per row where the model allows it.
        """

    def joint_space(self, q: Sequence[float] | None = None,
                    parameters: Mapping[str, float] | None = None) -> JointSpace:
        """M, B, K and G at configuration *q*, checked: row 0 of :meth:`joint_stack`.

        Parameters
        ----------
        q : sequence of float, optional
            Joint coordinates, one per entry of :attr:`coordinates` (none for a constant model).
        parameters : mapping, optional
            Parameter overrides by name.
        """
        if parameters:
            rebuilt = self.with_parameters(parameters)
            if rebuilt is not self:     # other parameters made another model (a flexible arm's mode count)
                return rebuilt.joint_space(q)
        names = [str(c) for c in self.coordinates]
        q = [] if q is None else list(q)
        if len(q) != len(names):
            raise InputError(f"model {self.name!r} needs {len(names)} joint coordinates "
                             f"({', '.join(names) or 'none'}), got {len(q)}")
        row = check_vector("configuration q", q, len(q)) if q else np.zeros(0)
        stack = self.joint_stack(row[None, :], parameters)
        return JointSpace(*(None if part is None else np.array(part[0]) for part in stack))

    def with_parameters(self, parameters: Mapping[str, float] | None = None) -> "RobotModel":
        """The model at other parameter values, where they change what it is (a flexible arm's mode
        shapes, a URDF's gravity); itself where its parameters are taken when it is evaluated.

        Parameters
        ----------
        parameters : mapping, optional
            Parameter overrides by name.
        """
        return self

    def mechanical_functions(self, parameters: Mapping[str, float] | None = None) -> MechanicalFunctions:
        """M(q), c(q, q̇) and G(q) at fixed parameters, for the nonlinear dynamics (where :attr:`nonlinear`).

        Parameters
        ----------
        parameters : mapping, optional
            Parameter overrides by name.
        """
        raise InputError(f"model {self.name!r} has no symbolic M(q): nonlinear dynamics need a symbolic model")

    @property
    def elastic(self) -> tuple[int, ...]:
        """The coordinates (0-based) that carry a spring of the model's own: none unless the model says."""
        return ()

    def pose_note(self, q: Sequence[float], parameters: Mapping[str, float] | None = None) -> str | None:
        """A warning about pose *q* the netlist and the command line repeat (a closed chain near a singular
        pose), or None.

        Parameters
        ----------
        q : sequence of float
            The pose.
        parameters : mapping, optional
            Parameter overrides.
        """
        return None
