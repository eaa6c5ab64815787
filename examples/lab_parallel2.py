# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: the 2-DOF parallel five-bar (paper eqs. 24-26, Fig. 13): grounded actuators, coupled masses
#
# Run as a script with `python examples/lab_parallel2.py [output-folder]`, or open it as a
# notebook (see examples/README.md).
#
# **Physics.** A five-bar pantograph (a haptic device) has two motors on the base, at
# A1 = (-d/2, 0) and A2 = (d/2, 0). Each turns a proximal link (angle q_k); two
# distal links (angles psi_1, psi_2, passive) meet at the end effector. Both
# actuators are grounded, so the parallel topology v = r is the natural one:
# each node velocity is a motor speed, each force source is grounded, and
# M' = M, B' = B. The links still couple the motors' inertias: the off-diagonal
# M12 becomes an MP model p'12 = -M12 between the two nodes.
#
# M(q) is derived from the kinematics of the closed chain: with all link
# coordinates theta = (q, psi), the kinetic energy gives M_theta; the loop must
# stay closed, so the passive rates are psi_dot = G q_dot with G = dpsi/dq from
# the closure equations, and M = Sᵀ M_theta S with S = [I; G]. M therefore
# depends on q directly and through psi(q) and G(q).
#
# **Steps**
#
# 1. Print M(q) symbolically (in q, psi and the rates dpsi/dq).
# 2. Assemble the mechanism at q = (2.1, 0.9) rad: psi(q), G(q), the end effector;
#    check G against central differences of psi(q).
# 3. Print M' = M and the circuit elements; simulate in ngspice and check
#    against the ODE and exact solutions; draw circuit and mechanism.
# 4. Sweep q1 (q2 fixed) over poses where the five-bar stays in its working
#    mode: the MP capacitance p'12 changes sign twice, so the motors decouple at
#    two poses (p'12 = 0), and M stays positive definite.

# %%
import _lab
import numpy as np

import analogy

out = _lab.output_folder()

# %% [markdown]
# ## 1. Symbolic mass matrix of the closed chain

# %%
scene = analogy.scene("parallel2")
model = scene.build_model()
_lab.section("mass matrix M(q) = S^T M_theta S of the closed chain")
print("passive coordinates:", ", ".join(map(str, model.passive)))
_lab.print_symbolic("M", model.mass_matrix)

# %% [markdown]
# ## 2. Assembly at the scene's pose

# %%
_lab.section(f"assembly at q = {scene.q} rad")
psi, rates = model.assemble(scene.q)
par = model.parameters
q1, q2 = scene.q
tips = [np.array([side * par["d"] / 2, 0.0])
        + par["la"] * np.array([np.cos(q), np.sin(q)]) + par["lb"] * np.array([np.cos(p), np.sin(p)])
        for side, q, p in ((-1, q1, psi[0]), (1, q2, psi[1]))]
print(f"psi = {psi} rad; end effector at {1e3 * tips[0]} mm "
      f"(the two legs meet to {np.linalg.norm(tips[0] - tips[1]):.1e} m)")
_lab.print_matrix("G = dpsi/dq", rates)
assert np.linalg.norm(tips[0] - tips[1]) <= 1e-12, "the loop is closed"
_lab.check_loop_closure_rates(model, scene.q)

# %% [markdown]
# ## 3. Circuit at the scene's pose

# %%
system = scene.system(model)
_lab.section("node system (parallel topology: v = r, M' = M)")
_lab.print_matrix("M' = M", system.mass)
_lab.print_elements(system)
assert np.array_equal(system.mass, system.joint.mass_matrix)
_lab.check_solvers(system, out, "parallel2")
_lab.draw_diagrams(system, out, "parallel2")

# %% [markdown]
# ## 4. Sweep q1
#
# Every pose is assembled by continuation from the reference assembly; a pose outside
# the working mode raises InputError and is skipped.

# %%
_lab.section("sweep q1")
x, mats, skipped = _lab.sweep(scene, model, 0, np.linspace(1.0, 3.6, 105))
assert x.min() <= scene.q[0] <= x.max(), "the sweep covers the scene pose"
m_ground, p_float = _lab.split(mats)
p12 = p_float[0, 1]
assert np.all(np.linalg.eigvalsh(mats)[:, 0] > 0), "M is positive definite at every assembled pose"
flips = np.flatnonzero(np.diff(np.sign(p12)) != 0)
# Zero crossings of p'12, refined by linear interpolation between the two sweep points.
zeros = [x[k] - p12[k] * (x[k + 1] - x[k]) / (p12[k + 1] - p12[k]) for k in flips]
print("p'12 = 0 (decoupled motors) near q1 =", ", ".join(f"{z:.3f}" for z in zeros), "rad")
assert len(zeros) == 2, "p'12 changes sign twice over the sweep"

fig, axes = _lab.figure(size=(7, 4.2))
ax = axes[0, 0]
for k, z in enumerate(zeros):
    ax.axvline(z, color="C3", ls=":", lw=0.8, label=None if k else "p'12 = 0")
_lab.plot_sweep(ax, x, {
    "m'1 (grounded C1: mass at motor 1)": (m_ground[:, 0], dict(color="C0")),
    "m'2 (grounded C2: mass at motor 2)": (m_ground[:, 1], dict(color="C1")),
    "p'12 (floating C1_2: MP model)": (p12, dict(color="C3", lw=2)),
}, xlabel="q1 [rad]", ylabel="capacitance [mF] = inertia [g·m²]", scale=1e3,
    title=f"Five-bar: element values over q1 (q2 = {scene.q[1]} rad)", here=scene.q[0], skipped=skipped)
_lab.save(fig, out / "parallel2_sweep.png")
