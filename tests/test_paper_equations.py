"""Equations (11)–(35) of Stocco & Yedlin, "Modelling Robot Dynamics with Masses and Pulleys".

Every printed result is derived here from first principles with the package's own
machinery: mass matrices from kinematics (``point_mass_matrix``), node matrices by
congruence M' = T⁻ᵀ·M·T⁻¹ (``congruence`` with the ``serial`` or ``parallel`` T),
element values by the grounded/floating split of ``laplacian_split`` done
symbolically, and circuit equations by symbolic nodal analysis of the element list
(``analogy.nodal``). The printed forms below are written by hand from the paper;
they are claims under test. Where a printed form is a misprint, its test asserts
that the printed form differs from the derivation and that the corrected form
equals it. docs/equations.md tabulates the verdicts.

Notation. Serial robots: node k moves at v_k = r_1 + … + r_k, actuator k acts
between nodes k−1 and k (0 is ground). Parallel robots: T = I, actuator k acts
between ground and node k. The paper's i_k is the current of source k (= joint
force f_k), so the current injected into the nodes is T⁻ᵀ·(i_1 … i_n), which the
package calls the node currents.
"""

from functools import lru_cache
from itertools import permutations

import numpy as np
import pytest
import sympy as sp

from analogy.circuit.elements import laplacian_split
from analogy.circuit.nodal import nodal_analysis
from analogy.circuit.topology import congruence, parallel, serial
from analogy.model.robots import planar_serial, point_mass_matrix, redundant_actuators

s = sp.Symbol("s")
q1, q2, q3 = sp.symbols("q1 q2 q3", real=True)
l1, l2, d1, d2, d3 = sp.symbols("l1 l2 d1 d2 d3", positive=True)
m1, m2, m3, m4, m5, m6 = sp.symbols("m1:7")
b1, b2, b3 = sp.symbols("b1:4")
f1, f2, f3 = sp.symbols("f1:4")
r1, r2, r3 = sp.symbols("r1:4")
i1, i2, i3 = sp.symbols("i1:4")
v1, v2, v3 = sp.symbols("v1:4")
g1, g2, g3 = sp.symbols("g1:4")
c1, c2, c3, c12, c13, c23 = sp.symbols("c1 c2 c3 c12 c13 c23")


# --------------------------------------------------------------------------- helpers

def same(a, b) -> bool:
    """True when a − b simplifies to zero (scalars or matrices)."""
    diff = sp.Matrix(a) - sp.Matrix(b) if isinstance(a, (sp.MatrixBase, list)) else sp.Matrix([a - b])
    return sp.simplify(diff).is_zero_matrix


def holds(printed, derived):
    """The printed form is the derivation."""
    assert same(printed, derived), f"printed {printed} != derived {sp.simplify(derived)}"


def misprint(printed, corrected, derived):
    """The printed form is wrong and the corrected form is the derivation."""
    assert not same(printed, derived), f"printed {printed} is not a misprint: it equals the derivation"
    assert same(corrected, derived), f"corrected {corrected} != derived {sp.simplify(derived)}"


def t_matrix(kind: str, n: int) -> sp.Matrix:
    """The package's joint-to-node map T as an exact sympy matrix."""
    top = serial(n) if kind == "serial" else parallel(n)
    return sp.Matrix(top.matrix.astype(int))


def node_matrix(x, kind: str) -> sp.Matrix:
    """X' = T⁻ᵀ·X·T⁻¹ (package congruence)."""
    x = sp.Matrix(x)
    return congruence(x, t_matrix(kind, x.rows))


def split(x):
    """Symbolic laplacian_split: grounded x_i = Σ_j X_ij and floating x_ij = −X_ij (i < j)."""
    x = sp.Matrix(x)
    n = x.rows
    grounded = [sp.simplify(sum(x.row(i))) for i in range(n)]
    floating = {(i + 1, j + 1): sp.simplify(-x[i, j]) for i in range(n) for j in range(i + 1, n)}
    return grounded, floating


def actuator_nodes(kind: str, k: int):
    """(node driven, node reacted) of actuator k: across nodes k−1 and k when serial."""
    return (k, k - 1) if kind == "serial" else (k, 0)


def sources(kind: str, currents):
    """One current source per actuator, carrying that actuator's force."""
    return [("I", *actuator_nodes(kind, k), i) for k, i in enumerate(currents, start=1)]


