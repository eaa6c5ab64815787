"""Equations (1)–(60) of Lee & Book, "Efficient Dynamic Models for Flexible Robots".

Every printed result is derived here from the package's own machinery: the deformed
positions and Jacobians of ``chain_kinematics`` (eqs. 20–21), the numeric model of
``flexible_chain`` (M = Σ∫ρA·JᵀJ dx, G = ∂U_g/∂q, modal K) for the paper's example
of two links with two clamped-free modes each, the exact modes of ``beam_modes`` and
the Christoffel symbols of ``analogy.model.symbolic``. The printed forms below are
written by hand from the paper; they are claims under test. Where a printed form is a
misprint, its test asserts that the printed form differs from the derivation and that
the corrected form equals it. docs/equations.md tabulates the verdicts.

Two derivations are compared with each printed form. Symbolically, every integral over
link i of a monomial x^a·ψ_i1^b·ψ_i2^c becomes a label (m_i, m_i·l_ic, J_i, LM_ij,
AM_ij, NM_ij, …, eqs. 34–39), so that M, G and C_jk(i) follow exactly from J_iᵀJ_i with
lengths, tip values ψ_ije and labels as free symbols. Numerically, the labels are the
quadrature integrals of the package's mode shapes, and printed entries are compared
with the package's model at random states (θ, δ) to 1e-10 of the matrix's scale.

Notation. The paper's ξ_ij (and q_ij inside d_21 … d_52 of eq. 54) is the package's
``delta{i}_{j}``; C_i = cos θ_i, S_i = sin θ_i, C_12 = cos(θ1 + θ2); u_1e = u_1(l_1) and
ψ_ije = ψ_ij(l_i). C_jk(i) is the package's ``christoffel_symbols(M, q)[i][j][k]``. The
gravity vector of (5) and (16) is gᵀ = (0, g), so U_g = g·∫y dm, as (31) implies.
"""

from functools import lru_cache

import numpy as np
import pytest
import sympy as sp
from scipy.optimize import brentq

from analogy.model.beams import beam_modes, frequency_roots, gauss_points
from analogy.model.flexible import FlexibleLink, chain_kinematics, flexible_chain
from analogy.model.symbolic import christoffel_symbols, velocity_terms

#: The paper's example (Fig. 2): link AB and link BC, two clamped-free modes each.
LINKS = (FlexibleLink(0.5, 0.4, 2.0, modes=2), FlexibleLink(0.4, 0.3, 1.0, modes=2))
GRAVITY = 9.81
QUADRATURE = 120        # not the package's 96 points: an independent quadrature

l1, l2 = sp.symbols("l1 l2", positive=True)
g = sp.Symbol("g", positive=True)
KIN = chain_kinematics([l1, l2], [2, 2])
X = KIN.x
Q = list(KIN.coordinates)
th1, th2, d11, d12, d21, d22 = Q
(p11, p12), (p21, p22) = KIN.shapes
(e11, e12), _ = KIN.tip_shapes         # ψ_ije; link 2's tip values are not used
u1 = p11 * d11 + p12 * d12
u2 = p21 * d21 + p22 * d22
u1e = e11 * d11 + e12 * d12
C1, S1, C2, S2 = sp.cos(th1), sp.sin(th1), sp.cos(th2), sp.sin(th2)
C12, S12 = sp.cos(th1 + th2), sp.sin(th1 + th2)
RATES = list(sp.symbols("qd1:7", real=True))


# ------------------------------------------------------------------ labelled integrals

m1_, m2_ = sp.symbols("m1 m2", positive=True)
lc1, lc2 = sp.symbols("l1c l2c", positive=True)
J1_, J2_ = sp.symbols("J1 J2", positive=True)
LM = [[sp.Symbol(f"LM{i}{j}") for j in (1, 2)] for i in (1, 2)]
AM = [[sp.Symbol(f"AM{i}{j}") for j in (1, 2)] for i in (1, 2)]
NM = [[sp.Symbol(f"NM{i}{j}", positive=True) for j in (1, 2)] for i in (1, 2)]
N12 = [sp.Symbol("N1_12"), sp.Symbol("N2_12")]        # ∫ψ_i1·ψ_i2·ρA dx: 0 for exact modes
ORTHOGONAL = {N12[0]: 0, N12[1]: 0}
_NAMED = {}
for _i, (_m, _lc, _J) in enumerate(((m1_, lc1, J1_), (m2_, lc2, J2_))):
    _NAMED |= {(_i, 0, 0, 0): _m, (_i, 1, 0, 0): _m * _lc, (_i, 2, 0, 0): _J,
               (_i, 0, 1, 0): LM[_i][0], (_i, 0, 0, 1): LM[_i][1],
               (_i, 1, 1, 0): AM[_i][0], (_i, 1, 0, 1): AM[_i][1],
               (_i, 0, 2, 0): NM[_i][0], (_i, 0, 0, 2): NM[_i][1], (_i, 0, 1, 1): N12[_i]}


def moment(link: int, powers) -> sp.Expr:
    """∫_0^{l_i} x^a·ψ_i1^b·ψ_i2^c·ρ_iA_i dx as a label (eqs. 34–39) or a new symbol."""
    key = (link, *powers)
    if key not in _NAMED:
        _NAMED[key] = sp.Symbol("I%d_%d%d%d" % (link + 1, *powers))
    return _NAMED[key]


def integral(expr, link: int) -> sp.Expr:
    """∫ρA·expr dx over link *link* (0 or 1): expr is a polynomial in x and that link's ψ symbols."""
    expr = sp.expand(expr)
    if expr == 0:
        return sp.S.Zero
    poly = sp.Poly(expr, X, *KIN.shapes[link])
    return sp.expand(sum((c * moment(link, p) for p, c in poly.terms()), sp.S.Zero))


def I1(expr):
    return integral(expr, 0)


def I2(expr):
    return integral(expr, 1)


@lru_cache(maxsize=None)
def label_mass_matrix() -> sp.ImmutableMatrix:
    """M = Σ_i ∫ρ_iA_i·J_iᵀJ_i dx_i from the package's Jacobians, in labels."""
    m = sp.zeros(6, 6)
    for i, jac in enumerate(KIN.jacobians()):
        m += (jac.T * jac).applyfunc(lambda e, i=i: integral(e, i))
    return sp.ImmutableMatrix(m)


@lru_cache(maxsize=None)
def label_gravity() -> sp.ImmutableMatrix:
    """G/g = ∂/∂q Σ_i ∫ρ_iA_i·y_i dx_i (the second rows of the J_i), in labels."""
    return sp.ImmutableMatrix(sum((jac[1, :].applyfunc(lambda e, i=i: integral(e, i))
                                   for i, jac in enumerate(KIN.jacobians())), sp.zeros(1, 6)))


@lru_cache(maxsize=None)
def label_christoffel():
    """C_jk(i) of the labelled M, with orthogonal modes (∫ψ_i1ψ_i2ρA dx = 0)."""
    m = label_mass_matrix().xreplace(ORTHOGONAL)
    return christoffel_symbols(m, Q)


# ------------------------------------------------------------------ the numeric model

@lru_cache(maxsize=None)
def modes(link: int, normalisation: str = "link-mass"):
    ln = LINKS[link]
    return beam_modes(ln.modes, ln.length, ln.rho_a, ln.ei, normalisation=normalisation)


@lru_cache(maxsize=None)
def model():
    return flexible_chain(LINKS, gravity=GRAVITY)


def quadrature(link: int):
    """Points x [m], weights ρA·dx [kg] and ψ_k(x) of one link."""
    ln = LINKS[link]
    xg, wg = gauss_points(QUADRATURE)
    x = xg * ln.length
    return x, wg * ln.length * ln.rho_a, modes(link).shape(x)


@lru_cache(maxsize=None)
def values() -> dict:
    """Numbers for the lengths, the tip values ψ_ije and every label used so far."""
    out = {l1: LINKS[0].length, l2: LINKS[1].length, g: GRAVITY}
    for i, ln in enumerate(LINKS):
        tips = modes(i).shape([ln.length])[0]
        out |= dict(zip(KIN.tip_shapes[i], tips.tolist()))
    return out


def label_value(sym) -> float:
    for (link, a, b, c), label in list(_NAMED.items()):
        if label.free_symbols & {sym} or label == sym:
            x, w, psi = quadrature(link)
            total = float(w @ (x ** a * psi[:, 0] ** b * psi[:, 1] ** c))
            if label == sym:
                return total
            if label.is_Mul:                       # m_i·l_ic: l_ic = first moment / m_i
                mass = float(w.sum())
                return total / mass
    raise KeyError(sym)


def at(expr, state) -> float:
    """A labelled expression at a state (θ1, θ2, δ11, δ12, δ21, δ22), labels by quadrature."""
    expr = sp.sympify(expr).xreplace(floats(dict(zip(Q, state))))
    numbers = values()
    for sym in expr.free_symbols - set(numbers):
        numbers[sym] = label_value(sym)
    return float(expr.xreplace(floats(numbers)))


