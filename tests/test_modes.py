"""Natural modes of the linear system: generalised eigenvalues of (K, M), modal damping, locked joints."""

import csv

import numpy as np
import pytest
import scipy.linalg as la

from analogy.errors import InputError
from analogy.model.joint import JointSpace
from analogy.results.modes import natural_modes
from analogy.scenes.builtin import scene


def random_space(n=4, alpha=0.3, beta=0.02, seed=0):
    rng = np.random.default_rng(seed)
    a, c = rng.normal(size=(n, n)), rng.normal(size=(n, n))
    m, k = a @ a.T + n * np.eye(n), c @ c.T + np.eye(n)
    return JointSpace(m, alpha * m + beta * k, k)


def test_frequencies_are_the_generalised_eigenvalues():
    js = random_space()
    modes = natural_modes(js)
    w2 = np.sort(la.eigvals(js.stiffness, js.mass_matrix).real)
    np.testing.assert_allclose(modes.omega ** 2, w2, rtol=1e-10)
    np.testing.assert_allclose(modes.shapes.T @ js.mass_matrix @ modes.shapes, np.eye(4), atol=1e-12)


def test_proportional_damping_gives_the_exact_damping_ratios():
    """B = αM + βK: ζ_k = (α/ω_k + β·ω_k)/2, and the damped eigenvalues are −ζω ± iω√(1 − ζ²)."""
    js = random_space()
    modes = natural_modes(js)
    np.testing.assert_allclose(modes.damping_ratio, (0.3 / modes.omega + 0.02 * modes.omega) / 2, rtol=1e-10)
    n = js.dof
    a = np.block([[np.zeros((n, n)), np.eye(n)],
                  [-np.linalg.solve(js.mass_matrix, js.stiffness), -np.linalg.solve(js.mass_matrix, js.damping)]])
    lam = la.eigvals(a)
    lam = lam[lam.imag > 0]
    lam = lam[np.argsort(np.abs(lam))]          # ascending natural frequency
    np.testing.assert_allclose(np.abs(lam), modes.omega, rtol=1e-9)
    np.testing.assert_allclose(-lam.real / np.abs(lam), modes.damping_ratio, rtol=1e-9)


def test_locked_joints_leave_the_free_block_and_rigid_modes_are_zero():
    js = random_space()
    locked = natural_modes(js, [1, 3])
    w2 = np.sort(la.eigvalsh(js.stiffness[np.ix_([1, 3], [1, 3])], js.mass_matrix[np.ix_([1, 3], [1, 3])]))
    np.testing.assert_allclose(locked.omega ** 2, w2, rtol=1e-10)
    assert locked.free == (2, 4)
    free = natural_modes(scene("default").system().joint)       # no springs: two rigid-body modes
    assert free.omega.tolist() == [0.0, 0.0] and np.all(np.isnan(free.damping_ratio))
    with pytest.raises(InputError, match="cannot lock joint 3"):
        natural_modes(scene("default").system().joint, [3])


def test_the_modes_command_writes_the_documented_columns(tmp_path):
    from analogy.cli import main
    out = tmp_path / "modes.csv"
    assert main(["modes", "--scene", "parallel3", "--locked", "1", "--csv", str(out)]) == 0
    rows = list(csv.reader(out.open()))
    # the free joints' shares of each M-normalised shape follow, named after the joints
    assert rows[0] == ["mode", "omega_rad_s", "f_hz", "damping_ratio", "kind", "shape_q2", "shape_q3"]
    assert len(rows) == 3
    assert float(rows[1][2]) == pytest.approx(float(rows[1][1]) / (2 * np.pi), rel=1e-12)
    assert [r[0] for r in rows[1:]] == ["1", "2"] and {r[4] for r in rows[1:]} <= {"oscillating", "rigid body"}


def test_a_damped_system_without_springs_lists_its_real_poles():
    # M·s² + B·s = 0 with diagonal M = (1, 2), B = (1, 3): s = 0 twice (free), s = −b/m = −1 and −1.5
    modes = natural_modes(JointSpace(np.diag([1.0, 2.0]), np.diag([1.0, 3.0])))
    assert np.allclose(np.sort(modes.poles.real), [-1.5, -1.0, 0.0, 0.0], rtol=0, atol=1e-14)
    assert np.all(modes.poles.imag == 0)
    text = modes.table()
    assert "time constant 1 s" in text and "time constant 0.6667 s" in text and "nan" not in text


def test_poles_are_the_roots_of_the_mass_spring_damper_characteristic_equation():
    # one mass: m·s² + b·s + k = 0, s = (−b ± √(b² − 4mk)) / 2m
    m, b, k = 2.0, 0.4, 8.0
    modes = natural_modes(JointSpace(np.array([[m]]), np.array([[b]]), np.array([[k]])))
    root = (-b + np.sqrt(complex(b * b - 4 * m * k))) / (2 * m)
    # eigenvalues of a 2 × 2 companion matrix: a few ε of |s|
    assert np.allclose(np.sort_complex(modes.poles), np.sort_complex([root, root.conjugate()]),
                       rtol=0, atol=16 * np.finfo(float).eps * abs(root))
    assert -modes.poles[0].real / abs(modes.poles[0]) == pytest.approx(modes.damping_ratio[0], rel=1e-12)