def stage_mass_matrix():
    """Two stages on one axis: stage 1 (mass d1) at x = q1, stage 2 (mass d2) at x = q1 + q2."""
    return point_mass_matrix([d1, d2], [sp.Matrix([q1]), sp.Matrix([q1 + q2])], [q1, q2])


def arm_positions(lengths, angles):
    """Planar serial arm: the distal end of every link."""
    x = y = a = 0
    out = []
    for length, q in zip(lengths, angles):
        a += q
        x += length * sp.cos(a)
        y += length * sp.sin(a)
        out.append(sp.Matrix([x, y]))
    return out


@lru_cache(maxsize=None)
def arm2_mass_matrix():
    """2-DOF arm: point mass d1 at the end of link 1 (distal actuator), d2 at the end effector."""
    return sp.ImmutableMatrix(point_mass_matrix([d1, d2], arm_positions([l1, l2], [q1, q2]), [q1, q2]))


def general_mass_matrix(n: int) -> sp.Matrix:
    """Eqs. (17) and (33): the general symmetric 2x2 and 3x3 forms m1..m6."""
    if n == 2:
        return sp.Matrix([[m1, m3], [m3, m2]])
    return sp.Matrix([[m1, m4, m5], [m4, m2, m6], [m5, m6, m3]])


# ------------------------------------------------------------ the machinery itself

@pytest.mark.parametrize("n", [2, 3, 6])
def test_symbolic_split_is_the_package_laplacian_split(n):
    """The symbolic split used below agrees with analogy.circuit.elements.laplacian_split."""
    rng = np.random.default_rng(n)
    a = rng.normal(size=(n, n))
    x = a @ a.T + n * np.eye(n)
    grounded, floating = split(sp.Matrix(x.tolist()))
    g_pkg, f_pkg = laplacian_split(x)
    np.testing.assert_allclose(np.array(grounded, dtype=float), g_pkg, rtol=1e-12)
    for (a_, b_), val in floating.items():
        assert float(val) == pytest.approx(f_pkg[a_ - 1, b_ - 1], rel=1e-12)


@pytest.mark.parametrize("n", [1, 2, 3, 5])
@pytest.mark.parametrize("kind", ["serial", "parallel"])
def test_nodal_analysis_of_split_elements_rebuilds_the_node_matrices(n, kind):
    """Grounded and floating elements of M' and B' give back C = M' and G = B' by nodal analysis,
    and one source per actuator injects T⁻ᵀ·i: power i·r = J·v is conserved."""
    mm = sp.Matrix(n, n, lambda i, j: sp.Symbol(f"x{min(i, j)}{max(i, j)}"))
    bb = sp.diag(*sp.symbols(f"b1:{n + 1}"))
    i = sp.Matrix(sp.symbols(f"i1:{n + 1}"))
    mp, bp = node_matrix(mm, kind), node_matrix(bb, kind)
    circuit = sources(kind, i)
    for element_kind, mat in (("C", mp), ("G", bp)):
        grounded, floating = split(mat)
        circuit += [(element_kind, k + 1, 0, val) for k, val in enumerate(grounded)]
        circuit += [(element_kind, a, b, val) for (a, b), val in floating.items()]
    nodal = nodal_analysis(circuit, n)
    t = t_matrix(kind, n)
    assert same(nodal.C, mp) and same(nodal.G, bp)
    assert same(nodal.J, t.inv().T * i)
    r = sp.Matrix(sp.symbols(f"r1:{n + 1}"))
    assert same(i.T * r, nodal.J.T * (t * r))


def test_nodal_analysis_reads_the_package_elements():
    """The package's element list of a node system (C in F, R in Ω, L in H) gives back its
    node matrices: C = M' and G = B'."""
    from analogy import scene
    from analogy.circuit.elements import elements
    system = scene("default").system()
    nodal = nodal_analysis(elements(system), system.dof)
    np.testing.assert_allclose(np.array(nodal.C, dtype=float), system.mass, rtol=1e-12)
    np.testing.assert_allclose(np.array(nodal.G, dtype=float), system.damping, rtol=1e-12)


