"""One solver's part in a comparison: its run, its errors against the reference, its estimate, its status."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from ..results.metrics import OutputErrors
from ..results.trajectory import SolverStats, Trajectory

__all__ = ["SolverRecord", "RecordStatus"]

RecordStatus = Literal["ok", "failed", "skipped"]


@dataclass(eq=False, slots=True)
class SolverRecord:
    """Everything a comparison knows of one solver, in one place.

    Attributes
    ----------
    name : str
        The registered solver's name.
    status : {"ok", "failed", "skipped"}
        It ran; it failed (the others still ran); or it does not apply to the system.
    reason : str
        Why it failed or does not apply (``""`` when it ran).
    trajectory : Trajectory or None
        Its run on the comparison's shared time points.
    own : Trajectory or None
        Its run on its own points, where its errors are measured (the same object when
        the shared points are its own).
    errors : OutputErrors or None
        Every output against the reference on its own points, each against its own peak
        (None without a reference).
    estimate : OutputErrors or None
        Its errors estimated without a reference, when asked for.
    unestimated : str
        Why an estimate asked for could not be made (``""`` otherwise).
    energy : float or None
        Nonlinear systems: max |T + U − T(0) − W| over the energy scale along its run.
    loop : (float, float) or None
        Closed chains: the largest loop residual |Φ| and the largest equilibrated cond(Φ_p).
    """

    name: str
    status: RecordStatus = "ok"
    reason: str = ""
    trajectory: Trajectory | None = None
    own: Trajectory | None = None
    errors: OutputErrors | None = None
    estimate: OutputErrors | None = None
    unestimated: str = ""
    energy: float | None = None
    loop: tuple[float, float] | None = None

    @property
    def ran(self) -> bool:
        """True if the solver produced a trajectory."""
        return self.status == "ok"

    @property
    def stats(self) -> SolverStats | None:
        """Its run's statistics (steps, evaluations, wall time), None if it did not run."""
        return None if self.trajectory is None else self.trajectory.stats

    @property
    def relative_error(self) -> float:
        """Its worst output's error over that output's own peak (NaN without a reference)."""
        return math.nan if self.errors is None else self.errors.relative

    def __repr__(self) -> str:
        if not self.ran:
            return f"<SolverRecord {self.name}: {self.status}: {self.reason}>"
        err = "" if self.errors is None else f", error/peak {self.errors.relative:.2e}"
        guess = "" if self.estimate is None else f", estimated {self.estimate.relative:.2e}"
        return f"<SolverRecord {self.name}: {self.trajectory.run_time * 1e3:.3g} ms{err}{guess}>"
