"""Zero current sources whose corners steer ngspice's steps: its first step, a batch's horizons, a motion's clock."""

from __future__ import annotations

from .spice_numbers import spice_text as _num

__all__ = ["CLOCK_CORNERS", "first_step_lines"]

#: Corners a clock's zero current source holds: a PWL's value is found from its first corner on.
CLOCK_CORNERS = 64


def first_step_lines(settings, node: str) -> list[str]:
    """Zero current sources: one with corners at ``settings.breakpoint``, which makes ngspice's first
    (unchecked, backward Euler) step a hundredth of it, and at ``settings.horizons``, where shorter
    systems of a batch end; and the clock, ``settings.clock``, where the motion asks short steps, in
    sources of :data:`CLOCK_CORNERS` corners (ngspice finds a PWL's segment from its first corner
    at every evaluation: one source of 6,586 corners made the hopper's steps 2.5 times dearer);
    nothing when none is needed.

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
        lines.append(f"* zero currents; {len(clock)} corners from t = {_num(clock[0])} to {_num(clock[-1])} s keep "
                     "ngspice's steps short where the motion is fast")
    for k in range(0, len(clock), CLOCK_CORNERS):
        rows = [" ".join(f"{_num(t)} 0" for t in clock[j:min(j + 8, k + CLOCK_CORNERS)])
                for j in range(k, min(k + CLOCK_CORNERS, len(clock)), 8)]
        lines += [f"Iclock{k // CLOCK_CORNERS + 1} 0 {node} PWL(0 0 {rows[0]}"] + [f"+ {r}" for r in rows[1:]] + ["+ )"]
    return lines