@pytest.mark.parametrize("element", [("X", 1, 0, 1), ("C", 1, 1, 1), ("C", -1, 0, 1), ("C", 1)])
def test_nodal_analysis_rejects_malformed_elements(element):
    from analogy.errors import InputError
    with pytest.raises(InputError):
        nodal_analysis([element])


# ------------------------------------------------------ 3: redundant actuators (11)–(16)

def test_eq11_redundant_actuator_mass_matrix():
    """(11) M = [[m1, m2], [m2, m2]] holds, with m1 = d1 + d2 the whole mass actuator 1 moves
    and m2 = d2 the mass of stage 2 (not m1 = stage-1 mass: then M11 would be m1 + m2)."""
    derived = stage_mass_matrix()
    assert same(derived, redundant_actuators().mass_matrix.xreplace(
        {sp.Symbol(n, real=True): v for n, v in (("d1", d1), ("d2", d2), ("q1", q1), ("q2", q2))}))
    printed = sp.Matrix([[m1, m2], [m2, m2]])
    holds(printed.subs({m1: d1 + d2, m2: d2}), derived)
    assert not same(printed.subs({m1: d1, m2: d2}), derived)


def circuit_fig9():
    """Fig. 9: stage masses c1, c2 to ground; damper g1 across actuator 1, g2 across actuator 2."""
    return [("G", 1, 0, g1), ("G", 1, 2, g2), ("C", 1, 0, c1), ("C", 2, 0, c2)] \
        + sources("serial", [i1, i2])


def test_eq12_nodal_analysis_of_the_redundant_actuator_circuit():
    """(12) holds: J = [i1 − i2, i2] = T⁻ᵀ·i, G = [[g1 + g2, −g2], [−g2, g2]], C = diag(c1, c2)."""
    nodal = nodal_analysis(circuit_fig9())
    holds(sp.Matrix([i1 - i2, i2]), nodal.J)
    holds(sp.Matrix([i1 - i2, i2]), t_matrix("serial", 2).inv().T * sp.Matrix([i1, i2]))
    holds(sp.Matrix([[g1 + g2, -g2], [-g2, g2]]), nodal.G)
    holds(sp.diag(c1, c2), nodal.C)


@pytest.mark.parametrize("n", [2, 3])
def test_eq13_eq31_serial_dynamics_in_node_coordinates(n):
    """(13), (31) hold: T⁻ᵀ·(B·R + M·s·R) = B'·(T·R) + M'·s·(T·R), with left side
    [f1 − f2, …, fn] and node velocities [r1, r1 + r2, …] as printed."""
    r, f = sp.Matrix([r1, r2, r3][:n]), sp.Matrix([f1, f2, f3][:n])
    mm, bb = general_mass_matrix(n), sp.diag(*[b1, b2, b3][:n])
    t = t_matrix("serial", n)
    forces = bb * r + mm * s * r
    v = t * r
    holds(t.inv().T * forces, node_matrix(bb, "serial") * v + node_matrix(mm, "serial") * s * v)
    printed_v = {2: sp.Matrix([r1, r1 + r2]), 3: sp.Matrix([r1, r1 + r2, r1 + r2 + r3])}[n]
    printed_lhs = {2: sp.Matrix([f1 - f2, f2]), 3: sp.Matrix([f1 - f2, f2 - f3, f3])}[n]
    holds(printed_v, v)
    holds(printed_lhs, t.inv().T * f)


def test_eq14_redundant_actuator_node_damping():
    """(14) holds: B' = T⁻ᵀ·diag(b1, b2)·T⁻¹ = [[b1 + b2, −b2], [−b2, b2]], i.e. b'1 = b1 grounded at
    node 1 and b'2 = b2 floating between nodes 1 and 2; it is the G of (12) with g = b."""
    derived = node_matrix(sp.diag(b1, b2), "serial")
    holds(sp.Matrix([[b1 + b2, -b2], [-b2, b2]]), derived)
    grounded, floating = split(derived)
    bp1, bp2 = grounded[0], floating[(1, 2)]
    assert grounded[1] == 0
    holds(sp.Matrix([[bp1 + bp2, -bp2], [-bp2, bp2]]), derived)
    holds(nodal_analysis(circuit_fig9()).G.subs({g1: b1, g2: b2}), derived)


