# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: the 3-DOF planar 3-RRR parallel mechanism (paper eq. 35): three MP models and three springs
#
# Run as a script with `python examples/lab_parallel3.py [output-folder]`, or open it as a
# notebook (see examples/README.md).
#
# **Physics.** Three motors sit on the base at 120 degree spacing; each turns a
# proximal link (angle q_k), and a passive distal link carries a triangular
# platform (position x, y, orientation phi). The motors are grounded, so the
# parallel topology v = r applies: M' = M, B' = B, K' = K. Each motor has a
# damper b_k (a grounded resistor R = 1/b_k) and a return spring k_k (a grounded
# inductor L = 1/k_k). The platform couples all three motors: every off-diagonal
# M_ij becomes an MP model p'_ij = -M_ij between nodes i and j, and every node
# gets the grounded capacitor m'_i = sum_j M_ij. (The paper's eq. 35 mixes up
# M13 and M23 in m'1, p'23 and p'13; the split used here follows from the
# nodal equations, C_ii = c_i + sum_j c_ij and C_ij = -c_ij.)
#
# M(q) = Sᵀ M_theta S as for the five-bar: the passive coordinates
# p = (psi_1, psi_2, psi_3, x, y, phi) follow from the loop-closure equations,
# and their rates G = dp/dq enter M.
#
# **Steps**
#
# 1. Print M(q) symbolically (in q, p and the rates dp/dq; long).
# 2. Assemble at q = (2.6, -1.7, 0.35) rad: platform pose, G, checked against
#    central differences.
# 3. Print M' = M and the circuit elements; simulate, check against the ODE and
#    exact solutions; draw circuit and mechanism.
# 4. Sweep q1 (q2, q3 fixed) from 0.8 to 3 rad. Near q1 = 2.785 rad the closed
#    loop becomes singular (the closure equations no longer fix the passive
#    coordinates: dp/dq, and with it every mass the motors feel, grows without
#    bound), and past it the working mode does not continue: those poses raise
#    InputError and are skipped. Over the rest all six element values change
#    with q1, every MP capacitance changes sign somewhere, the grounded m'1 is
#    even negative for a while, and M stays positive definite.

# %%
import _lab
import numpy as np

import analogy

out = _lab.output_folder()

# %% [markdown]
# ## 1. Symbolic mass matrix of the closed chain

# %%
scene = analogy.scene("parallel3")
model = scene.build_model()
_lab.section("mass matrix M(q) = S^T M_theta S of the closed chain")
print("passive coordinates:", ", ".join(map(str, model.passive)))
_lab.print_symbolic("M", model.mass_matrix)

# %% [markdown]
# ## 2. Assembly at the scene's pose

# %%
_lab.section(f"assembly at q = {scene.q} rad")
p, rates = model.assemble(scene.q)
x_p, y_p, phi = p[3:]
print(f"distal link angles psi = {p[:3]} rad")
print(f"platform at ({1e3 * x_p:.2f}, {1e3 * y_p:.2f}) mm, orientation {phi:.4f} rad")
_lab.print_matrix("G = dp/dq", rates)
_lab.check_loop_closure_rates(model, scene.q)

# %% [markdown]
# ## 3. Circuit at the scene's pose

# %%
system = scene.system(model)
_lab.section("node system (parallel topology: v = r, M' = M, K' = K)")
_lab.print_matrix("M' = M", system.mass)
_lab.print_matrix("K' = K", system.stiffness)
_lab.print_elements(system)
# Each MP capacitance is minus its own off-diagonal entry (C2_3 = -M23, not -M13 as eq. 35 prints).
values = {e.name: e.value for e in analogy.elements(system)}
for i, j in ((0, 1), (0, 2), (1, 2)):
    assert values[f"C{i + 1}_{j + 1}"] == -system.mass[i, j]
assert not np.isclose(values["C2_3"], -system.mass[0, 2]), "M13 and M23 differ at this pose"
kinds = [e.kind + ("_float" if e.floating else "") for e in analogy.elements(system)]
assert kinds.count("C_float") == 3 and kinds.count("L") == 3, "three MP models, three springs"
_lab.check_solvers(system, out, "parallel3")
_lab.draw_diagrams(system, out, "parallel3")

# %% [markdown]
# ## 4. Sweep q1 past the edge of the working mode

# %%
_lab.section("sweep q1")
x, mats, skipped = _lab.sweep(scene, model, 0, np.linspace(0.8, 3.0, 89))
assert skipped and min(skipped) > scene.q[0], "poses beyond the working mode are skipped, not plotted"
assert x.min() <= scene.q[0] <= x.max()
assert np.all(np.linalg.eigvalsh(mats)[:, 0] > 0), "M is positive definite at every assembled pose"
m_ground, p_float = _lab.split(mats)
changes = {f"p'{i + 1}_{j + 1}": int(np.count_nonzero(np.diff(np.sign(v)))) for (i, j), v in p_float.items()}
print("sign changes of the MP capacitances over the sweep:", changes)
assert all(n > 0 for n in changes.values()), "every coupling vanishes somewhere on the sweep"
print(f"the grounded m'1 is negative for q1 in about "
      f"[{x[m_ground[:, 0] < 0].min():.2f}, {x[m_ground[:, 0] < 0].max():.2f}] rad; M stays positive definite")

fig, axes = _lab.figure(2, 1, size=(9, 7.5))
common = dict(xlabel="q1 [rad]", ylabel="capacitance [mF] = inertia [g·m²]", scale=1e3,
              here=scene.q[0], skipped=skipped)
_lab.plot_sweep(axes[0, 0], x, {f"m'{i + 1} (grounded C{i + 1})": (m_ground[:, i], dict(color=f"C{i}"))
                                for i in range(3)}, title="masses (grounded capacitors)", **common)
_lab.plot_sweep(axes[1, 0], x, {f"p'{i + 1}_{j + 1} (C{i + 1}_{j + 1}, MP model)": (v, dict(color=f"C{k + 3}"))
                                for k, ((i, j), v) in enumerate(p_float.items())},
                title="MP models (floating capacitors)", **common)
# Close to the singularity the values grow without bound; the axes show the rest.
regular = x <= 2.7
for ax, data in ((axes[0, 0], m_ground), (axes[1, 0], np.array(list(p_float.values())).T)):
    lo, hi = 1e3 * data[regular].min(), 1e3 * data[regular].max()
    ax.set_ylim(lo - 0.25 * (hi - lo), hi + 0.25 * (hi - lo))
    ax.axvline((x.max() + min(skipped)) / 2, color="k", ls="-.", lw=0.8,
               label="singular pose: values grow without bound")
    _lab.legend_outside(ax)
fig.suptitle(f"3-RRR: element values over q1 (q2 = {scene.q[1]}, q3 = {scene.q[2]} rad)")
_lab.save(fig, out / "parallel3_sweep.png")
