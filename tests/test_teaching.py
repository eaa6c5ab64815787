"""The solutions of the exercises in docs/teaching.md, checked with the package against the physics.

Each test is one exercise (its number in the docstring). None needs ngspice: the exercises
are about the circuit's element values and dynamics, which the exact solver already shows.
"""

import numpy as np
import pytest
from scipy.optimize import brentq

import analogy
from analogy.model.beams import beam_modes


def _arm(q2):
    """The 2-DOF serial arm (scene serial2) at elbow angle q2, in the serial node topology."""
    return analogy.scene("serial2").replace(q=(0.0, q2)).system()


def test_exercise_1_a_damper_driven_mass_is_a_first_order_lag_with_time_constant_m_over_b():
    """Exercise 1: M dv/dt + b v = F from rest gives v = (F/b)(1 - exp(-t b/M))."""
    mass, damping, force = 1.5, 2.0, 3.0
    system = analogy.node_system(analogy.JointSpace([[mass]], [[damping]]), forces=[force], t_stop=10.0)
    tau = mass / damping
    v = analogy.solve_exact(system, [tau, 10.0]).voltages[:, 0]
    assert v[0] == pytest.approx((force / damping) * (1 - np.exp(-1)), rel=1e-12), "1 - 1/e of the final speed"
    assert v[1] == pytest.approx(force / damping, rel=1e-5), "after 13 tau the speed is F/b"
    (element,) = [e for e in analogy.elements(system) if e.kind == "R"]
    assert element.value * mass == pytest.approx(tau), "RC = (1/b) M = tau"


def test_exercise_2_the_mp_capacitance_of_the_arm_vanishes_at_right_angles_and_peaks_stretched_or_folded():
    """Exercise 2: c12 = -l1 l2 d2 cos q2: zero at q2 = +-pi/2, -l1 l2 d2 at 0, +l1 l2 d2 at pi."""
    p = analogy.scene("serial2").build_model().parameters
    scale = p["l1"] * p["l2"] * p["d2"]
    c12 = {q2: analogy.mp_capacitance(_arm(q2).mass)[0, 1] for q2 in (0.0, np.pi / 2, -np.pi / 2, np.pi)}
    assert c12[0.0] == pytest.approx(-scale, rel=1e-12)
    assert c12[np.pi] == pytest.approx(scale, rel=1e-12)
    assert abs(c12[np.pi / 2]) <= 1e-12 * scale and abs(c12[-np.pi / 2]) <= 1e-12 * scale
    sweep = [analogy.mp_capacitance(_arm(q2).mass)[0, 1] for q2 in np.linspace(-np.pi, np.pi, 73)]
    assert min(sweep) >= -scale * (1 + 1e-12) and max(sweep) <= scale * (1 + 1e-12), "|c12| <= l1 l2 d2"


def test_exercise_3_the_grounded_mass_at_the_tip_is_negative_beyond_arccos_of_minus_l2_over_l1():
    """Exercise 3: m'2 = d2 l2 (l2 + l1 cos q2) < 0 exactly when cos q2 < -l2/l1, yet M' stays positive definite."""
    p = analogy.scene("serial2").build_model().parameters
    edge = np.arccos(-p["l2"] / p["l1"])
    for q2, sign in ((edge - 1e-3, +1), (edge + 1e-3, -1), (-edge - 1e-3, -1), (np.pi, -1)):
        system = _arm(q2)
        m2 = system.mass.sum(axis=1)[1]              # the grounded capacitor: the row sum of M'
        assert m2 == pytest.approx(p["d2"] * p["l2"] * (p["l2"] + p["l1"] * np.cos(q2)), rel=1e-9, abs=1e-12)
        assert np.sign(m2) == sign
        assert np.linalg.eigvalsh(system.mass).min() > 0, "the arm stays passive"