def test_eq15_redundant_actuator_node_mass_is_misprinted():
    """(15) misprint: M' = diag(m1 − m2, m2) = diag(d1, d2), not diag(m1 + m2, m2)."""
    derived = node_matrix(stage_mass_matrix(), "serial")
    holds(sp.diag(d1, d2), derived)
    in_m = derived.subs({d1: m1 - m2, d2: m2})          # (11): m1 = d1 + d2, m2 = d2
    holds(in_m, node_matrix(sp.Matrix([[m1, m2], [m2, m2]]), "serial"))
    misprint(sp.diag(m1 + m2, m2), sp.diag(m1 - m2, m2), in_m)


def test_eq16_redundant_actuator_element_values_are_misprinted():
    """(16) misprint: [b'1, b'2, m'1, m'2] = [b1, b2, m1 − m2, m2], not m'1 = m1 + m2."""
    bg, bf = split(node_matrix(sp.diag(b1, b2), "serial"))
    mg, mf = split(node_matrix(sp.Matrix([[m1, m2], [m2, m2]]), "serial"))
    assert mf[(1, 2)] == 0                               # no MP model: c1, c2 suffice
    derived = sp.Matrix([bg[0], bf[(1, 2)], mg[0], mg[1]])
    misprint(sp.Matrix([b1, b2, m1 + m2, m2]), sp.Matrix([b1, b2, m1 - m2, m2]), derived)


# ---------------------------------------------------------- 3.1: serial 2-DOF (17)–(23)

def test_eq17_serial_arm_mass_matrix_is_symmetric_2x2():
    """(17) holds: M(q) = Σ d·JᵀJ is symmetric, so it is [[m1, m3], [m3, m2]];
    planar_serial(2) derives the same matrix."""
    derived = arm2_mass_matrix()
    assert same(derived, derived.T)
    holds(general_mass_matrix(2).subs({m1: derived[0, 0], m2: derived[1, 1], m3: derived[0, 1]}),
          derived)
    pkg = planar_serial(2).mass_matrix.xreplace(
        {sp.Symbol(str(x), real=True): x for x in (q1, q2, l1, l2, d1, d2)})
    holds(pkg, derived)


@pytest.mark.parametrize("eq, entry, printed", [
    (18, (0, 0), l2**2 * d2 + 2 * l1 * l2 * d2 * sp.cos(q2) + l1**2 * (d1 + d2)),
    (19, (1, 1), l2**2 * d2),
    (20, (0, 1), l2**2 * d2 + l1 * l2 * d2 * sp.cos(q2)),
], ids=["eq18_m1", "eq19_m2", "eq20_m3"])
def test_eq18_to_eq20_serial_arm_mass_entries(eq, entry, printed):
    """(18)–(20) hold: the entries of Σ d·JᵀJ for point masses d1 at the elbow and d2 at the tip."""
    holds(printed, arm2_mass_matrix()[entry])


def circuit_fig11():
    """Fig. 11: Fig. 9 plus the floating capacitor c12 between nodes 1 and 2."""
    return circuit_fig9() + [("C", 1, 2, c12)]


def test_eq21_nodal_analysis_of_the_serial_arm_circuit():
    """(21) holds: J = [i1 − i2, i2], G as in (12), C = [[c1 + c12, −c12], [−c12, c2 + c12]]."""
    nodal = nodal_analysis(circuit_fig11())
    holds(sp.Matrix([i1 - i2, i2]), nodal.J)
    holds(sp.Matrix([[g1 + g2, -g2], [-g2, g2]]), nodal.G)
    holds(sp.Matrix([[c1 + c12, -c12], [-c12, c2 + c12]]), nodal.C)


def test_eq22_serial_arm_node_mass_matrix_is_misprinted():
    """(22) left form holds; right form misprint: M'11 = m1 + m2 − 2·m3, not m1 + m2."""
    derived = node_matrix(general_mass_matrix(2), "serial")
    (mp1, mp2), floating = split(derived)
    p12 = floating[(1, 2)]
    holds(sp.Matrix([[mp1 + p12, -p12], [-p12, mp2 + p12]]), derived)
    misprint(sp.Matrix([[m1 + m2, m3 - m2], [m3 - m2, m2]]),
             sp.Matrix([[m1 + m2 - 2 * m3, m3 - m2], [m3 - m2, m2]]), derived)


