"""The stress suite: every family runs, no run marked ok breaks its bound, and units do not change the error."""

import csv
import math
import subprocess
import sys

import numpy as np
import pytest

from analogy.diagnostics.stress import FAMILY_TITLES, cases
from analogy.diagnostics.stress.families import spd_with_spectrum


def test_a_spd_matrix_with_a_set_spectrum_has_that_condition_number():
    import numpy as np
    m = spd_with_spectrum(np.logspace(0, 8, 6))
    assert np.linalg.cond(m) == pytest.approx(1e8, rel=1e-6) and np.all(np.linalg.eigvalsh(m) > 0)


def test_the_quick_subset_has_every_family():
    assert {c.family for c in cases(quick=True)} == set(FAMILY_TITLES)


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("stress")
    res = subprocess.run([sys.executable, "-m", "analogy", "stress", "--quick", "-o", str(out), "--no-progress"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    with (out / "stress.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    return out, rows, res.stdout


@pytest.mark.ngspice
@pytest.mark.deep       # the whole quick stress report: about a minute
def test_the_stress_report_has_every_family_and_no_ok_row_past_its_bound(quick_report):
    out, rows, stdout = quick_report
    assert {r["family"] for r in rows} == set(FAMILY_TITLES)
    for r in rows:
        err, bound = float(r["error"]), float(r["bound"])
        if r["status"] == "ok" and not r["message"].startswith(("horizon", "within 1e-3")):     # chaotic: judged by its horizon
            assert not err > bound, r
        if r["status"] == "outside bound":
            assert err > bound, r
    assert all((out / f"stress_{f}.png").exists() for f in FAMILY_TITLES)
    assert "| family | solver |" in (out / "stress.md").read_text() and "cost growth" in stdout
    assert "horizon inf" not in stdout      # a run that never departs says so in words


@pytest.mark.ngspice
@pytest.mark.deep
def test_the_error_does_not_depend_on_the_units(quick_report):
    """Family e: masses 1e-9 to 1e6, time scales 1e-6 to 1e4, velocities 1e-9 to 1e3: every
    solver within a factor of 10 of its unit-scale error (SPICE measured 7.0e-8 throughout)."""
    _, rows, _ = quick_report
    units = [r for r in rows if r["family"] == "e"]
    for solver in ("spice", "ode"):
        unit = next(float(r["error"]) for r in units if r["solver"] == solver and r["axis"] == "unit")
        for r in units:
            if r["solver"] == solver:
                assert r["status"] == "ok" and float(r["error"]) <= 10 * max(unit, 1e-14), r
                assert math.isfinite(float(r["error"]))


def test_the_3rrr_mass_matrix_grows_as_one_over_the_distance_to_its_singular_pose():
    """Near a parallel singularity M' ~ 1/δ: cond(M') grows a hundredfold per hundredfold closer."""
    from analogy.errors import InputError
    from analogy.scenes.builtin import scene
    from analogy.diagnostics.stress.families import singular_q1
    q1 = singular_q1()
    base = scene("parallel3")
    with pytest.raises(InputError):
        base.replace(q=(q1 + 1e-9, -1.7, 0.35)).system()       # past it the loop does not close
    conds = [np.linalg.cond(base.replace(q=(q1 - d, -1.7, 0.35)).system().mass) for d in (1e-2, 1e-4, 1e-6)]
    assert 50 < conds[1] / conds[0] < 200 and 50 < conds[2] / conds[1] < 200


def test_the_command_s_default_runs_every_family():
    from analogy.cli import build_parser
    from analogy.diagnostics.stress.families import ALL_FAMILIES
    assert build_parser().parse_args(["stress"]).families == ALL_FAMILIES