def floats(mapping) -> dict:
    """A substitution with sympy Floats (xreplace takes sympy values only)."""
    return {k: sp.Float(float(v)) for k, v in mapping.items()}


def states(count=3, seed=11):
    rng = np.random.default_rng(seed)
    return [np.concatenate([rng.uniform(-np.pi, np.pi, 2), rng.uniform(-0.1, 0.1, 4)]) for _ in range(count)]


STATES = states()


@lru_cache(maxsize=None)
def numeric_parts():
    """The package's M(q), G(q) and C_jk(i)(q), compiled."""
    mdl = model()
    q = list(mdl.coordinates)
    gamma = christoffel_symbols(mdl.mass_matrix, q)
    return (sp.lambdify(q, mdl.mass_matrix, "numpy"), sp.lambdify(q, list(mdl.gravity), "numpy"),
            sp.lambdify(q, gamma, "numpy"))


def model_mass(state):
    return np.array(numeric_parts()[0](*state), dtype=float)


def model_gravity(state):
    return np.array(numeric_parts()[1](*state), dtype=float)


def model_christoffel(state):
    return np.array(numeric_parts()[2](*state), dtype=float)


# --------------------------------------------------------------------------- helpers

_c, _s = sp.symbols("_c1 _c2"), sp.symbols("_s1 _s2")


def reduced(expr) -> sp.Expr:
    """Canonical form of a polynomial in sin θ_i, cos θ_i: cos² θ_i replaced by 1 − sin² θ_i."""
    e = sp.expand(sp.expand_trig(sp.sympify(expr)))
    e = sp.expand(e.xreplace({sp.cos(th1): _c[0], sp.cos(th2): _c[1], sp.sin(th1): _s[0], sp.sin(th2): _s[1]}))
    for c, s in zip(_c, _s):
        if e.has(c):
            e = sp.rem(e, c ** 2 + s ** 2 - 1, c)
    return sp.expand(e)


def same(a, b) -> bool:
    """True when a − b reduces to zero (scalars or matrices)."""
    a, b = sp.Matrix([a]) if not isinstance(a, sp.MatrixBase) else a, \
        sp.Matrix([b]) if not isinstance(b, sp.MatrixBase) else b
    return a.shape == b.shape and all(reduced(x) == 0 for x in (a - b))


def holds(printed, derived):
    """The printed form is the derivation."""
    assert same(printed, derived), f"printed {printed} != derived {derived}"


def misprint(printed, corrected, derived):
    """The printed form is wrong and the corrected form is the derivation."""
    assert not same(printed, derived), f"printed {printed} is not a misprint: it equals the derivation"
    assert same(corrected, derived), f"corrected {corrected} != derived {derived}"


def holds_numerically(printed, numeric, scale):
    """At every state the printed labelled form equals the package's number, to 1e-10 of the scale."""
    for state in STATES:
        assert abs(at(printed, state) - numeric(state)) <= 1e-10 * scale(state), (printed, state)


def misprint_numerically(printed, corrected, numeric, scale):
    """The printed form misses the package's number; the corrected form meets it."""
    assert any(abs(at(printed, st) - numeric(st)) > 1e-6 * scale(st) for st in STATES)
    holds_numerically(corrected, numeric, scale)


def check(printed, corrected, derived, numeric=None, scale=None):
    """Symbolic and (given *numeric*) numeric verdict: *corrected* None means the printed form holds."""
    if corrected is None:
        holds(printed, derived)
        if numeric is not None:
            holds_numerically(printed, numeric, scale)
    else:
        misprint(printed, corrected, derived)
        if numeric is not None:
            misprint_numerically(printed, corrected, numeric, scale)


def mass_scale(state):
    return np.abs(model_mass(state)).max()


def christoffel_scale(state):
    return np.abs(model_christoffel(state)).max()


def at_time(expr, coordinates, t):
    """expr with the coordinates as functions of t."""
    return expr.xreplace({q: sp.Function(str(q))(t) for q in coordinates})


def from_time(expr, coordinates, t, rates, accelerations=None):
    """Back from functions of t: q̈ → accelerations, q̇ → rates, q(t) → q."""
    funcs = [sp.Function(str(q))(t) for q in coordinates]
    if accelerations is not None:
        expr = expr.subs({f.diff(t, 2): a for f, a in zip(funcs, accelerations)})
    expr = expr.subs({f.diff(t): r for f, r in zip(funcs, rates)})
    return expr.subs(dict(zip(funcs, coordinates))).doit()


# ---------------------------------------------------------------- 2: the general method

LINK, J, K = sp.symbols("link j k", integer=True, positive=True)
E = sp.IndexedBase("E")         # E[i, j] stands for ∫_0^{l_i} ṙ_iᵀṙ_j ρ_iA_i dx_i


def kinetic_energy_per_link():
    """½∫ṙ_iᵀṙ_i ρ_iA_i dx_i of each link, with ṙ_i the time derivative of r_i(q(t)), in labels."""
    t = sp.Symbol("t")
    out = []
    for i, r in enumerate(KIN.points):
        v = from_time(at_time(r, Q, t).diff(t), Q, t, RATES)
        out.append(sp.Rational(1, 2) * integral((v.T * v)[0], i))
    return out


def quadratic_form(m):
    qd = sp.Matrix(RATES)
    return sp.Rational(1, 2) * (qd.T * m * qd)[0]


def test_eq1_kinetic_energy_pairs_each_link_with_itself():
    """(1) misprint: T = ½Σ_i ∫ṙ_iᵀṙ_i ρ_iA_i dx_i; the printed ṙ_iᵀṙ_j leaves j bound by no sum."""
    printed = sp.Rational(1, 2) * sp.Sum(E[LINK, J], (LINK, 1, 2))
    corrected = sp.Rational(1, 2) * sp.Sum(E[LINK, LINK], (LINK, 1, 2))
    assert J in printed.free_symbols and J not in corrected.free_symbols
    per_link = kinetic_energy_per_link()
    value = corrected.doit().xreplace({E[1, 1]: 2 * per_link[0], E[2, 2]: 2 * per_link[1]})
    holds(value, quadratic_form(label_mass_matrix()))


def test_eq2_eq25_eq26_velocity_is_the_jacobian_times_the_rates():
    """(2), (25), (26) hold: d/dt r_i(q(t)) = J_i·q̇ for both links, with q = q_12 of (27)."""
    t = sp.Symbol("t")
    for r, jac in zip(KIN.points, KIN.jacobians()):
        holds(from_time(at_time(r, Q, t).diff(t), Q, t, RATES), jac * sp.Matrix(RATES))


def test_eq3_kinetic_energy_is_the_quadratic_form_of_m():
    """(3): the last line T = ½ΣΣ M_ij q̇_i q̇_j holds (sums over the six coordinates); the middle
    lines are misprinted like (1): (J_i q̇_i)ᵀ(J_j q̇_j) pairs link i with link j and a scalar rate q̇_i
    with a matrix. Corrected: T = ½ q̇ᵀ(Σ_l ∫ρ_lA_l J_lᵀJ_l dx_l) q̇."""
    per_link = kinetic_energy_per_link()
    derived = per_link[0] + per_link[1]
    m = label_mass_matrix()
    last_line = sp.Rational(1, 2) * sum(m[i, j] * RATES[i] * RATES[j] for i in range(6) for j in range(6))
    holds(last_line, derived)
    printed_middle = sp.Rational(1, 2) * sp.Sum(E[LINK, J], (LINK, 1, 2))
    assert J in printed_middle.free_symbols
    holds(quadratic_form(m), derived)
    for state in STATES:                       # the package's M gives the same energy
        rates = np.random.default_rng(3).uniform(-1, 1, 6)
        t_model = 0.5 * rates @ model_mass(state) @ rates
        t_label = at(derived.xreplace(dict(zip(RATES, rates))), state)
        assert t_label == pytest.approx(t_model, rel=1e-10)


def test_eq4_eq30_mass_matrix_from_the_jacobians():
    """(30) holds: M = Σ_i ∫ρ_iA_i J_iᵀJ_i dx_i (the whole matrix; M_ij on its left names M),
    checked by an independent quadrature of JᵀJ against the package at random states.
    (4) misprint: M_ij is a scalar, ∫J_iᵀJ_j ρ_iA_i dx_i a 6 × 6 matrix pairing links i and j.
    Corrected: M_ij = Σ_l ∫ρ_lA_l J_l^(i)·J_l^(j) dx_l (columns i and j of the link Jacobians)."""
    jacs = KIN.jacobians()
    assert (jacs[0].T * jacs[1]).shape == (6, 6)            # not one entry
    corrected = sp.Matrix(6, 6, lambda i, j: sum(integral(jacs[l][:, i].dot(jacs[l][:, j]), l)
                                                  for l in range(2)))
    holds(corrected, label_mass_matrix())
    for state in STATES:
        total = np.zeros((6, 6))
        for l, jac in enumerate(jacs):
            x, w, psi = quadrature(l)
            integrand = (jac.T * jac).xreplace(floats(dict(zip(Q, state)))).xreplace(floats(values()))
            f = sp.lambdify([X, *KIN.shapes[l]], integrand)
            total += sum(wk * np.array(f(xk, *pk), dtype=float) for xk, wk, pk in zip(x, w, psi))
        np.testing.assert_allclose(total, model_mass(state), rtol=0, atol=1e-10 * mass_scale(state))