def test_exercise_4_serial_nodes_make_the_redundant_stages_two_masses_parallel_nodes_need_an_mp_model():
    """Exercise 4: serial nodes give M' = diag(d1, d2); parallel nodes keep M' = M with p'12 = -d2."""
    scene = analogy.scene("redundant")
    p = scene.build_model().parameters
    serial = scene.system()
    parallel = scene.replace(topology="parallel").system()
    assert np.allclose(serial.mass, np.diag([p["d1"], p["d2"]]), rtol=0, atol=1e-15)
    assert not [e for e in analogy.elements(serial) if e.meaning == "MP model"]
    (mp,) = [e for e in analogy.elements(parallel) if e.meaning == "MP model"]
    assert mp.value == pytest.approx(-p["d2"], rel=1e-12)
    # Same device: the kinetic energy of any joint rates r is the same in both circuits.
    r = np.array([0.7, -1.3])
    energies = [0.5 * v @ s.mass @ v for s in (serial, parallel) for v in [s.topology.matrix @ r]]
    assert energies[0] == pytest.approx(energies[1], rel=1e-12)


def test_exercise_5_the_mp_model_across_links_1_and_3_vanishes_where_q2_plus_q3_is_a_right_angle():
    """Exercise 5: p'1_3 = -l1 l3 d3 cos(q2 + q3), so with q2 = 0.4 it vanishes at q3 = +-pi/2 - 0.4; p'1_2 stays."""
    scene = analogy.scene("serial3")
    q2 = 0.4
    at = {q3: scene.replace(q=(0.0, q2, q3)).system().mass for q3 in (np.pi / 2 - q2, -np.pi / 2 - q2, 0.0)}
    for q3 in (np.pi / 2 - q2, -np.pi / 2 - q2):
        assert abs(at[q3][0, 2]) <= 1e-12 * np.abs(at[q3]).max(), "p'1_3 = 0"
        assert at[q3][0, 1] == pytest.approx(at[0.0][0, 1], rel=1e-12), "p'1_2 depends on q2 only"
    p = scene.build_model().parameters
    assert -at[0.0][0, 2] == pytest.approx(-p["l1"] * p["l3"] * p["d3"] * np.cos(q2), rel=1e-12)


@pytest.mark.parametrize("q2", [0.3, 2.0, 3.0])
def test_exercise_6_the_time_constants_do_not_depend_on_the_choice_of_nodes(q2):
    """Exercise 6: M' = T^-T M T^-1, B' = T^-T B T^-1 is a congruence, so eig(M'^-1 B') = eig(M^-1 B)."""
    serial = _arm(q2)
    parallel = analogy.scene("serial2").replace(q=(0.0, q2), topology="parallel").system()
    joint = serial.joint

    def rates(mass, damping):
        return np.sort(np.linalg.eigvals(np.linalg.solve(mass, damping)).real)

    expected = rates(joint.mass_matrix, joint.damping)
    assert np.allclose(rates(serial.mass, serial.damping), expected, rtol=1e-12)
    assert np.allclose(rates(parallel.mass, parallel.damping), expected, rtol=1e-12)
    assert not np.allclose(serial.mass, parallel.mass), "the circuits differ, their time constants do not"


def test_exercise_7_the_first_frequency_of_a_clamped_free_link_follows_the_beam_equation():
    """Exercise 7: omega_k = (beta_k L)^2 sqrt(EI / (rho A L^4)), with 1 + cos(beta L) cosh(beta L) = 0."""
    length, rho_a, ei = 0.5, 1.2, 3.0
    roots = [brentq(lambda x: 1 + np.cos(x) * np.cosh(x), a, b) for a, b in ((1.0, 3.0), (4.0, 6.0))]
    expected = np.array(roots) ** 2 * np.sqrt(ei / (rho_a * length**4))
    assert np.allclose(beam_modes(2, length, rho_a, ei).omega, expected, rtol=1e-9)
    # A motor at the tip adds mass where the link moves most: the frequencies fall.
    loaded = beam_modes(2, length, rho_a, ei, tip_mass=0.2, tip_inertia=1e-3).omega
    assert np.all(loaded < expected)