def test_eq23_serial_arm_element_values_are_misprinted():
    """(23) misprint: [m'1, m'2, p'12] = [m1 − m3, m3, m2 − m3], not m'1 = m1 + m3."""
    (mp1, mp2), floating = split(node_matrix(general_mass_matrix(2), "serial"))
    derived = sp.Matrix([mp1, mp2, floating[(1, 2)]])
    misprint(sp.Matrix([m1 + m3, m3, m2 - m3]), sp.Matrix([m1 - m3, m3, m2 - m3]), derived)
    # In the arm's own terms: c1 = l1²(d1 + d2) + l1·l2·d2·cos q2, c2 = l2·d2(l2 + l1 cos q2).
    m = arm2_mass_matrix()
    holds(derived.subs({m1: m[0, 0], m2: m[1, 1], m3: m[0, 1]}),
          sp.Matrix([l1**2 * (d1 + d2) + l1 * l2 * d2 * sp.cos(q2),
                     l2 * d2 * (l2 + l1 * sp.cos(q2)),
                     -l1 * l2 * d2 * sp.cos(q2)]))


def test_misprints_15_16_22_23_share_one_dropped_cross_term():
    """The printed M'11 of (15) and (22) is M11 + M22: the derived M11 − 2·M12 + M22 without −2·M12.
    The printed m'1 of (16) and (23) is the row sum of that wrong M'11 with the right M'12."""
    for mm, printed_mp11, printed_m1 in ((sp.Matrix([[m1, m2], [m2, m2]]), m1 + m2, m1 + m2),
                                         (general_mass_matrix(2), m1 + m2, m1 + m3)):
        derived = node_matrix(mm, "serial")
        holds(printed_mp11, derived[0, 0] + 2 * mm[0, 1])
        holds(printed_m1, printed_mp11 + derived[0, 1])


# -------------------------------------------------------------- text claims of 3, 3.1, 3.2

def test_claim_redundant_actuator_node_mass_is_diagonal():
    """Text after (16): for the redundant actuators M' is diagonal (no MP model needed): holds."""
    derived = node_matrix(stage_mass_matrix(), "serial")
    assert derived[0, 1] == 0


def test_claim_end_point_velocity_is_node_2():
    """Text after (12): v2 is the end-point velocity r1 + r2: holds."""
    holds(t_matrix("serial", 2) * sp.Matrix([r1, r2]), sp.Matrix([r1, r1 + r2]))


def test_claim_p12_vanishes_iff_m2_equals_m3_iff_q2_is_plus_minus_half_pi():
    """Text after (23): p'12 = 0 exactly when m2 = m3, i.e. when q2 = ±π/2: holds."""
    _, floating = split(node_matrix(general_mass_matrix(2), "serial"))
    p12 = floating[(1, 2)]
    assert sp.solve(p12, m2) == [m3]
    m = arm2_mass_matrix()
    p12_arm = sp.simplify(p12.subs({m1: m[0, 0], m2: m[1, 1], m3: m[0, 1]}))
    holds(p12_arm, -l1 * l2 * d2 * sp.cos(q2))
    zeros = sp.solveset(p12_arm, q2, sp.Interval.Lopen(-sp.pi, sp.pi))
    assert zeros == sp.FiniteSet(-sp.pi / 2, sp.pi / 2)


def test_claim_p12_negative_for_q2_between_minus_and_plus_half_pi():
    """Text after Fig. 12: p'12 < 0 exactly when −π/2 < q2 < π/2 (for q2 in (−π, π]): holds.
    p'12 is continuous in q2 and vanishes only at ±π/2, so one sample fixes its sign on each piece."""
    m = arm2_mass_matrix()
    _, floating = split(node_matrix(m, "serial"))
    p12 = floating[(1, 2)]
    # solveset/solve_univariate_inequality return [0, π/2) for cos(q2) > 0 on (−π, π] in
    # sympy 1.14, so the sign is fixed from the zeros instead.
    assert sp.solveset(p12, q2, sp.Interval.Lopen(-sp.pi, sp.pi)) == sp.FiniteSet(-sp.pi / 2, sp.pi / 2)
    assert p12.subs(q2, 0).is_negative
    assert p12.subs(q2, -3 * sp.pi / 4).is_positive and p12.subs(q2, sp.pi).is_positive


