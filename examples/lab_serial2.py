# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: the 2-DOF serial arm (paper eqs. 17-23, Figs. 10-12) and its configuration-dependent MP model
#
# Run as a script with `python examples/lab_serial2.py [output-folder]`, or open it as a
# notebook (see examples/README.md).
#
# **Physics.** A planar arm with two revolute joints carries a point mass d1 at the
# elbow and d2 at the tip (links l1, l2). Its kinetic energy T = ½·rᵀ M(q) r
# defines the mass matrix M(q); the joints have dampers b1, b2. In the serial
# topology the circuit's node voltages are the absolute angular velocities of the
# links, v1 = r1 and v2 = r1 + r2 (v = T r), and actuator 2 acts between the two
# links, so it is a current source between n1 and n2. The node mass matrix is
# M' = T⁻ᵀ M T⁻¹. Each node gets a grounded capacitor m'_i (row sum of M': a
# mass) and the pair gets a floating capacitor p'12 = -M'12: an MP model, the
# mass/pulley device of Fig. 5 whose mass is driven by the difference v2 - v1.
#
# **Steps**
#
# 1. Print M(q) symbolically, derive M'(q) and the element values symbolically.
#    (The paper prints M'11 = m1 + m2 and m'1 = m1 + m3 in eqs. 22-23; the
#    derivation below gives M'11 = m1 + m2 - 2 m3 and m'1 = m1 - m3.)
# 2. Evaluate at the scene's pose q2 = 0.3 rad, print M' and the circuit elements.
# 3. Simulate the circuit in ngspice and check it against the ODE and exact
#    solutions (step torque on joint 1, sine torque on joint 2, r2(0) = 0.2 rad/s).
# 4. Draw the circuit and the mechanism.
# 5. Sweep q2 over a full turn: p'12 = -l1 l2 d2 cos(q2) is negative for
#    |q2| < π/2, zero at ±π/2 (the paper's M' diagonal case) and positive beyond.

# %%
import _lab
import numpy as np
import sympy as sp

import analogy

out = _lab.output_folder()

# %% [markdown]
# ## 1. Symbolic model: M(q) comes from the kinematics, M = sum d_k J_kᵀ J_k

# %%
scene = analogy.scene("serial2")
model = scene.build_model()
system = scene.system(model)
_lab.section("mass matrix M(q), derived from the kinematics")
_lab.print_symbolic("M", model.mass_matrix)

node_mass = _lab.symbolic_node_matrix(model.mass_matrix, system)
_lab.print_symbolic("M'", node_mass)
grounded, floating = _lab.symbolic_split(node_mass)
for name, expr in {**grounded, **floating}.items():
    print(f"   {name} = {expr}")

q2, l1, l2, d1, d2 = sp.symbols("q2 l1 l2 d1 d2", real=True)
# M'11 is what node 1 feels when link 2 does not rotate (v2 = 0): then the tip mass
# only translates with the elbow, so M'11 = l1^2 (d1 + d2), whatever q2 is.
assert sp.simplify(node_mass[0, 0] - l1**2 * (d1 + d2)) == 0
assert sp.simplify(floating["p'1_2"] + l1 * l2 * d2 * sp.cos(q2)) == 0

# The same split for a general symmetric M = [[m1, m3], [m3, m2]] (the paper's labels):
# m'1 = m1 - m3, m'2 = m3, p'12 = m2 - m3. The paper's eq. 23 prints m'1 = m1 + m3.
general = _lab.paper_mass_matrix(2)
m1, m2, m3 = sorted(general.free_symbols, key=str)
g_ground, g_float = _lab.symbolic_split(_lab.symbolic_node_matrix(general, system))
assert [g_ground["m'1"], g_ground["m'2"], g_float["p'1_2"]] == [m1 - m3, m3, m2 - m3]
assert sp.simplify(g_ground["m'1"] - (m1 + m3)) != 0, "eq. 23's m'1 = m1 + m3 is a misprint"
print("general M: m'1 =", g_ground["m'1"], " m'2 =", g_ground["m'2"], " p'12 =", g_float["p'1_2"])

# %% [markdown]
# ## 2. Numbers at the scene's pose

# %%
_lab.section(f"node system at q = {scene.q} rad (serial topology, v = T r)")
_lab.print_matrix("M(q)", system.joint.mass_matrix)
_lab.print_matrix("M' = T^-T M T^-1", system.mass)
_lab.print_elements(system)

# %% [markdown]
# ## 3. Three solvers, one answer

# %%
_lab.section("SPICE vs ODE vs exact (accurate preset)")
_lab.check_solvers(system, out, "serial2")

# %% [markdown]
# ## 4. Circuit and mechanism side by side: same topology, element for element

# %%
_lab.draw_diagrams(system, out, "serial2")

# %% [markdown]
# ## 5. Sweep q2 through the package (numbers), and compare with the symbolic formulas