def gravity_potential():
    """U_g/g = Σ_j ∫ρ_jA_j y_j dx_j in labels (gᵀ = (0, g))."""
    return sum((integral(r[1], i) for i, r in enumerate(KIN.points)), sp.S.Zero)


def test_eq5_gravity_potential_needs_the_centre_of_mass():
    """(5): the first line U_g = Σ∫gᵀr_j ρ_jA_j dx_j holds (its gradient is the package's G); the
    second, Σ m_j gᵀr_j, is a misprint: r_j depends on x_j. Corrected: Σ m_j gᵀr̄_j with
    r̄_j = ∫r_j ρ_jA_j dx_j / m_j the deformed link's centre of mass. Even read at x_j = l_jc the
    printed line misses the modal terms (m_j ψ_jk(l_jc) is not LM_jk)."""
    u = gravity_potential()
    holds(sp.Matrix([u]).jacobian(Q), label_gravity())
    for i in range(6):
        holds_numerically(GRAVITY * sp.diff(u, Q[i]), lambda st, i=i: model_gravity(st)[i],
                          lambda st: np.abs(model_gravity(st)).max())
    masses = (m1_, m2_)
    printed = sum((masses[i] * r[1] for i, r in enumerate(KIN.points)), sp.S.Zero)
    assert X in printed.free_symbols                        # a function of x, not a number
    centre = [integral(r[1], i) / masses[i] for i, r in enumerate(KIN.points)]
    holds(sum(masses[i] * centre[i] for i in range(2)), u)
    # the printed line read at the centres of mass, with the package's modes
    at_centre = 0
    for i, r in enumerate(KIN.points):
        half = LINKS[i].length / 2
        shape_at = dict(zip(KIN.shapes[i], modes(i).shape([half])[0].tolist()))
        at_centre += masses[i] * r[1].xreplace(floats({X: half} | shape_at))
    assert any(abs(at(at_centre, st) - at(u, st)) > 1e-6 * abs(at(u, st)) for st in STATES)


def test_eq6_eq34_to_eq39_labelled_integrals():
    """(6), (34)–(39) hold as definitions; for uniform links m_i = ρA·l, l_ic = l/2 (the centre of
    mass), J_i = ρA·l³/3 about the joint, NM_ij = the modal mass of the normalisation (ρA·l for the
    package's default, 1 kg for "unit"), and LM_ij, AM_ij are the ∫ψ, ∫xψ that M is built of: the
    package's constant part of M11 is J1 + m2·l1² + J2 + 2·l1·m2·l2c·C2, and its G1 at δ = 0 is
    g[(m1·l1c + m2·l1)C1 + m2·l2c·C12]."""
    for i, ln in enumerate(LINKS):
        mass, length = ln.rho_a * ln.length, ln.length
        assert label_value((m1_, m2_)[i]) == pytest.approx(mass, rel=1e-13)
        assert label_value((lc1, lc2)[i]) == pytest.approx(length / 2, rel=1e-13)
        assert label_value((J1_, J2_)[i]) == pytest.approx(mass * length ** 2 / 3, rel=1e-13)
        for k in range(2):
            assert label_value(NM[i][k]) == pytest.approx(mass, rel=1e-12)
        for norm, target in (("link-mass", mass), ("unit", 1.0)):
            x, w, _ = quadrature(i)
            psi = modes(i, norm).shape(x)
            np.testing.assert_allclose(w @ psi ** 2, [target, target], rtol=1e-12)
    for th in (0.3, -1.1):
        state = np.array([0.7, th, 0, 0, 0, 0])
        rigid_m11 = J1_ + m2_ * l1 ** 2 + J2_ + 2 * l1 * m2_ * lc2 * C2
        assert at(rigid_m11, state) == pytest.approx(model_mass(state)[0, 0], rel=1e-12)
        rigid_g1 = g * ((m1_ * lc1 + m2_ * l1) * C1 + m2_ * lc2 * C12)
        assert at(rigid_g1, state) == pytest.approx(model_gravity(state)[0], rel=1e-12)
    # LM and AM enter M13 and M15: AM11 + ψ11e(l1·m2 + …) and AM21 + LM21(l1·C2 + …)
    holds(label_mass_matrix()[0, 2].xreplace({d21: 0, d22: 0}), AM[0][0] + e11 * (l1 * m2_ + m2_ * lc2 * C2))
    holds(label_mass_matrix()[0, 4].xreplace({d11: 0, d12: 0}), AM[1][0] + LM[1][0] * l1 * C2)


def elastic_energy_by_quadrature(state):
    """½Σ_i ∫E_iI_i (∂²u_i/∂x_i²)² dx_i with the package's mode shapes."""
    total = 0.0
    for i, ln in enumerate(LINKS):
        xg, wg = gauss_points(QUADRATURE)
        d2 = modes(i).shape(xg * ln.length, 2) @ state[2 + 2 * i:4 + 2 * i]
        total += 0.5 * ln.ei * ln.length * wg @ d2 ** 2
    return total


def modal_stiffness(link):
    """K_ijk = ∫E_iI_i ψ_ij''ψ_ik'' dx_i by quadrature."""
    ln = LINKS[link]
    xg, wg = gauss_points(QUADRATURE)
    d2 = modes(link).shape(xg * ln.length, 2)
    return ln.ei * ln.length * (d2.T * wg) @ d2


def test_eq7_elastic_energy_of_each_link_with_itself():
    """(7) misprint: U_e = ½Σ_i ∫E_iI_i (∂²u_i/∂x_i²)² dx_i; the printed u_j, u_k (and x_j, x_k) are
    bound by no sum. The corrected form is the package's ½qᵀKq at random δ."""
    w = sp.IndexedBase("W")     # W[i, j, k] stands for ∫E_iI_i u_j''u_k'' dx_i
    printed = sp.Rational(1, 2) * sp.Sum(w[LINK, J, K], (LINK, 1, 2))
    assert {J, K} <= printed.free_symbols
    stiffness = np.array(model().stiffness.tolist(), dtype=float)
    for state in STATES:
        assert elastic_energy_by_quadrature(state) == pytest.approx(0.5 * state @ stiffness @ state, rel=1e-10)


def test_eq8_eq22_eq23_deflection_is_the_modal_sum():
    """(8), (22), (23) hold: along link i's normal n_i, r_i − o_i is u_i = Σ_j ψ_ij ξ_ij, and along
    its axis e_i it is x."""
    origins = [sp.zeros(2, 1), KIN.tips[0]]
    for i, (r, o) in enumerate(zip(KIN.points, origins)):
        alpha = sum(Q[:i + 1])
        axis, normal = sp.Matrix([sp.cos(alpha), sp.sin(alpha)]), sp.Matrix([-sp.sin(alpha), sp.cos(alpha)])
        holds((r - o).dot(normal), (u1, u2)[i])
        holds((r - o).dot(axis), X)


def test_eq9_elastic_energy_in_modal_coordinates():
    """(9) holds, reading ψ_j, ψ_k as ψ_ij, ψ_ik and x_j, x_k as x_i: U_e = ½ΣΣΣ K_ijk δ_ij δ_ik."""
    for state in STATES:
        modal = sum(0.5 * state[2 + 2 * i:4 + 2 * i] @ modal_stiffness(i) @ state[2 + 2 * i:4 + 2 * i]
                    for i in range(2))
        assert modal == pytest.approx(elastic_energy_by_quadrature(state), rel=1e-12)


def test_eq10_modal_stiffness():
    """(10) holds: the package's K is ∫E_iI_i ψ_ij''ψ_ik'' dx_i per link, zero in the θ rows; for the
    exact clamped-free modes it is diagonal, K_ijj = ω_j²·NM_ij."""
    k = np.array(model().stiffness.tolist(), dtype=float)
    assert not k[:2].any() and not k[:, :2].any()
    for i in range(2):
        block = k[2 + 2 * i:4 + 2 * i, 2 + 2 * i:4 + 2 * i]
        np.testing.assert_allclose(block, modal_stiffness(i), rtol=1e-10, atol=1e-10 * block.max())
        np.testing.assert_allclose(block, np.diag(modes(i).omega ** 2 * label_value(NM[i][0])),
                                   rtol=1e-10, atol=1e-10 * block.max())
    assert not k[2:4, 4:].any()


