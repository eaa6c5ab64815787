# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: the 3-DOF planar serial arm (paper eqs. 29-34, Fig. 14): three MP models
#
# Run as a script with `python examples/lab_serial3.py [output-folder]`, or open it as a
# notebook (see examples/README.md).
#
# **Physics.** Three revolute joints in a chain, point masses d_k at the end of link k
# (lengths l_k), joint dampers b_k. In the serial topology node k carries the
# absolute angular velocity of link k, v_k = r_1 + ... + r_k, and actuator k acts
# between links k-1 and k. The node mass matrix M' = T⁻ᵀ M T⁻¹ turns out much
# simpler than M: M'_kk = l_k² (mass carried beyond joint k) and each
# off-diagonal entry couples two links only through the angle between them. So
# every pair of links gets its own MP model:
#
#     p'1_2 = -l1 l2 (d2 + d3) cos(q2)      (links 1 and 2: angle q2)
#     p'2_3 = -l2 l3 d3 cos(q3)             (links 2 and 3: angle q3)
#     p'1_3 = -l1 l3 d3 cos(q2 + q3)        (links 1 and 3: angle q2 + q3)
#
# The lab derives these, it does not assume them.
#
# **Steps**
#
# 1. Print M(q) symbolically; derive M'(q) and the six element values.
# 2. Evaluate at q = (0, 0.4, -0.7) rad, print M' and the circuit elements.
# 3. Simulate in ngspice; check against the ODE and exact solutions.
# 4. Draw the circuit and the mechanism.
# 5. Sweep q2 (q3 fixed) and q3 (q2 fixed): each MP capacitance changes sign where
#    the angle between its two links passes ±π/2, and is constant when that
#    angle does not change.

# %%
import _lab
import numpy as np
import sympy as sp

import analogy

out = _lab.output_folder()

# %% [markdown]
# ## 1. Symbolic model and node matrix

# %%
scene = analogy.scene("serial3")
model = scene.build_model()
system = scene.system(model)
_lab.section("mass matrix M(q), derived from the kinematics")
_lab.print_symbolic("M", model.mass_matrix)
node_mass = _lab.symbolic_node_matrix(model.mass_matrix, system)
_lab.print_symbolic("M'", node_mass)
grounded, floating = _lab.symbolic_split(node_mass)
for name, expr in {**grounded, **floating}.items():
    print(f"   {name} = {expr}")

q1, q2, q3 = model.coordinates
l1, l2, l3, d1, d2, d3 = (model.symbols[k] for k in ("l1", "l2", "l3", "d1", "d2", "d3"))
expected = {"p'1_2": -l1 * l2 * (d2 + d3) * sp.cos(q2),
            "p'2_3": -l2 * l3 * d3 * sp.cos(q3),
            "p'1_3": -l1 * l3 * d3 * sp.cos(q2 + q3)}
for name, expr in expected.items():
    assert sp.simplify(floating[name] - expr) == 0, name
for k, beyond in enumerate((d1 + d2 + d3, d2 + d3, d3)):
    assert sp.simplify(node_mass[k, k] - (l1, l2, l3)[k] ** 2 * beyond) == 0

# The same split for a general symmetric M in the paper's labels (m4 = M12, m5 = M13,
# m6 = M23) reproduces the paper's eq. 34 for the serial topology.
general = _lab.paper_mass_matrix(3)
m1, m2, m3, m4, m5, m6 = sorted(general.free_symbols, key=str)
g_ground, g_float = _lab.symbolic_split(_lab.symbolic_node_matrix(general, system))
derived = [*g_ground.values(), g_float["p'1_2"], g_float["p'2_3"], g_float["p'1_3"]]
eq34 = [m1 - m4, m4 - m5, m5, m2 + m5 - m4 - m6, m3 - m6, m6 - m5]
assert all(sp.simplify(a - b) == 0 for a, b in zip(derived, eq34))
print("eq. 34 [m'1, m'2, m'3, p'12, p'23, p'13] =", derived, "(holds)")

# %% [markdown]
# ## 2. Numbers at the scene's pose

# %%
_lab.section(f"node system at q = {scene.q} rad (serial topology)")
_lab.print_matrix("M(q)", system.joint.mass_matrix)
_lab.print_matrix("M' = T^-T M T^-1", system.mass)
_lab.print_elements(system)

# %% [markdown]
# ## 3. Three solvers

# %%
_lab.section("SPICE vs ODE vs exact (accurate preset)")
_lab.check_solvers(system, out, "serial3")

# %% [markdown]
# ## 4. Diagrams

# %%
_lab.draw_diagrams(system, out, "serial3")

# %% [markdown]
# ## 5. Sweeps of q2 and of q3, through the package, checked against the formulas

# %%
_lab.section("sweep q2 and q3")
numbers = {model.symbols[k]: v for k, v in model.parameters.items()}
formulas = {name: sp.lambdify((q2, q3), expr.subs(numbers)) for name, expr in expected.items()}
pairs = {"p'1_2": (0, 1), "p'2_3": (1, 2), "p'1_3": (0, 2)}
angles = np.linspace(-np.pi, np.pi, 73)
fig, axes = _lab.figure(2, 1, size=(9, 7.5))
for joint, ax in zip((1, 2), axes[:, 0]):
    x, mats, skipped = _lab.sweep(scene, model, joint, angles)
    assert not skipped, "an open chain assembles at every pose"
    _, p = _lab.split(mats)
    qq = np.array([scene.q[1], scene.q[2]])[:, None] * np.ones_like(x)
    qq[joint - 1] = x
    for name, (i, j) in pairs.items():
        assert np.allclose(p[i, j], formulas[name](*qq), rtol=0, atol=1e-12), name
    # The MP model across a pair of links sees only the angle between them.
    if joint == 1:
        assert np.ptp(p[1, 2]) <= 1e-12, "p'2_3 depends on q3 only"
        crossings = [-np.pi / 2 - scene.q[2], np.pi / 2 - scene.q[2]]   # q2 + q3 = -+pi/2
    else:
        assert np.ptp(p[0, 1]) <= 1e-12, "p'1_2 depends on q2 only"
        crossings = [-np.pi / 2 - scene.q[1], np.pi / 2 - scene.q[1]]
    for c in crossings:
        q = list(scene.q)
        q[joint] = c
        assert abs(scene.replace(q=tuple(q)).system(model).mass[0, 2]) <= 1e-12, "p'1_3 = 0 there"
    assert np.all(np.linalg.eigvalsh(mats)[:, 0] > 0), "M' is positive definite"
    for k, c in enumerate(crossings):
        ax.axvline(c, color="C2", ls=":", lw=0.8, label=None if k else "q2 + q3 = ±π/2")
    _lab.plot_sweep(ax, x, {
        "p'1_2 (C1_2, links 1-2)": (p[0, 1], dict(color="C0")),
        "p'2_3 (C2_3, links 2-3)": (p[1, 2], dict(color="C1")),
        "p'1_3 (C1_3, links 1-3)": (p[0, 2], dict(color="C2")),
    }, xlabel=f"q{joint + 1} [rad]", here=scene.q[joint],
        title=f"MP capacitances over q{joint + 1} (other joints at the scene pose)")
print("each MP capacitance depends only on the angle between its two links; "
      "p'1_3 vanishes where q2 + q3 = +-pi/2")
_lab.save(fig, out / "serial3_sweep.png")