def test_claim_net_mass_perceived_is_positive():
    """Text after Fig. 12: M' stays positive definite although p'12 may be negative: holds.
    M'11 = l1²(d1 + d2) and det M' = det M = l1²·l2²·d2·(d1 + d2·sin² q2)."""
    mp = node_matrix(arm2_mass_matrix(), "serial")
    holds(mp[0, 0], l1**2 * (d1 + d2))
    det = sp.factor(sp.trigsimp(mp.det()))
    holds(det, l1**2 * l2**2 * d2 * (d1 + d2 * sp.sin(q2)**2))
    assert mp[0, 0].is_positive and det.is_positive


def test_claim_serial_arm_node_damping_is_that_of_eq14_but_not_diagonal():
    """Text before Fig. 11 ("B' is the same diagonal matrix as in (14)"): the same matrix as (14)
    holds; "diagonal" does not: B is diagonal, B' has −b2 off the diagonal."""
    derived = node_matrix(sp.diag(b1, b2), "serial")
    holds(sp.Matrix([[b1 + b2, -b2], [-b2, b2]]), derived)
    assert not derived.is_diagonal()


def test_claim_parallel_node_matrices_are_the_joint_matrices():
    """Text before (24): for a parallel robot B' = B and M' = M: holds (T = I)."""
    mm, bb = general_mass_matrix(3), sp.Matrix(3, 3, lambda i, j: sp.Symbol(f"b{min(i, j)}{max(i, j)}"))
    holds(node_matrix(mm, "parallel"), mm)
    holds(node_matrix(bb, "parallel"), bb)


# --------------------------------------------------------- 3.2: parallel 2-DOF (24)–(26)

def test_eq24_nodal_analysis_of_the_parallel_circuit():
    """(24) holds: grounded sources and dampers give J = [i1, i2], G = diag(g1, g2) and
    C = [[c1 + c12, −c12], [−c12, c2 + c12]]."""
    circuit = [("G", 1, 0, g1), ("G", 2, 0, g2), ("C", 1, 0, c1), ("C", 2, 0, c2),
               ("C", 1, 2, c12)] + sources("parallel", [i1, i2])
    nodal = nodal_analysis(circuit)
    holds(sp.Matrix([i1, i2]), nodal.J)
    holds(sp.diag(g1, g2), nodal.G)
    holds(sp.Matrix([[c1 + c12, -c12], [-c12, c2 + c12]]), nodal.C)


def test_eq25_parallel_dynamics_in_element_form():
    """(25) holds: F = diag(b'1, b'2)·R + [[m'1 + p'12, −p'12], [−p'12, m'2 + p'12]]·s·R with
    b' = b and m', p' the split of M' = M."""
    r, f_lhs = sp.Matrix([r1, r2]), sp.Matrix([f1, f2])
    mm, bb = general_mass_matrix(2), sp.diag(b1, b2)
    t = t_matrix("parallel", 2)
    bp, mp = node_matrix(bb, "parallel"), node_matrix(mm, "parallel")
    (mp1, mp2), floating = split(mp)
    p12 = floating[(1, 2)]
    printed_rhs = sp.diag(b1, b2) * r + sp.Matrix([[mp1 + p12, -p12], [-p12, mp2 + p12]]) * s * r
    holds(printed_rhs, bp * (t * r) + mp * s * (t * r))
    holds(printed_rhs, bb * r + mm * s * r)
    holds(f_lhs, t.inv().T * f_lhs)


def test_eq26_parallel_2dof_element_values():
    """(26) holds: [m'1, m'2, p'12] = [m1 + m3, m2 + m3, −m3]."""
    (mp1, mp2), floating = split(node_matrix(general_mass_matrix(2), "parallel"))
    holds(sp.Matrix([m1 + m3, m2 + m3, -m3]), sp.Matrix([mp1, mp2, floating[(1, 2)]]))


# ------------------------------------------------------------- 3.3: n-DOF (27)–(35)

def joint_matrix_of_actuator_elements(kind: str, element_kind: str, values):
    """One element per actuator, placed across it; nodal matrix X then joint matrix Tᵀ·X·T."""
    n = len(values)
    circuit = [(element_kind, *actuator_nodes(kind, k), val) for k, val in enumerate(values, 1)]
    nodal = nodal_analysis(circuit, n)
    x = nodal.G if element_kind == "G" else nodal.Gamma
    t = t_matrix(kind, n)
    return t.T * x * t