# ---------------------------------------------------------------- Lagrange's equations

N_GENERIC = 3
QG = list(sp.symbols(f"q1:{N_GENERIC + 1}", real=True))
QDG = list(sp.symbols(f"qd1:{N_GENERIC + 1}", real=True))
QDDG = list(sp.symbols(f"qdd1:{N_GENERIC + 1}", real=True))


def generic_mass_matrix(coordinates):
    n = len(coordinates)
    return sp.Matrix(n, n, lambda i, j: sp.Function(f"M{min(i, j) + 1}{max(i, j) + 1}")(*coordinates))


def test_eq11_to_eq15_lagrange_terms_of_a_general_mass_matrix():
    """(11)–(15) hold for any symmetric M(q): d/dt(∂T/∂q̇_i) = ΣM_ij q̈_j + Σ(dM_ij/dt)q̇_j (12),
    dM_ij/dt = Σ_k ∂M_ij/∂q_k q̇_k (13), the symmetrised form (14), ∂T/∂q_i = ½ΣΣ ∂M_jk/∂q_i q̇_j q̇_k
    (15), so that Lagrange's equation (11) has the velocity terms of (43)."""
    t = sp.Symbol("t")
    m = generic_mass_matrix(QG)
    n = N_GENERIC
    tkin = sp.Rational(1, 2) * (sp.Matrix(QDG).T * m * sp.Matrix(QDG))[0]
    gamma = christoffel_symbols(m, QG)
    for i in range(n):
        momentum = sp.diff(tkin, QDG[i])
        ddt = from_time(sp.diff(at_time(momentum, QG, t).xreplace(
            {qd: sp.Function(str(q))(t).diff(t) for q, qd in zip(QG, QDG)}), t), QG, t, QDG, QDDG)
        mdot = [from_time(sp.diff(at_time(m[i, j], QG, t), t), QG, t, QDG) for j in range(n)]
        holds(mdot, [sum(sp.diff(m[i, j], QG[k]) * QDG[k] for k in range(n)) for j in range(n)])   # (13)
        eq12 = sum(m[i, j] * QDDG[j] for j in range(n)) + sum(mdot[j] * QDG[j] for j in range(n))
        holds(ddt, eq12)
        line1 = sum(m[i, j] * QDDG[j] for j in range(n)) + sum(
            sp.diff(m[i, j], QG[k]) * QDG[j] * QDG[k] for j in range(n) for k in range(n))
        line2 = sum(m[i, j] * QDDG[j] for j in range(n)) + sum(
            sp.Rational(1, 2) * (sp.diff(m[i, j], QG[k]) + sp.diff(m[i, k], QG[j])) * QDG[j] * QDG[k]
            for j in range(n) for k in range(n))
        holds(ddt, line1)
        holds(ddt, line2)                                                                         # (14)
        eq15 = sum(sp.Rational(1, 2) * sp.diff(m[j, k], QG[i]) * QDG[j] * QDG[k] for j in range(n) for k in range(n))
        holds(sp.diff(tkin, QG[i]), eq15)
        lagrange = ddt - sp.diff(tkin, QG[i])
        holds(lagrange, sum(m[i, j] * QDDG[j] for j in range(n))
              + sum(gamma[i][j][k] * QDG[j] * QDG[k] for j in range(n) for k in range(n)))


def test_eq16_gravity_force_needs_the_integral():
    """(16) misprint: ∂U_g/∂q_i = Σ_j ∫ρ_jA_j gᵀJ_j^(i) dx_j (as (31) has it); the printed
    Σ_j m_j gᵀJ_j^(i) depends on x_j (through x_j and ψ_jk(x_j)), and read at the centres of mass
    it misses the package's G in every row once the links bend (m_jψ_jk(l_jc) is not LM_jk)."""
    jacs = KIN.jacobians()
    masses = (m1_, m2_)
    corrected = [sum(integral(jacs[l][1, i], l) for l in range(2)) for i in range(6)]
    holds(corrected, label_gravity())
    scale = lambda st: np.abs(model_gravity(st)).max()      # noqa: E731
    for i in range(6):
        holds_numerically(g * corrected[i], lambda st, i=i: model_gravity(st)[i], scale)
        printed = sum(masses[l] * jacs[l][1, i] for l in range(2))
        assert printed.has(X, *KIN.shapes[0], *KIN.shapes[1])
        at_centre = 0
        for l in range(2):
            half = LINKS[l].length / 2
            shape_at = dict(zip(KIN.shapes[l], modes(l).shape([half])[0].tolist()))
            at_centre += masses[l] * jacs[l][1, i].xreplace(floats({X: half} | shape_at))
        misprint_numerically(g * at_centre, g * corrected[i], lambda st, i=i: model_gravity(st)[i], scale)


def test_eq17_elastic_force_of_one_mode():
    """(17) misprint: ∂U_e/∂δ_ij = Σ_k K_ijk δ_ik (= K_ijj δ_ij, no sum, for the exact modes, whose K
    is diagonal); the printed Σ_j K_ijj δ_ij adds the forces of all modes of link i into every row."""
    k = np.array(model().stiffness.tolist(), dtype=float)
    for state in STATES:
        derived = k @ state
        for i in range(2):
            rows = slice(2 + 2 * i, 4 + 2 * i)
            kii = modal_stiffness(i)
            printed = sum(kii[j, j] * state[rows][j] for j in range(2))
            corrected = kii @ state[rows]
            np.testing.assert_allclose(corrected, derived[rows], rtol=1e-10)
            np.testing.assert_allclose(np.diag(kii) * state[rows], derived[rows], rtol=1e-10)
            assert all(abs(printed - d) > 1e-6 * abs(d) for d in derived[rows])


def lagrange_residual(state, rates, accelerations):
    """Lagrange's equations of the package's model: (d/dt ∂T/∂q̇ − ∂T/∂q + ∂U/∂q) at one state,
    with U = U_g (labels by quadrature) + ½qᵀKq, and the chain rule of (12)–(15)."""
    mdl = model()
    m = mdl.mass_matrix
    point = dict(zip(Q, state))
    dm = [m.diff(q).xreplace(point) for q in Q]
    mnum = np.array(m.xreplace(point).tolist(), dtype=float)
    dmn = [np.array(d.tolist(), dtype=float) for d in dm]
    ddt = mnum @ accelerations + sum(dmn[k] * rates[k] for k in range(6)) @ rates
    dtdq = np.array([0.5 * rates @ dmn[i] @ rates for i in range(6)])
    ug = gravity_potential()
    dudq = np.array([at(GRAVITY * sp.diff(ug, q), state) for q in Q])
    k = np.array(mdl.stiffness.tolist(), dtype=float)
    return ddt - dtdq + dudq + k @ state


def test_eq18_eq19_equations_of_motion():
    """(19) holds: Mq̈ + Kq + Σ C_jk(i) q̇_j q̇_k + G·g = τ is Lagrange's equation (11) of the package's
    T and U. (18) is that equation with the misprinted terms of (16) and (17), printed over two
    lines of which the second carries the label "(9)"; corrected it is (19)."""
    rng = np.random.default_rng(5)
    k = np.array(model().stiffness.tolist(), dtype=float)
    for state in STATES:
        rates, accelerations = rng.uniform(-1, 1, 6), rng.uniform(-1, 1, 6)
        gamma = model_christoffel(state)
        eq19 = model_mass(state) @ accelerations + k @ state \
            + np.einsum("ijk,j,k->i", gamma, rates, rates) + model_gravity(state)
        np.testing.assert_allclose(eq19, lagrange_residual(state, rates, accelerations), rtol=1e-10, atol=1e-10)
        diagonal = np.diag(k) * state                       # K_ijj·δ_ij, one mode per row
        printed = np.array([0, 0] + [diagonal[2 + 2 * i] + diagonal[3 + 2 * i] for i in range(2) for _ in range(2)])
        assert not np.allclose(printed, k @ state, rtol=1e-6)
        np.testing.assert_allclose(diagonal, k @ state, rtol=1e-10, atol=1e-10)


# --------------------------------------------------------- 3.1: the two-link example

def test_eq20_eq21_deformed_positions():
    """(20), (21) hold: the package's r_1(x), r_2(x)."""
    holds(sp.Matrix([X * C1 - u1 * S1, X * S1 + u1 * C1]), KIN.points[0])
    holds(sp.Matrix([l1 * C1 - u1e * S1 + X * C12 - u2 * S12, l1 * S1 + u1e * C1 + X * S12 + u2 * C12]),
          KIN.points[1])


