"""Zero current sources whose corners steer ngspice's steps: its first step, a batch's horizons, a motion's clock."""

from __future__ import annotations

from .spice_numbers import spice_text as _num

__all__ = ["first_step_lines"]


def first_step_lines(settings, node: str) -> list[str]:
    """Zero current sources: one with corners at ``settings.breakpoint``, which makes ngspice's first
    (unchecked, backward Euler) step a hundredth of it, and at ``settings.horizons``, where shorter
    systems of a batch end; and the clock, ``settings.clock``, where the motion asks short steps
    (one source: split in sources of 8, 64 or 512 corners, the hopper's 6,586 ran 2.0, 1.2 and 1.2
    times as long in plain ngspice); nothing when none is needed.

    Parameters
    ----------
    settings : TransientSettings
        The spice solver's settings.
    node : str
        A node of the circuit to hang the sources on (they carry no current).
    """
    horizons, clock = tuple(getattr(settings, "horizons", ())), tuple(getattr(settings, "clock", ()))
    lines = []
    if settings.breakpoint is not None or horizons:
        first = [settings.breakpoint] if settings.breakpoint is not None else []
        why = [f"its {'first ' if horizons else ''}corner sets ngspice's first step to a hundredth of its time"] * len(
            first) + (["ngspice steps onto the ends of the shorter systems"] if horizons else [])
        lines += [f"* zero current; {'; '.join(why)}",
                  f"Ifirst_step 0 {node} PWL(0 0 " + " ".join(f"{_num(t)} 0" for t in [*first, *horizons]) + ")"]
    if clock:
        rows = [" ".join(f"{_num(t)} 0" for t in clock[j:j + 8]) for j in range(0, len(clock), 8)]
        lines += [f"* zero current; {len(clock)} corners from t = {_num(clock[0])} to {_num(clock[-1])} s keep "
                  "ngspice's steps short where the motion is fast",
                  "* where ngspice stops at 'timestep too small' in them, analogy's own run raises abstol and vntol "
                  "1e3, then 1e6 times, then drops this source",
                  f"Iclock 0 {node} PWL(0 0 {rows[0]}"] + [f"+ {r}" for r in rows[1:]] + ["+ )"]
    return lines
