"""Robots that touch the ground: the one-legged hopper, a body on a springy leg with a foot."""

from __future__ import annotations

import sympy as sp

from .contact import Contact
from .symbolic import Model

__all__ = ["hopper", "HOPPER"]

#: The hopper's default parameters: a 1 kg body on a 0.3 m leg of 1 kN/m, a 0.1 kg foot, and a
#: ground of 10 kN/m and 20 N·s/m. Standing, the foot sinks (mb + mf)·g/kc = 1.08 mm; the
#: smoothing length δ = 10 µm is under 1 % of that, so a stance is the linear oscillator to 1 %.
HOPPER = {"mb": 1.0, "mf": 0.1, "l0": 0.3, "kl": 1000.0, "bl": 6.0, "kc": 2000.0, "cc": 10.0, "delta": 1e-4,
          "g": 9.81}


def hopper(**values: float) -> Model:
    """A one-legged hopper moving vertically: a body on a prismatic leg, a foot that meets the ground.

    q1 = z is the body's height and q2 = d the foot's height relative to the body (−l0 at the
    leg's rest length), so the foot is at y = z + d. The body mass mb and the foot mass mf give
    M = [[mb + mf, mf], [mf, mf]]; in the serial topology the nodes are the body's and the
    foot's velocities, each mass a grounded capacitor and the leg a floating resistor bl and
    spring kl between them. The leg's spring rests at d = −l0 whatever pose the run starts at,
    so it is part of the potential U = g·(mb·z + mf·y) + kl·(d + l0)²/2, with G = ∂U/∂q. The
    foot's contact with the ground (:mod:`analogy.model.contact`) is a one-port from the foot's
    node to ground: a diode-like spring kc and damper cc, switched on over delta.

    Parameters
    ----------
    **values : float
        Overrides of :data:`HOPPER`.
    """
    params = dict(HOPPER, **values)
    z, d = sp.symbols("q1 q2", real=True)
    mb, mf, l0, kl, bl, kc, cc, delta, g = sp.symbols("mb mf l0 kl bl kc cc delta g", real=True)
    foot = z + d
    potential = g * (mb * z + mf * foot) + kl * (d + l0) ** 2 / 2
    gravity = [sp.diff(potential, z), sp.diff(potential, d)]
    mass = sp.Matrix([[mb + mf, mf], [mf, mf]])
    return Model("hopper", mass, damping=[0, bl], gravity=gravity, parameters=params, coordinates=(z, d),
                 topology="serial", joints=("prismatic", "prismatic"),
                 contacts=(Contact("foot", foot, kc, cc, delta),),
                 description="a one-legged hopper: body height z, foot height d below it, the foot on a "
                             "one-sided ground contact")
