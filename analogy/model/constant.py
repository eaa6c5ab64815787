"""Models whose matrices do not depend on the configuration, kept as numpy arrays (no sympy at any size)."""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..errors import InputError
from .base import RobotModel
from .joint import JointStack, configuration_stack

__all__ = ["ConstantModel"]


class ConstantModel(RobotModel):
    """Constant M, B, K (no coordinates, no parameters): the same contract as a compiled model.

    Parameters
    ----------
    name : str
        The model's name.
    joint : JointSpace
        Its checked matrices.
    topology : str
        Default topology.
    description : str
        A few words.
    """

    coordinates: tuple = ()

    def __init__(self, name: str, joint: JointSpace, topology: str = "parallel", description: str = ""):
        self.name, self.joint, self.topology, self.description = name, joint, topology, description
        self.parameters = {}
        self.joints = self.units = None     # given by its numbers: no joint kinds declared

    def __repr__(self) -> str:
        return f"ConstantModel({self.name!r}, {self.dof} joints)"

    @property
    def dof(self) -> int:
        return self.joint.dof

    def _check(self, parameters):
        if parameters:
            raise InputError(f"model {self.name!r} has no parameters (got {', '.join(parameters)})")

    def joint_stack(self, qs, parameters: Mapping[str, float] | None = None) -> JointStack:
        """The matrices repeated for every (empty) row of *qs*.

        Parameters
        ----------
        qs : array_like, shape (count, 0)
            Configurations.
        parameters : mapping, optional
            Must be empty.
        """
        self._check(parameters)
        count = configuration_stack(self.name, (), qs).shape[0]
        j = self.joint
        def rep(a):
            return None if a is None else np.broadcast_to(a, (count,) + a.shape)
        return JointStack(rep(j.mass_matrix), rep(j.damping), rep(j.stiffness), rep(j.gravity))