def test_eq24_tip_deflection():
    """(24) holds: link 2 starts at r_1(l_1) (its modes are clamped there, ψ_2k(0) = 0), with
    u_1e = u_1(l_1) and ψ_1je = ψ_1j(l_1); the model's tip values are the mode shapes at l_1."""
    holds(KIN.tips[0], KIN.points[0].xreplace({X: l1, p11: e11, p12: e12}))
    holds(KIN.points[1].xreplace({X: 0, p21: 0, p22: 0}), KIN.tips[0])      # clamped: ψ_2k(0) = 0
    assert np.abs(modes(1).shape([0.0])).max() <= 1e-14
    np.testing.assert_allclose([values()[e11], values()[e12]], modes(0).shape([LINKS[0].length])[0], rtol=1e-15)


def test_eq27_coordinates():
    """(27) holds: q = (θ1, θ2, ξ11, ξ12, ξ21, ξ22), the package's order."""
    names = ["theta1", "theta2", "delta1_1", "delta1_2", "delta2_1", "delta2_2"]
    assert [str(q) for q in KIN.coordinates] == names
    assert [str(q) for q in model().coordinates] == names


J1_PRINTED = {            # (row, column): (printed, corrected or None)
    (0, 0): (-u1 * C1 - X * S1, None),
    (1, 0): (-u1 * S1 - X * C1, X * C1 - u1 * S1),
    (0, 1): (0, None), (1, 1): (0, None),
    (0, 2): (-p11 * S1, None), (1, 2): (p11 * C1, None),
    (0, 3): (-p12 * C1, -p12 * S1), (1, 3): (p12 * S1, p12 * C1),
    (0, 4): (0, None), (1, 4): (0, None), (0, 5): (0, None), (1, 5): (0, None),
}


@pytest.mark.parametrize("entry", list(J1_PRINTED), ids=lambda e: f"J1_{e[0] + 1}{e[1] + 1}")
def test_eq28_jacobian_of_link_1(entry):
    """(28): J1[2,1] = x1C1 − u1S1 (printed −u1S1 − x1C1) and the ξ12 column −ψ12S1, ψ12C1 (printed
    −ψ12C1, ψ12S1) are misprints; the other entries hold."""
    printed, corrected = J1_PRINTED[entry]
    check(printed, corrected, KIN.jacobians()[0][entry])


#: (29) as converted: four rows, two of two entries (the θ columns) and two of four (the ξ columns)
J2_CONVERTED = [
    [-l1 * S1 - u1e * C1 - u2 * C12 - X * S12, -u2 * C12 - X * S12],
    [l1 * C1 - u1e * S1 - u2 * S12 + X * C12, -u2 * S12 + X * C12],
    [-e11 * S1, -e12 * S1, -p21 * S12, -p22 * S12],
    [e11 * C1, e12 * C1, p21 * C12, p22 * C12],
]


def rejoined_j2():
    """The 2 × 6 matrix the converted rows come from: rows 1 + 3 and rows 2 + 4."""
    return sp.Matrix([J2_CONVERTED[0] + J2_CONVERTED[2], J2_CONVERTED[1] + J2_CONVERTED[3]])


def test_eq29_layout_is_garbled():
    """(29) is garbled by the text conversion: a 2 × 6 matrix set in two blocks became four rows of
    unequal length (2, 2, 4, 4), which is no matrix; rejoined, it is the package's J2."""
    assert [len(r) for r in J2_CONVERTED] == [2, 2, 4, 4]
    with pytest.raises(ValueError):
        sp.Matrix(J2_CONVERTED)
    holds(rejoined_j2(), KIN.jacobians()[1])


@pytest.mark.parametrize("entry", [(r, c) for c in range(6) for r in range(2)],
                         ids=lambda e: f"J2_{e[0] + 1}{e[1] + 1}")
def test_eq29_jacobian_of_link_2(entry):
    """(29): every entry of the rejoined J2 holds."""
    check(rejoined_j2()[entry], None, KIN.jacobians()[1][entry])


def test_eq31_gravity_rows():
    """(31) holds for the rows it prints, G_i = Σ_{j=i}^2 ∫ρ_jA_j J_j[2, i] dx_j (i = 1, 2). The modal
    rows G3 … G6 (same sum from j = 1) are not printed and are not zero: G3 = (LM11 + m2ψ11e)C1,
    G4 = (LM12 + m2ψ12e)C1, G5 = LM21·C12, G6 = LM22·C12."""
    jacs = KIN.jacobians()
    derived = label_gravity()
    for i in (0, 1):
        holds(sum(integral(jacs[j][1, i], j) for j in range(i, 2)), derived[i])
    modal = [(LM[0][0] + m2_ * e11) * C1, (LM[0][1] + m2_ * e12) * C1, LM[1][0] * C12, LM[1][1] * C12]
    holds(sp.Matrix([modal]), derived[:, 2:])
    for state in STATES:
        assert np.all(np.abs(model_gravity(state)[2:]) > 1e-3 * np.abs(model_gravity(state)).max())
        np.testing.assert_allclose([at(GRAVITY * e, state) for e in modal], model_gravity(state)[2:], rtol=1e-10)


M_PRINTED = {             # (row, column) 0-based: (printed, corrected or None)
    (0, 0): (I1(X**2 + u1**2) - I2(l1**2 + u1e**2 + u2**2 + X**2
                                   - 2 * (l1 * X * C2 - l1 * u2 * S2 - u1e * u2 * C2 + u1e * X * S2)),
             I1(X**2 + u1**2) + I2(l1**2 + u1e**2 + u2**2 + X**2
                                   + 2 * (l1 * X * C2 - l1 * u2 * S2 + u1e * u2 * C2 + u1e * X * S2))),
    (0, 1): (I2(X**2 + u2**2 - l1 * X * C2 - l1 * u2 * S2 - u1e * u2 * C2 + u1e * X * S2),
             I2(X**2 + u2**2 + l1 * X * C2 - l1 * u2 * S2 + u1e * u2 * C2 + u1e * X * S2)),
    (0, 2): (I1(X * p11) + e11 * I2(l1 - X * C2 - u2 * S2), I1(X * p11) + e11 * I2(l1 + X * C2 - u2 * S2)),
    (0, 3): (I1(X * p12) + e12 * I2(l1 - X * C2 - u2 * S2), I1(X * p12) + e12 * I2(l1 + X * C2 - u2 * S2)),
    (0, 4): (I2(p21 * (X + l1 * C2 + u1e * S2)), None),
    (0, 5): (I2(p22 * (X + l1 * C2 + u1e * S2)), None),
    (1, 1): (I2(X**2 + u2**2), None),
    (1, 2): (e11 * I2(X * C2 - u2 * S2), None),
    (1, 3): (e12 * I2(X * C2 - u2 * S2), None),
    (1, 4): (I2(X * p21), None),
    (1, 5): (I2(X * p22), None),
    (2, 2): (I1(p11**2) + e11**2 * I2(1), None),
    (2, 3): (I1(p11 * p12) + e11 * e12 * I2(1), None),
    (2, 4): (e11 * C2 * I2(p21), None),
    (2, 5): (e11 * C2 * I2(p22), None),
    (3, 3): (I1(p12**2) + e12**2 * I2(1), None),
    (3, 4): (e12 * C2 * I2(p21), None),
    (3, 5): (e12 * C2 * I2(p22), None),
    (4, 4): (I2(p21**2), None),
    (4, 5): (I2(p21 * p22), None),
    (5, 5): (I2(p22**2), None),
}


@pytest.mark.parametrize("entry", list(M_PRINTED), ids=lambda e: f"M{e[0] + 1}{e[1] + 1}")
def test_eq32_mass_matrix_entry(entry):
    """(32): M11, M12, M13, M14 are misprinted (see M_PRINTED for the corrected forms); the other
    17 entries of the upper triangle hold, symbolically and against the package's M."""
    printed, corrected = M_PRINTED[entry]
    check(printed, corrected, label_mass_matrix()[entry], lambda st: model_mass(st)[entry], mass_scale)


def test_eq32_m11_m12_sign_errors_are_not_only_line_initial_signs():
    """The printed M11 with its two line-initial minus signs made plus is still wrong by
    4·u1e·C2·∫u2ρ2A2dx2: the term u1e·u2·C2 has the wrong sign in M11 and in M12; M12 also has
    −l1x2C2 for +l1x2C2, and M13, M14 −x2C2 for +x2C2."""
    derived = label_mass_matrix()
    plus_signs = I1(X**2 + u1**2) + I2(l1**2 + u1e**2 + u2**2 + X**2
                                       + 2 * (l1 * X * C2 - l1 * u2 * S2 - u1e * u2 * C2 + u1e * X * S2))
    holds(derived[0, 0] - plus_signs, 4 * C2 * u1e * I2(u2))
    holds(derived[0, 1] - M_PRINTED[(0, 1)][0], 2 * l1 * C2 * I2(X) + 2 * C2 * u1e * I2(u2))
    holds(derived[0, 2] - M_PRINTED[(0, 2)][0], 2 * e11 * C2 * I2(X))


