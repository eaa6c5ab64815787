"""Frequency responses: SPICE's .ac sweep against (M's + B' + K'/s)⁻¹, resonances at the natural frequencies."""

import numpy as np
import pytest

from analogy.cli import main
from analogy.errors import InputError
from analogy.model.joint import JointSpace
from analogy.circuit.node_system import node_system
from analogy.results.frequency import frequency_grid
from analogy.solvers.exact import exact_mobility
from analogy.results.modes import natural_modes
from analogy.scenes.scene import Scene
from analogy.scenes.spec import ModelSpec


def one_mass(m=2.0, b=0.3, k=50.0):
    return node_system(JointSpace([[m]], [[b]], [[k]]), forces=[1.0])


def test_one_mass_mobility_is_one_over_ms_plus_b_plus_k_over_s():
    f = frequency_grid(0.1, 100, 50)
    y = exact_mobility(one_mass(), f).mobility[:, 0, 0]
    s = 2j * np.pi * f
    np.testing.assert_allclose(y, 1 / (2.0 * s + 0.3 + 50.0 / s), rtol=1e-14)


def test_one_mass_resonance_is_at_sqrt_k_over_m_whatever_its_damping():
    """Im(1/Y) = mω − k/ω vanishes at ω = √(k/m) for any b."""
    for b in (0.0, 0.3, 3.0):
        r = exact_mobility(one_mass(b=b), frequency_grid(0.1, 100, 20)).resonances()
        assert r.size == 1 and r[0] == pytest.approx(np.sqrt(25.0) / (2 * np.pi), rel=1e-3)


def test_frequency_grid_is_ngspice_dec_sweep_and_bad_sweeps_are_refused():
    f = frequency_grid(1, 1000, 10)
    assert f.size == 31 and f[0] == 1 and f[-1] == pytest.approx(1000, rel=1e-12)
    with pytest.raises(InputError):
        frequency_grid(10, 1, 10)


@pytest.mark.ngspice
@pytest.mark.parametrize("topology", ["parallel", "serial"])
def test_spice_mobility_of_the_flexible_arm_matches_the_exact_one(topology):
    """SPICE's AC sweep agrees with (M's + B' + K'/s)⁻¹ (measured: 6e-9 parallel, 1.5e-8 serial) and
    locates every resonance within 1e-3 of the generalised eigenvalues (measured: worst 2.3e-4)."""
    from analogy.study.mobility import mobility_check
    sc = Scene.of("arm", ModelSpec(robot="flex2"), q=[-0.6, 0.3, 0, 0, 0, 0], forces=[1, 1, 0, 0, 0, 0],
                  topology=topology)
    check = mobility_check(sc.system(), per_decade=500)
    assert check.error <= 1e-7
    assert check.worst_resonance <= 1e-3
    natural = natural_modes(sc.system().joint).omega / (2 * np.pi)
    for f in natural[natural > 0]:
        assert np.min(np.abs(check.spice.resonances() / f - 1)) <= 1e-3


@pytest.mark.ngspice
def test_ac_command_prints_every_mode_and_writes_its_files(tmp_path, capsys):
    csv, png = tmp_path / "y.csv", tmp_path / "y.png"
    rc = main(["ac", "--robot", "flex1", "--q=-0.5,0,0", "--csv", str(csv), "--plot", str(png),
               "--points", "100"])
    out = capsys.readouterr().out
    assert rc == 0 and "rigid" not in out and out.count("e-0") >= 3
    assert csv.read_text().splitlines()[0].startswith("f_hz,abs_Y1_1,phase_deg_Y1_1")
    assert png.stat().st_size > 10000


def test_the_csv_joint_mobility_is_reciprocal_in_a_serial_circuit(tmp_path):
    """R_i/F_j = R_j/F_i: the joint mobility (B + sM + K/s)⁻¹ is symmetric whatever the topology,
    to rounding (κ·ε of its largest entry). In the serial circuit the node voltages per joint force
    are not: v2/F1 ≠ v1/F2. The CSV names both for what they are."""
    import csv
    from analogy.scenes.builtin import scene
    system = scene("serial3").system()
    assert system.topology.name == "serial"
    response = exact_mobility(system, frequency_grid(0.01, 100.0, 20))
    y = response.joint_mobility()
    cond = np.linalg.cond(system.mass)
    assert np.max(np.abs(y - np.swapaxes(y, 1, 2))) <= 100 * cond * np.finfo(float).eps * np.max(np.abs(y))
    nodes = response.mobility
    assert np.max(np.abs(nodes[:, 1, 0] - nodes[:, 0, 1])) > 1e-3 * np.max(np.abs(nodes))
    path = tmp_path / "y.csv"
    response.to_csv(path)
    rows = list(csv.DictReader(path.open()))
    assert abs(float(rows[5]["abs_Y1_2"]) - float(rows[5]["abs_Y2_1"])) <= \
        100 * cond * np.finfo(float).eps * np.max(np.abs(y))
    assert "abs_v2_F1" in rows[0]
