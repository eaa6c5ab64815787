"""Assumed modes of a flexible link: the exact eigenfunctions of a clamped beam, bare or tip-loaded."""

import numpy as np
import pytest

from analogy.errors import InputError
from analogy.model.beams import (
    beam_modes,
    frequency_equation,
    frequency_roots,
    gauss_points,
)


def modal_matrices(m, points=96):
    """Mass (beam, tip mass, tip inertia) and bending stiffness matrices of the modes, by quadrature."""
    xg, wg = gauss_points(points)
    x = xg * m.length
    phi, d2 = m.shape(x), m.shape(x, 2)
    tip, slope = m.shape([m.length])[0], m.shape([m.length], 1)[0]
    mass = m.rho_a * m.length * (phi.T * wg) @ phi + m.tip_mass * np.outer(tip, tip) \
        + m.tip_inertia * np.outer(slope, slope)
    stiffness = m.ei * m.length * (d2.T * wg) @ d2
    return mass, stiffness


def test_a_clamped_free_link_has_the_cantilevers_roots():
    """1 + cos λ·cosh λ = 0: λL = 1.8751, 4.6941, 7.8548 (to 10 digits: 1.875104069, 4.694091133, 7.854757438)."""
    lam = frequency_roots(3)
    np.testing.assert_allclose(lam, [1.875104069, 4.694091133, 7.854757438], rtol=1e-9)
    assert all(abs(1 + np.cos(x) * np.cosh(x)) <= 1e-9 * np.cosh(x) for x in lam)


def test_a_heavy_tip_mass_gives_the_massless_beams_frequency():
    """M ≫ ρA·L: ω² → 3EI/(M·L³), i.e. λ⁴·μ → 3."""
    for mu in (100.0, 1000.0):
        lam = frequency_roots(1, mu)[0]
        assert lam ** 4 * mu / 3 == pytest.approx(1.0, rel=1.0 / mu)


@pytest.mark.parametrize("tip_mass, tip_inertia", [(0.0, 0.0), (0.3, 0.0), (0.3, 0.002), (2.0, 0.05)])
@pytest.mark.parametrize("normalisation", ["link-mass", "unit"])
@pytest.mark.parametrize("count", [4, 16])
def test_modes_are_orthogonal_and_normalised_with_their_tip_load(tip_mass, tip_inertia, normalisation, count):
    """With the tip load in the mass operator the modes are orthogonal, K = diag(ω²)·M, and
    the modal mass is ρA·L (link-mass) or 1 kg (unit)."""
    m = beam_modes(count, 0.5, 0.4, 2.0, tip_mass, tip_inertia, normalisation)
    mass, stiffness = modal_matrices(m)
    target = m.rho_a * m.length if normalisation == "link-mass" else 1.0
    # roots to a few ε (frequency_equation has no cancelling terms) and shapes without cancelling
    # exponentials: each value's argument λ·ξ rounds by ε·λ, and the 96-point quadrature sums them
    rounding = 96 * np.finfo(float).eps * m.lam[-1]
    np.testing.assert_allclose(mass, target * np.eye(count), atol=rounding * target)
    np.testing.assert_allclose(stiffness, np.diag(m.omega ** 2) * target, rtol=1e-10,
                               atol=1e-10 * m.omega[-1] ** 2 * target)
    mu, j = tip_mass / 0.2, tip_inertia / 0.2 / 0.25
    for x in m.lam:
        # λ itself is known to ε·λ, and the equation's slope is of the size of its terms 1, μλ, jλ³, μjλ⁴
        size = 1 + mu * x + j * x ** 3 + mu * j * x ** 4
        assert abs(frequency_equation(x, mu, j)) <= 4 * np.finfo(float).eps * x * size


def test_the_quadrature_is_converged_below_1e_14():
    m = beam_modes(3, 0.5, 0.4, 2.0, 0.3, 0.002)
    a, b = modal_matrices(m, 96)[0], modal_matrices(m, 160)[0]
    assert np.max(np.abs(a - b)) <= 1e-14 * np.max(np.abs(a))


def test_tip_loads_lower_every_frequency():
    bare = beam_modes(3, 0.5, 0.4, 2.0).omega
    loaded = beam_modes(3, 0.5, 0.4, 2.0, tip_mass=0.3, tip_inertia=0.002).omega
    assert np.all(loaded < bare)


def test_impossible_links_are_refused():
    with pytest.raises(InputError, match="positive length"):
        beam_modes(2, 0.0, 0.4, 2.0)
    with pytest.raises(InputError, match="at least one mode"):
        frequency_roots(0)


def test_more_modes_than_the_frequency_equation_resolves_are_refused():
    """Past the modes whose quadrature is tested, a link's mode count is refused, not returned unchecked."""
    from analogy.errors import InputError
    from analogy.model.beams import MAX_BEAM_MODES, beam_modes
    beam_modes(MAX_BEAM_MODES, 0.5, 0.4, 2.0)
    with pytest.raises(InputError, match="1 to 16 assumed modes"):
        beam_modes(MAX_BEAM_MODES + 1, 0.5, 0.4, 2.0)