G_PRINTED = {
    0: I1(X * C1 - u1 * S1) + I2(l1 * C1 - u1e * S1 + X * C12 - u2 * S12),
    1: I2(X * C12 - u2 * S12),
}


@pytest.mark.parametrize("row", [0, 1], ids=["G1", "G2"])
def test_eq33_gravity_entry(row):
    """(33) holds: G1 and G2 (times g, the package's gravity load). Its G1 uses x1C1 − u1S1, the
    correct J1[2,1], which confirms that (28)'s −u1S1 − x1C1 is a typesetting slip."""
    check(G_PRINTED[row], None, label_gravity()[row], lambda st: model_gravity(st)[row] / GRAVITY,
          lambda st: np.abs(model_gravity(st)).max() / GRAVITY)


# ------------------------------------------------------------------ modal identities (40)–(42)

def cantilever_roots(count):
    """λ_k of 1 + cos λ·cosh λ = 0, solved as cos λ + 1/cosh λ = 0 (no cancellation)."""
    f = lambda lam: np.cos(lam) + 1.0 / np.cosh(lam)      # noqa: E731
    return np.array([brentq(f, (k - 0.5) * np.pi - 0.5, (k - 0.5) * np.pi + 0.5, xtol=1e-15, rtol=1e-15)
                     for k in range(1, count + 1)])


def cantilever_shapes(xi, lam):
    """φ_k(ξ) = cosh − cos − σ_k(sinh − sin), with ∫_0^1 φ² dξ = 1, evaluated without overflow."""
    z = np.outer(xi, lam)
    sigma = (np.sinh(lam) - np.sin(lam)) / (np.cosh(lam) + np.cos(lam))
    # ½e^z(1 − σ) = e^(z−λ)(e^−λ + cos λ + sin λ)/(1 + e^−2λ + 2 cos λ e^−λ)
    grow = np.exp(z - lam) * (np.exp(-lam) + np.cos(lam) + np.sin(lam)) \
        / (1 + np.exp(-2 * lam) + 2 * np.cos(lam) * np.exp(-lam))
    return grow + 0.5 * np.exp(-z) * (1 + sigma) - np.cos(z) + sigma * np.sin(z)


MODE_COUNTS = (1, 2, 4, 8, 16, 32)


@lru_cache(maxsize=None)
def modal_sums(modal_mass="unit"):
    """Relative remainders 1 − ΣLM_j²/m, 1 − ΣLM_jAM_j/(m·l_c), 1 − ΣAM_j²/J of link AB's exact
    clamped-free modes, as printed (no division by NM_j), for each count in MODE_COUNTS."""
    ln = LINKS[0]
    mass = ln.rho_a * ln.length
    nm = 1.0 if modal_mass == "unit" else mass
    xg, wg = gauss_points(400)
    psi = cantilever_shapes(xg, cantilever_roots(max(MODE_COUNTS))) * np.sqrt(nm / mass)
    w, x = wg * ln.length * ln.rho_a, xg * ln.length
    assert np.allclose((psi.T * w) @ psi, nm * np.eye(psi.shape[1]), atol=1e-12 * nm)
    lm, am = w @ psi, (w * x) @ psi
    first, second = mass * ln.length / 2, mass * ln.length ** 2 / 3
    return {n: (1 - (lm[:n] ** 2).sum() / mass, 1 - (lm[:n] * am[:n]).sum() / first,
                1 - (am[:n] ** 2).sum() / second) for n in MODE_COUNTS}


def test_eq40_to_eq42_modal_identities_converge():
    """(40)–(42) hold for clamped-free modes of unit modal mass (NM_j = 1 kg), as the number of
    modes grows: ΣLM_j² → m, ΣLM_jAM_j → m·l_c, ΣAM_j² → J (Parseval for 1 and x in the complete
    orthonormal set). The relative remainders fall as 4/(π²N), 4/(π³N²) and 4/(π⁴N³)."""
    sums = modal_sums("unit")
    for which in range(3):
        r = [sums[n][which] for n in MODE_COUNTS]
        assert all(a > b > 0 for a, b in zip(r, r[1:]))
    n = MODE_COUNTS[-1]
    assert n * sums[n][0] == pytest.approx(4 / np.pi ** 2, rel=0.01)
    assert n ** 2 * sums[n][1] == pytest.approx(4 / np.pi ** 3, rel=0.01)
    assert n ** 3 * sums[n][2] == pytest.approx(4 / np.pi ** 4, rel=0.01)
    assert sums[n][0] < 0.013 and sums[n][1] < 1.3e-4 and sums[n][2] < 1.3e-6


def test_eq40_to_eq42_need_unit_modal_mass():
    """As printed, (40)–(42) need NM_j = 1: with the package's default modal mass NM_j = m (or any
    other) the sums tend to NM·m, NM·m·l_c, NM·J. The form free of the normalisation is
    Σ LM_j²/NM_j = m (and likewise for (41), (42))."""
    mass = LINKS[0].rho_a * LINKS[0].length
    unit, link_mass = modal_sums("unit"), modal_sums("link-mass")
    for n in MODE_COUNTS:
        for which in range(3):
            assert 1 - link_mass[n][which] == pytest.approx(mass * (1 - unit[n][which]), rel=1e-12)
    assert abs(link_mass[32][0]) > 0.5        # ΣLM² ≈ 0.2·m, nowhere near m