@pytest.mark.parametrize("n", [2, 3, 5])
@pytest.mark.parametrize("kind", ["serial", "parallel"])
def test_eq27_actuator_damping_is_diagonal(kind, n):
    """(27) holds: a damper b_k across each actuator (conductance g_k = b_k) gives B = diag(b1 … bn)."""
    b = sp.symbols(f"b1:{n + 1}", positive=True)
    holds(sp.diag(*b), joint_matrix_of_actuator_elements(kind, "G", b))


@pytest.mark.parametrize("n", [2, 3, 5])
@pytest.mark.parametrize("kind", ["serial", "parallel"])
def test_eq28_actuator_stiffness_is_misprinted(kind, n):
    """(28) misprint: a spring k_k across each actuator is an inductor L_k = 1/k_k (Fig. 1, eq. 2),
    so K = diag(k1 … kn); diag(1/k1 … 1/kn) is the inductance (compliance) matrix."""
    k = sp.symbols(f"k1:{n + 1}", positive=True)
    # Eq. (2): V = F·s/K, i.e. F = K·V/s; an inductor carries I = E/(s·L). Equal for K = 1/L.
    spring_k, inductance = sp.symbols("K L", positive=True)
    solved = sp.solve(sp.Eq(spring_k * v1 / s, v1 / (s * inductance)), inductance)
    assert solved == [1 / spring_k]
    derived = joint_matrix_of_actuator_elements(kind, "L", [1 / kk for kk in k])
    misprint(sp.diag(*[1 / kk for kk in k]), sp.diag(*k), derived)


def circuit_fig14():
    """Fig. 14 (serial 3-DOF): a damper across each actuator, c_i to ground and c_ij between nodes."""
    return [("G", 1, 0, g1), ("G", 1, 2, g2), ("G", 2, 3, g3),
            ("C", 1, 0, c1), ("C", 2, 0, c2), ("C", 3, 0, c3),
            ("C", 1, 2, c12), ("C", 1, 3, c13), ("C", 2, 3, c23)] + sources("serial", [i1, i2, i3])


def test_eq29_nodal_analysis_of_the_serial_3dof_circuit():
    """(29) holds: J = [i1 − i2, i2 − i3, i3] = T⁻ᵀ·i, and G(q) = T⁻ᵀ·diag(g)·T⁻¹."""
    nodal = nodal_analysis(circuit_fig14())
    holds(sp.Matrix([i1 - i2, i2 - i3, i3]), nodal.J)
    holds(nodal.J, t_matrix("serial", 3).inv().T * sp.Matrix([i1, i2, i3]))
    holds(nodal.G, node_matrix(sp.diag(g1, g2, g3), "serial"))
    v = sp.Matrix([v1, v2, v3])
    holds(nodal.currents(v, s), nodal.G * v + nodal.C * s * v)


def test_eq30_capacitance_matrix_of_the_3dof_circuit():
    """(30) holds: C_ii = c_i + Σ_j c_ij, C_ij = −c_ij."""
    printed = sp.Matrix([[c1 + c12 + c13, -c12, -c13],
                         [-c12, c2 + c12 + c23, -c23],
                         [-c13, -c23, c3 + c23 + c13]])
    holds(printed, nodal_analysis(circuit_fig14()).C)


# (31) is checked with (13) above: test_eq13_eq31_serial_dynamics_in_node_coordinates[3].


@pytest.mark.parametrize("kind", ["serial", "parallel"])
def test_eq32_node_mass_matrix_in_element_form(kind):
    """(32) holds: with m'_i the row sums and p'_ij = −M'_ij, M' is
    [[m'1 + p'12 + p'13, −p'12, −p'13], [−p'12, m'2 + p'12 + p'23, −p'23], [−p'13, −p'23, m'3 + p'13 + p'23]],
    and it is the C of (30) for c_i = m'_i, c_ij = p'_ij."""
    mp = node_matrix(general_mass_matrix(3), kind)
    (a1, a2, a3), p = split(mp)
    p12, p13, p23 = p[(1, 2)], p[(1, 3)], p[(2, 3)]
    printed = sp.Matrix([[a1 + p12 + p13, -p12, -p13],
                         [-p12, a2 + p12 + p23, -p23],
                         [-p13, -p23, a3 + p13 + p23]])
    holds(printed, mp)
    values = {c1: a1, c2: a2, c3: a3, c12: p12, c13: p13, c23: p23}
    holds(nodal_analysis(circuit_fig14()).C.subs(values), mp)


