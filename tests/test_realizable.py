"""The realizable circuit: no negative element values, same dynamics as the signed circuit."""

import re

import numpy as np
import pytest

from analogy import netlist, solve_exact
from analogy.scenes.builtin import SCENES, scene

pytestmark = pytest.mark.ngspice

_VALUE = re.compile(r"^([CRL]\S*) \S+ \S+ (\S+)$")


def element_values(text):
    return [float(m.group(2)) for m in map(_VALUE.match, text.splitlines()) if m]


# flexpar's realizable circuit misses 1e-6 of the largest peak at accurate (1.5e-5 measured: its
# undamped modes' trapezoidal phase error, flagged by compare with exit 3): the step its phase
# error asks is taken by plain linear circuits only, so the signed one keeps the bound
class BoundMissed(AssertionError):
    """Both circuits ran, structurally right, but missed the accurate bound."""


_FLEXPAR = [pytest.mark.xfail(strict=True, raises=BoundMissed,
                              reason="the accurate run misses 1e-6 on flexpar, signed and realizable alike"),
            pytest.mark.deep]


@pytest.mark.parametrize("name", [pytest.param(n, marks=_FLEXPAR) if n == "flexpar" else n for n in SCENES
                                  if SCENES[n].dynamics == "linear"])
def test_realizable_netlist_has_no_negative_values_and_matches_signed(name):
    from analogy.solvers.spice import run_netlist
    s = scene(name).system()
    signed, real = netlist(s, "accurate"), netlist(s, "accurate", realizable=True)
    assert all(v > 0 for v in element_values(real))
    n_negative = sum(v < 0 for v in element_values(signed))
    assert real.count("\nF") == n_negative          # one inverting coupling per negative element
    runs = {}
    for label, text in (("signed", signed), ("realizable", real)):
        d = run_netlist(text, s.nodes)
        v = np.column_stack([d[n] for n in s.nodes])
        exact = solve_exact(s, d["time"])
        peak = np.max(np.abs(exact.rates))
        runs[label] = np.max(np.abs(s.joint_rates(v) - exact.rates)) / peak
    if not (runs["signed"] <= 1e-6 and runs["realizable"] <= 1e-6):
        raise BoundMissed(f"signed {runs['signed']:.3g}, realizable {runs['realizable']:.3g}")


def test_default_scene_needs_one_inverting_coupling():
    """Serial 2-DOF at q2 = 0.3: only the MP capacitance c12 is negative."""
    real = netlist(scene("default").system(), realizable=True)
    assert re.search(r"^EC1_2 c1_2_x 0 n2 n1 1$", real, re.M)
    assert re.search(r"^FC1_2 n1 n2 VC1_2 1$", real, re.M)