# %%
_lab.section("sweep q2")
q2_values = np.linspace(-np.pi, np.pi, 121)
x, mats, skipped = _lab.sweep(scene, model, 1, q2_values)
assert not skipped, "an open chain assembles at every pose"
m_ground, p_float = _lab.split(mats)
p12 = p_float[0, 1]

values = model.parameters
formula = sp.lambdify(q2, floating["p'1_2"].subs({model.symbols[k]: v for k, v in values.items()}))
assert np.allclose(p12, formula(x), rtol=0, atol=1e-12), "numeric sweep disagrees with the formula"
assert np.allclose(mats[:, 0, 0], values["l1"] ** 2 * (values["d1"] + values["d2"]), rtol=1e-12)

# The MP capacitance changes sign exactly at q2 = +-pi/2 ...
inside = np.abs(x) < np.pi / 2 - 1e-9
outside = np.abs(x) > np.pi / 2 + 1e-9
assert np.all(p12[inside] < 0) and np.all(p12[outside] > 0)
for edge in (-np.pi / 2, np.pi / 2):
    m_edge = scene.replace(q=(0.0, edge)).system(model).mass
    assert abs(m_edge[0, 1]) <= 1e-12 * np.abs(m_edge).max(), "M' is diagonal at q2 = +-pi/2"
# ... the grounded m'2 = d2 l2 (l2 + l1 cos q2) turns negative when the arm folds back
# far enough (cos q2 < -l2/l1), yet M' stays positive definite: the arm is passive.
assert np.any(m_ground[:, 1] < 0)
assert np.all(np.linalg.eigvalsh(mats)[:, 0] > 0)
print(f"p'12 < 0 for |q2| < pi/2 and > 0 beyond; m'2 < 0 for |q2| > "
      f"{np.arccos(-values['l2'] / values['l1']):.4f} rad; M' positive definite at all {x.size} poses")

fig, axes = _lab.figure(size=(7, 4.2))
ax = axes[0, 0]
for k, edge in enumerate((-np.pi / 2, np.pi / 2)):
    ax.axvline(edge, color="C3", ls=":", lw=0.8, label=None if k else "q2 = ±π/2 (p'12 = 0)")
_lab.plot_sweep(ax, x, {
    "m'1 (grounded C1: mass)": (m_ground[:, 0], dict(color="C0")),
    "m'2 (grounded C2: mass)": (m_ground[:, 1], dict(color="C1")),
    "p'12 (floating C1_2: MP model)": (p12, dict(color="C3", lw=2)),
    "M'11 = m'1 + p'12 = l1²·(d1 + d2)": (mats[:, 0, 0], dict(color="k", ls=":")),
}, xlabel="q2 [rad]", title="2-DOF serial arm: element values over the elbow angle",
    here=scene.q[1])
ax.set_xticks(np.linspace(-np.pi, np.pi, 5), ["−π", "−π/2", "0", "π/2", "π"])
_lab.save(fig, out / "serial2_sweep.png")

# %% [markdown]
# ## 6. Turn the elbow yourself: the element values follow the pose
#
# In a notebook, drag the slider: the bars are the circuit's capacitances at that elbow angle
# (red where negative). The floating C1_2 = p'12 = −l1·l2·d2·cos q2 goes through zero at
# q2 = ±π/2 and comes back positive past it; the grounded C1 = M'11 − C1_2 moves the other way,
# so M'11 = C1 + C1_2 stays l1²·(d1 + d2). Run as a script, the cell draws two poses instead.

# %%
def capacitances_at(q2: float):
    """The capacitors of the circuit at elbow angle q2, and a bar chart of them."""
    at = scene.replace(q=(0.0, float(q2))).system(model)
    parts = [e for e in analogy.elements(at) if e.kind == "C"]
    fig, axes = _lab.figure(size=(6.5, 3.2))
    ax = axes[0, 0]
    ax.bar([e.name for e in parts], [e.value for e in parts],
           color=["C3" if e.value < 0 else "C0" for e in parts])
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_ylim(-1.2, 4.0)
    ax.set_ylabel(_lab.MASS_AXIS)
    mp = next(e for e in parts if e.floating)
    ax.set_title(f"q2 = {q2:.2f} rad: the MP capacitance {mp.name} = {mp.value:+.3f} F")
    return parts, fig


near, _ = capacitances_at(0.3)
folded, _ = capacitances_at(2.0)
c12 = {name: next(e.value for e in parts if e.floating) for name, parts in (("near", near), ("folded", folded))}
print(f"C1_2 at q2 = 0.3 rad: {c12['near']:+.4f} F; at q2 = 2.0 rad: {c12['folded']:+.4f} F")
assert c12["near"] < 0 < c12["folded"], "the MP capacitance changes sign past q2 = pi/2"
if _lab.in_notebook():
    import ipywidgets
    ipywidgets.interact(lambda q2: _lab.display_figure(capacitances_at(q2)[1]),
                        q2=ipywidgets.FloatSlider(value=0.3, min=-np.pi, max=np.pi, step=0.05,
                                                  description="q2 [rad]"))
