"""The mechanical diagram's symbols, drawn with schemdraw: a mass block, an MP model, a dashpot, a spring, a force."""

from __future__ import annotations

import numpy as np
import schemdraw.elements as elm
from schemdraw.segments import Segment, SegmentCircle, SegmentPoly

__all__ = ["MassBlock", "MPModel", "Dashpot", "Spring", "Force", "LinkGround"]

_GAP = (float("nan"), float("nan"))   # pen up inside a schemdraw segment path

# Segment 0 spans each symbol; schemdraw extends leads from its ends.


class MassBlock(elm.Element2Term):
    """A mass: a block on its node, tied to the ground reference by a dotted line."""

    def __init__(self, length: float = 3.0, **kwargs):
        super().__init__(**kwargs)
        self.segments.append(Segment([(0, 0), _GAP, (length, 0)]))
        self.segments.append(Segment([(0, 0), (0.8, 0)]))
        self.segments.append(SegmentPoly([(0.8, -0.55), (1.9, -0.55), (1.9, 0.55), (0.8, 0.55)],
                                         fill="#d9d9d9"))
        self.segments.append(Segment([(1.9, 0), (length, 0)], ls=":"))


class MPModel(elm.Element2Term):
    """An MP (mass/pulley) model: a two-terminal box holding a double pulley and its mass."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.segments.append(Segment([(0, 0), _GAP, (1.6, 0)]))
        self.segments.append(SegmentPoly([(0, -0.45), (1.6, -0.45), (1.6, 0.45), (0, 0.45)], fill="#e3ecf7"))
        self.segments.append(SegmentCircle((0.55, 0.08), 0.2))
        self.segments.append(SegmentCircle((1.05, 0.08), 0.2))
        self.segments.append(Segment([(0.8, 0.08), (0.8, -0.22)]))
        self.segments.append(SegmentPoly([(0.68, -0.22), (0.92, -0.22), (0.92, -0.38), (0.68, -0.38)],
                                         fill="black"))


class Dashpot(elm.Element2Term):
    """A damper: a cylinder open to one side and a piston."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.segments.append(Segment([(0, 0), _GAP, (1.1, 0)]))
        self.segments.append(Segment([(0.75, 0.28), (0, 0.28), (0, -0.28), (0.75, -0.28)]))
        self.segments.append(Segment([(0.4, 0.2), (0.4, -0.2)], lw=2.5))
        self.segments.append(Segment([(0.4, 0), (1.1, 0)]))


class Spring(elm.Element2Term):
    """A spring: a zigzag."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        pts = [(0.0, 0.0)] + [(0.1 + 0.15 * i, 0.25 * (-1) ** i) for i in range(8)] + [(1.3, 0.0)]
        self.segments.append(Segment(pts))


class Force(elm.Element2Term):
    """A force: a bold arrow from the reacting terminal to the driven one."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.segments.append(Segment([(0, 0), _GAP, (1.0, 0)]))
        self.segments.append(Segment([(0, 0), (1.0, 0)], arrow="->", lw=3,
                                     arrowwidth=0.4, arrowlength=0.45))


class LinkGround(elm.Element):
    """Mechanical ground: a hatched line."""

    _element_defaults = {"theta": 0, "drop": (0, 0)}

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.segments.append(Segment([(-0.4, 0), (0.4, 0)], lw=2))
        for x in np.linspace(-0.35, 0.35, 5):
            self.segments.append(Segment([(x + 0.05, 0), (x - 0.1, -0.2)]))
        self.anchors["start"] = (0, 0)