def test_eq33_mass_matrix_of_a_3dof_arm_is_symmetric_3x3():
    """(33) holds: M = Σ d·JᵀJ of a planar 3R arm is symmetric, so it is the six-entry form
    [[m1, m4, m5], [m4, m2, m6], [m5, m6, m3]], with six different entries."""
    lengths = [1, sp.Rational(4, 5), sp.Rational(1, 2)]
    m = point_mass_matrix([d1, d2, d3], arm_positions(lengths, [q1, q2, q3]), [q1, q2, q3])
    assert same(m, m.T)
    entries = {m1: m[0, 0], m2: m[1, 1], m3: m[2, 2], m4: m[0, 1], m5: m[0, 2], m6: m[1, 2]}
    holds(general_mass_matrix(3).subs(entries), m)
    assert len({sp.simplify(e) for e in entries.values()}) == 6


def test_eq34_serial_3dof_element_values():
    """(34) holds: [m'1, m'2, m'3, p'12, p'23, p'13] =
    [m1 − m4, m4 − m5, m5, m2 + m5 − m4 − m6, m3 − m6, m6 − m5]; for three stacked stages the MP
    models vanish and m'_k is stage k's mass."""
    (a1, a2, a3), p = split(node_matrix(general_mass_matrix(3), "serial"))
    derived = sp.Matrix([a1, a2, a3, p[(1, 2)], p[(2, 3)], p[(1, 3)]])
    printed = sp.Matrix([m1 - m4, m4 - m5, m5, m2 + m5 - m4 - m6, m3 - m6, m6 - m5])
    holds(printed, derived)
    stack = point_mass_matrix([d1, d2, d3], [sp.Matrix([q1]), sp.Matrix([q1 + q2]),
                                             sp.Matrix([q1 + q2 + q3])], [q1, q2, q3])
    entries = {m1: stack[0, 0], m2: stack[1, 1], m3: stack[2, 2],
               m4: stack[0, 1], m5: stack[0, 2], m6: stack[1, 2]}
    holds(printed.subs(entries), sp.Matrix([d1, d2, d3, 0, 0, 0]))


PRINTED_35 = sp.Matrix([m1 + m4 + m6, m2 + m4 + m6, m3 + m5 + m6, -m4, -m5, -m6])


def parallel_3dof_elements(mm):
    (a1, a2, a3), p = split(node_matrix(mm, "parallel"))
    return sp.Matrix([a1, a2, a3, p[(1, 2)], p[(2, 3)], p[(1, 3)]])


def test_eq35_parallel_3dof_element_values_are_misprinted():
    """(35) misprint: [m'1, m'2, m'3, p'12, p'23, p'13] = [m1 + m4 + m5, m2 + m4 + m6, m3 + m5 + m6,
    −m4, −m6, −m5]; printed m'1 = m1 + m4 + m6, p'23 = −m5 and p'13 = −m6 are wrong."""
    derived = parallel_3dof_elements(general_mass_matrix(3))
    corrected = sp.Matrix([m1 + m4 + m5, m2 + m4 + m6, m3 + m5 + m6, -m4, -m6, -m5])
    misprint(PRINTED_35, corrected, derived)
    wrong_rows = [k for k in range(6) if not same(PRINTED_35[k], derived[k])]
    assert wrong_rows == [0, 4, 5]


def test_eq35_misprint_is_not_a_labelling_convention():
    """No assignment of m4, m5, m6 to the off-diagonal entries (12), (13), (23) makes (35) hold;
    swapping m5 and m6 leaves only m'2 wrong."""
    wrong = {}
    for a, b, c in permutations([m4, m5, m6]):
        mm = sp.Matrix([[m1, a, b], [a, m2, c], [b, c, m3]])
        derived = parallel_3dof_elements(mm)
        wrong[(a, b, c)] = [k for k in range(6) if not same(PRINTED_35[k], derived[k])]
    assert all(rows for rows in wrong.values())
    assert wrong[(m4, m6, m5)] == [1]