@pytest.mark.parametrize("count", [1, 2, 4])
def test_eq40_to_eq42_package_modes_are_the_exact_modes(count):
    """The package's beam_modes give the same LM_j, AM_j as the exact modes for the first modes (the
    paper's example uses two)."""
    ln = LINKS[0]
    xg, wg = gauss_points(400)
    w, x = wg * ln.length * ln.rho_a, xg * ln.length
    pkg = beam_modes(count, ln.length, ln.rho_a, ln.ei, normalisation="unit").shape(x)
    exact = cantilever_shapes(xg, cantilever_roots(count)) / np.sqrt(ln.rho_a * ln.length)
    np.testing.assert_allclose(w @ pkg, w @ exact, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose((w * x) @ pkg, (w * x) @ exact, rtol=1e-10, atol=1e-12)


def test_package_cantilever_roots_beyond_eight_modes():
    """The package's cantilever roots for 16 modes should be those of 1 + cos λ cosh λ = 0."""
    np.testing.assert_allclose(frequency_roots(16), cantilever_roots(16), rtol=1e-9)


# ----------------------------------------------------------- 3.2: velocity coupling (43)–(60)

def test_eq43_christoffel_symbols():
    """(43) holds: the velocity terms of Lagrange's equation are Σ C_jk(i) q̇_j q̇_k with the printed
    C_jk(i), the package's christoffel_symbols and velocity_terms (generic symmetric M(q))."""
    m = generic_mass_matrix(QG)
    n = N_GENERIC
    gamma = christoffel_symbols(m, QG)
    printed = [[[sp.Rational(1, 2) * (sp.diff(m[i, j], QG[k]) + sp.diff(m[i, k], QG[j]) - sp.diff(m[j, k], QG[i]))
                 for k in range(n)] for j in range(n)] for i in range(n)]
    for i in range(n):
        holds(sp.Matrix(printed[i]), sp.Matrix(gamma[i]))
    holds(velocity_terms(m, QG, QDG), sp.Matrix([sum(printed[i][j][k] * QDG[j] * QDG[k]
                                                     for j in range(n) for k in range(n)) for i in range(n)]))


THETA, DELTA = range(2), range(2, 6)
QF = list(sp.symbols("q1:7", real=True))
QDF = list(sp.symbols("qd1:7", real=True))
QDDF = list(sp.symbols("qdd1:7", real=True))


@lru_cache(maxsize=None)
def generic_six():
    """A general symmetric M(q) of two rigid and four flexible coordinates, its C_jk(i), G(q), K."""
    m = generic_mass_matrix(QF)
    gravity = [sp.Function(f"G{i + 1}")(*QF) for i in range(6)]
    k = sp.Matrix(6, 6, lambda i, j: sp.Symbol(f"K{min(i, j) + 1}{max(i, j) + 1}") if i >= 2 and j >= 2 else 0)
    return m, christoffel_symbols(m, QF), gravity, k


#: the blocks each printed symbol differentiates, in the order of its three terms
PRINTED_BLOCKS = {"P": "AAA", "Q": "ABB", "R": "BBD", "P^": "BBA", "Q^": "BDB", "R^": "DDD"}
#: the index pattern (i, j, k) of each symbol: rigid θ or flexible δ
PATTERNS = {"P": (THETA, THETA, THETA), "Q": (THETA, THETA, DELTA), "R": (THETA, DELTA, DELTA),
            "P^": (DELTA, THETA, THETA), "Q^": (DELTA, THETA, DELTA), "R^": (DELTA, DELTA, DELTA)}


def kind(a, b) -> str:
    """The block of M that entry (a, b) lies in: A (θθ), B (θδ or δθ) or D (δδ)."""
    return "A" if a < 2 and b < 2 else "D" if a >= 2 and b >= 2 else "B"


def partitioned(m, i, j, k):
    """½{∂X_ij/∂q_k + ∂Y_ik/∂q_j − ∂Z_jk/∂q_i} of (46)–(51), X, Y, Z the blocks of M."""
    return sp.Rational(1, 2) * (sp.diff(m[i, j], QF[k]) + sp.diff(m[i, k], QF[j]) - sp.diff(m[j, k], QF[i]))


def test_eq46_to_eq51_partitioned_christoffel_symbols():
    """(46)–(51) hold: each is C_jk(i) of (43) for one pattern of rigid (θ) and flexible (δ)
    indices, with the blocks A (θθ), B (θδ) and D (δδ) of M that the paper names; in (49) and (50)
    B_ij with i flexible stands for the entry M_ij = B_ji of the symmetric M."""
    m, gamma, _, _ = generic_six()
    for name, (ri, rj, rk) in PATTERNS.items():
        for i in ri:
            for j in rj:
                for k in rk:
                    assert kind(i, j) + kind(i, k) + kind(j, k) == PRINTED_BLOCKS[name]
                    holds(partitioned(m, i, j, k), gamma[i][j][k])


def partitioned_row(i, factor):
    """Row i of (44) (i rigid) or (45) (i flexible), with *factor* on the θ̇δ̇ term."""
    m = generic_six()[0]
    row = sum(m[i, j] * QDDF[j] for j in THETA) + sum(m[i, j] * QDDF[j] for j in DELTA)
    row += sum(partitioned(m, i, j, kk) * QDF[j] * QDF[kk] for j in THETA for kk in THETA)
    row += factor * sum(partitioned(m, i, j, kk) * QDF[j] * QDF[kk] for j in THETA for kk in DELTA)
    row += sum(partitioned(m, i, j, kk) * QDF[j] * QDF[kk] for j in DELTA for kk in DELTA)
    return row


def full_row(i):
    """Row i of (19): Mq̈ + Kq + Σ C_jk(i) q̇_j q̇_k + G."""
    m, gamma, gravity, k = generic_six()
    return sum(m[i, j] * QDDF[j] for j in range(6)) + sum(k[i, j] * QF[j] for j in range(6)) \
        + sum(gamma[i][j][kk] * QDF[j] * QDF[kk] for j in range(6) for kk in range(6)) + gravity[i]


@pytest.mark.parametrize("i", [0, 1])
def test_eq44_rigid_rows_need_twice_the_q_terms(i):
    """(44) misprint: the θ̇_jδ̇_k terms appear twice in ΣΣ C_jk(i) q̇_j q̇_k (as jk and kj), so the
    Q term needs a factor 2: ΣA_ijθ̈_j + ΣB_ijδ̈_j + ΣΣP θ̇θ̇ + 2ΣΣQ θ̇δ̇ + ΣΣR δ̇δ̇ + G_i = τ_i
    (and the first sum runs over j, not i)."""
    _, _, gravity, _ = generic_six()
    misprint(partitioned_row(i, 1) + gravity[i], partitioned_row(i, 2) + gravity[i], full_row(i))


@pytest.mark.parametrize("i", [2, 3, 4, 5])
def test_eq45_flexible_rows_need_twice_the_q_terms_and_their_gravity(i):
    """(45) misprint: ΣB_jiθ̈_j + ΣD_ijδ̈_j + ΣΣP̂θ̇θ̇ + 2ΣΣQ̂θ̇δ̇ + ΣΣR̂δ̇δ̇ + Σ_{j=3}^6 K_ijδ_j
    + G_i = 0 (i = 3 … 6): the printed form lacks the 2 and the modal gravity G_i, and its
    elastic sum runs over j = 1, 2 (read literally, the K_ij of the rigid coordinates, all zero)."""
    _, _, gravity, k = generic_six()
    elastic = sum(k[i, j] * QF[j] for j in DELTA)
    assert sum(k[i, j] * QF[j] for j in THETA) == 0
    misprint(partitioned_row(i, 1) + elastic, partitioned_row(i, 2) + elastic + gravity[i], full_row(i))
    misprint(partitioned_row(i, 2) + elastic, partitioned_row(i, 2) + elastic + gravity[i], full_row(i))
    for state in STATES:                        # and the example's modal gravity is not zero
        assert abs(model_gravity(state)[i]) > 1e-3 * np.abs(model_gravity(state)).max()


def test_eq51_d_does_not_depend_on_the_flexible_states():
    """Text after (51) holds: D (the δδ block of (32), not of (29)) does not depend on δ, so
    R̂_jk(i) = 0. So does R_jk(i) of (48) in this example (the δδ blocks of C(1), C(2) vanish),
    although B depends on δ."""
    m = label_mass_matrix()
    assert all(sp.diff(m[a, b], Q[c]) == 0 for a in DELTA for b in DELTA for c in DELTA)
    assert any(sp.diff(m[a, b], Q[c]) != 0 for a in THETA for b in DELTA for c in DELTA)
    gamma = label_christoffel()
    for i in range(6):
        for j in DELTA:
            for k in DELTA:
                holds(gamma[i][j][k], 0)
    for state in STATES:
        assert np.abs(model_christoffel(state)[:, 2:, 2:]).max() <= 1e-12 * christoffel_scale(state)


def test_eq52_symmetry():
    """(52) holds: C_jk(i) = C_kj(i), for any M and for the package's model."""
    _, gamma, _, _ = generic_six()
    for i in range(6):
        holds(sp.Matrix(gamma[i]), sp.Matrix(gamma[i]).T)
    for state in STATES:
        c = model_christoffel(state)
        np.testing.assert_allclose(c, np.swapaxes(c, 1, 2), rtol=0, atol=1e-14)


def reflective_failures(m, coordinates):
    """(i, j, k), 1-based, with j ≤ i, k, where C_jk(i) ≠ −C_ji(k)."""
    gamma = christoffel_symbols(m, coordinates)
    n = len(coordinates)
    return {(i + 1, j + 1, k + 1) for i in range(n) for j in range(n) for k in range(n)
            if j <= min(i, k) and reduced(gamma[i][j][k] + gamma[k][j][i]) != 0}


def test_eq53_reflective_coupling():
    """(53): C_jk(i) + C_ji(k) = ∂M_ik/∂q_j for any M, so C_jk(i) = −C_ji(k) needs ∂M_ik/∂q_j = 0.
    It holds for rigid chains (M_ik depends on joints past min(i, k) only); for the flexible
    example it fails exactly for j = 2 (θ2) and {i, k} = {2, 3}, {2, 4}, {3, 5}, {3, 6}, {4, 5},
    {4, 6}: the entries M23, M24, M35, M36, M45, M46 depend on θ2."""
    m, gamma, _, _ = generic_six()
    for i, j, k in ((0, 1, 2), (3, 2, 5), (5, 4, 1)):
        holds(gamma[i][j][k] + gamma[k][j][i], sp.diff(m[i, k], QF[j]))
    rigid = flexible_chain([FlexibleLink(0.5, 0.4, 2.0, modes=0), FlexibleLink(0.4, 0.3, 1.0, modes=0),
                            FlexibleLink(0.3, 0.2, 1.0, modes=0)])
    assert reflective_failures(rigid.mass_matrix, list(rigid.coordinates)) == set()
    expected = {(i, 2, k) for a, b in ((2, 3), (2, 4), (3, 5), (3, 6), (4, 5), (4, 6)) for i, k in ((a, b), (b, a))}
    assert reflective_failures(label_mass_matrix().xreplace(ORTHOGONAL), Q) == expected
    # the package's numeric model agrees
    for state in STATES:
        c = model_christoffel(state)
        fails = {(i + 1, j + 1, k + 1) for i in range(6) for j in range(6) for k in range(6)
                 if j <= min(i, k) and abs(c[i, j, k] + c[k, j, i]) > 1e-9 * christoffel_scale(state)}
        assert fails == expected


#: (54) as printed; q_ij inside d_21 … d_52 is the modal coordinate ξ_ij (delta{i}_{j})
D_PRINTED = {
    "d1": I2((u1e * C2 - l1 * S2) * X - (u1e * S2 + l1 * C2) * u2),
    "d21": I1(p11**2 * d11) + e11 * I2(S2 * X + C2 * u2 + u1e),
    "d22": I1(p12**2 * d12) + e12 * I2(S2 * X + C2 * u2 + u1e),
    "d31": e11 * I2(S2 * X + C2 * u2),
    "d32": e12 * I2(S2 * X + C2 * u2),
    "d41": I2(p21 * (p21 * d21 + p22 * d22)),
    "d42": I2(p22 * (p21 * d21 + p22 * d22)),
    "d51": I2(p21 * ((p21 * d21 + p22 * d22) + (u1e * C2 - l1 * S2))),
    "d52": I2(p22 * ((p21 * d21 + p22 * d22) + (u1e * C2 - l1 * S2))),
    "d61": e11 * S2 * I2(p21),
    "d62": e11 * S2 * I2(p22),
    "d71": e12 * S2 * I2(p21),
    "d72": e12 * S2 * I2(p22),
}
#: the entry C_jk(i) (0-based i, j, k) and sign that each d stands for
D_MEANS = {"d1": (0, 0, 1, 1), "d21": (0, 0, 2, 1), "d22": (0, 0, 3, 1), "d31": (1, 0, 2, 1),
           "d32": (1, 0, 3, 1), "d41": (1, 0, 4, 1), "d42": (1, 0, 5, 1), "d51": (0, 0, 4, 1),
           "d52": (0, 0, 5, 1), "d61": (2, 0, 4, -1), "d62": (2, 0, 5, -1), "d71": (3, 0, 4, -1),
           "d72": (3, 0, 5, -1)}


@pytest.mark.parametrize("name", list(D_PRINTED))
def test_eq54_d_coefficient(name):
    """(54) holds as a list of coefficients: each printed d is one C_jk(i) (D_MEANS), symbolically
    with orthogonal modes and against the package's Christoffel symbols. But d4k = C_1,4+k(2) and
    d5k = C_1,4+k(1): (55), (56), (59), (60) use them the other way round."""
    i, j, k, sign = D_MEANS[name]
    check(D_PRINTED[name].xreplace(ORTHOGONAL), None, sign * label_christoffel()[i][j][k],
          lambda st: sign * model_christoffel(st)[i, j, k], christoffel_scale)


def test_eq54_q_is_the_modal_coordinate_and_d2_assumes_orthogonal_modes():
    """q_11, q_12, q_21, q_22 in (54) are the modal coordinates ξ_ij (read as entries of the vector
    q_12 of (27), θ1 and θ2, d21 would not be a Christoffel symbol). d21 = ∫ψ11²q11 ρ1A1dx1 + …
    holds for orthogonal modes only; in general its first term is ∫ψ11u1ρ1A1dx1 (d4, d5 already
    carry the whole u2)."""
    derived = label_christoffel()[0][0][2]
    as_theta = I1(p11**2 * th1) + e11 * I2(S2 * X + C2 * u2 + u1e)
    assert not same(as_theta, derived)
    general = sp.Rational(1, 2) * sp.diff(label_mass_matrix()[0, 0], d11)
    misprint(D_PRINTED["d21"], I1(p11 * u1) + e11 * I2(S2 * X + C2 * u2 + u1e), general)
    holds(D_PRINTED["d41"], sp.Rational(1, 2) * (sp.diff(label_mass_matrix()[1, 4], th1)
                                                 + sp.diff(label_mass_matrix()[0, 1], d21)
                                                 - sp.diff(label_mass_matrix()[0, 4], th2)))


_d = {name: sp.Symbol(name) for name in D_PRINTED}
d_1, d_21, d_22, d_31, d_32, d_41, d_42, d_51, d_52, d_61, d_62, d_71, d_72 = _d.values()
Z = sp.S.Zero
C_PRINTED = [        # upper triangles of (55)–(60)
    [[Z, d_1, d_21, d_22, d_41, d_42], [d_1, Z, Z, d_41, d_42], [Z, Z, Z, Z], [Z, Z, Z], [Z, Z], [Z]],
    [[-d_1, Z, d_31, d_32, d_51, d_52], [Z, Z, Z, d_51, d_52], [Z, Z, -d_61 / 2, -d_62 / 2], [Z, -d_71 / 2, -d_72 / 2],
     [Z, Z], [Z]],
    [[-d_21, -d_31, Z, Z, -d_61, -d_62], [-d_31, Z, Z, -d_61 / 2, -d_62 / 2], [Z, Z, Z, Z], [Z, Z, Z], [Z, Z], [Z]],
    [[-d_22, -d_32, Z, Z, -d_71, -d_72], [-d_32, Z, Z, -d_71 / 2, -d_72 / 2], [Z, Z, Z, Z], [Z, Z, Z], [Z, Z], [Z]],
    [[-d_41, -d_51, d_61, d_71, Z, Z], [-d_51, d_61 / 2, d_71 / 2, Z, Z], [Z, Z, Z, Z], [Z, Z, Z], [Z, Z], [Z]],
    [[-d_42, -d_52, d_62, d_72, Z, Z], [-d_52, d_62 / 2, d_72 / 2, Z, Z], [Z, Z, Z, Z], [Z, Z, Z], [Z, Z], [Z]],
]
#: corrected entries (i, j, k), 0-based, j ≤ k
C_CORRECTED = {
    (0, 0, 4): d_51, (0, 0, 5): d_52, (0, 1, 4): d_51, (0, 1, 5): d_52,
    (1, 0, 4): d_41, (1, 0, 5): d_42, (1, 1, 4): d_41, (1, 1, 5): d_42,
    (1, 2, 4): Z, (1, 2, 5): Z, (1, 3, 4): Z, (1, 3, 5): Z,
    (2, 1, 4): -d_61, (2, 1, 5): -d_62,
    (3, 1, 4): -d_71, (3, 1, 5): -d_72,
    (4, 0, 0): -d_51, (4, 0, 1): -d_41, (4, 1, 1): -d_41, (4, 1, 2): Z, (4, 1, 3): Z,
    (5, 0, 0): -d_52, (5, 0, 1): -d_42, (5, 1, 1): -d_42, (5, 1, 2): Z, (5, 1, 3): Z,
}
C_ENTRIES = [(i, j, k) for i in range(6) for j in range(6) for k in range(j, 6)]


def printed_c(i, j, k):
    return C_PRINTED[i][j][k - j]


def in_d(expr, definitions=None):
    return sp.sympify(expr).xreplace({_d[n]: e.xreplace(ORTHOGONAL) for n, e in (definitions or D_PRINTED).items()})


@pytest.mark.parametrize("entry", C_ENTRIES, ids=lambda e: f"C{e[0] + 1}_{e[1] + 1}{e[2] + 1}")
def test_eq55_to_eq60_velocity_coupling(entry):
    """(55)–(60), entry by entry (the paper prints the upper triangles; C(i) is symmetric by (52)):
    26 of the 126 printed entries are misprints (C_CORRECTED), 100 hold, symbolically with the
    printed d's of (54) and against the package's Christoffel symbols."""
    i, j, k = entry
    corrected = C_CORRECTED.get(entry)
    check(in_d(printed_c(*entry)), None if corrected is None else in_d(corrected), label_christoffel()[i][j][k],
          lambda st: model_christoffel(st)[i, j, k], christoffel_scale)


def test_eq55_to_eq60_misprints_are_a_d4_d5_swap_and_misplaced_halves():
    """With the definitions of d4k and d5k interchanged, 14 of the 26 wrong entries hold; the other
    12 are the halves: the paper splits ∂M2,2+k/∂ξ2l = −d(5+k)l between C_2+k,4+l(2) and
    C_2,4+l(2+k) (−d/2 each) and puts +d/2 at C_2,2+k(4+l); the derivation gives 0, −d and 0. The
    printed halves break C_jk(i) + C_ji(k) = ∂M_ik/∂q_j, which the derivation keeps."""
    swapped = dict(D_PRINTED) | {"d41": D_PRINTED["d51"], "d42": D_PRINTED["d52"],
                                 "d51": D_PRINTED["d41"], "d52": D_PRINTED["d42"]}
    gamma = label_christoffel()
    wrong = {e for e in C_ENTRIES if not same(in_d(printed_c(*e), swapped), gamma[e[0]][e[1]][e[2]])}
    halves = {(1, 2, 4), (1, 2, 5), (1, 3, 4), (1, 3, 5), (2, 1, 4), (2, 1, 5), (3, 1, 4), (3, 1, 5),
              (4, 1, 2), (4, 1, 3), (5, 1, 2), (5, 1, 3)}
    assert wrong == halves
    # C_jk(i) + C_ji(k) = ∂M_ik/∂q_j: the printed halves break it, e.g. C_23(5) + C_25(3) = ∂M35/∂θ2
    m = label_mass_matrix().xreplace(ORTHOGONAL)
    holds(gamma[4][1][2] + gamma[2][1][4], sp.diff(m[4, 2], th2))
    assert not same(in_d(printed_c(4, 1, 2) + printed_c(2, 1, 4)), sp.diff(m[4, 2], th2))
    assert set(C_CORRECTED) - halves == {e for e in C_ENTRIES if printed_c(*e).has(d_41, d_42, d_51, d_52)}
