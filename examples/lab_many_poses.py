# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: a thousand poses of the 2-DOF serial arm, built and simulated together
#
# Run as a script with `python examples/lab_many_poses.py [output-folder]`, or open it as a
# notebook (see examples/README.md).
#
# **Physics.** The circuit of an arm holds at one pose: its element values follow
# M(q). To see how they change, and whether the circuit keeps the arm's dynamics at
# every pose, build and simulate many poses. The congruence M' = T⁻ᵀ·M·T⁻¹ changes
# the elements but not the dynamics: M'⁻¹B' = T·(M⁻¹B)·T⁻¹ has the eigenvalues of
# M⁻¹B, so the circuit decays with the arm's own time constants.
#
# **Steps**
#
# 1. Build the arm's node systems at 1,000 values of q2 at once with
#    analogy.node_systems: one vectorised evaluation of M(q) and one stacked
#    congruence M' = T⁻ᵀ M T⁻¹ for all of them.
# 2. Check two facts across the sweep: the MP capacitance is
#    c12 = −l1·l2·d2·cos q2, and the circuit has the arm's own time constants
#    (the eigenvalues of M⁻¹ B do not change under the congruence).
# 3. Simulate every pose in ngspice, 100 independent circuits per run on both
#    cores, and compare each pose with its exact solution.
# 4. Plot c12, the time constants and each pose's SPICE error against q2.

# %%
import _lab
import numpy as np

import analogy
from analogy.batch import run_batch

out = _lab.output_folder()

scene = analogy.scene("default")
model = scene.numeric_model()
q2 = np.linspace(-np.pi, np.pi, 1000)
poses = np.column_stack([np.zeros_like(q2), q2])

# %% [markdown]
# ## 1. All node systems as one stack

# %%
systems = scene.systems(poses, model)
node_mass = np.stack([s.mass for s in systems])
print(f"built {len(systems)} node systems; M' at q2 = {q2[0]:+.3f}:\n{node_mass[0]}")

# %% [markdown]
# ## 2a. The floating capacitor between n1 and n2 is the MP model: c12 = −M'12

# %%
c12 = -node_mass[:, 0, 1]
p = model.parameters
assert np.allclose(c12, -p["l1"] * p["l2"] * p["d2"] * np.cos(q2), atol=1e-12)
print(f"c12 runs from {c12.min():+.3f} F to {c12.max():+.3f} F and changes sign at q2 = +-pi/2")

# %% [markdown]
# ## 2b. Time constants
#
# The decay rates are the eigenvalues of M⁻¹B in joint space and of M'⁻¹B' in node
# space; a congruence leaves them unchanged.

# %%
joint = model.joint_stack(poses)
rates_joint = np.sort(np.linalg.eigvals(np.linalg.solve(joint.mass_matrix, joint.damping)).real, axis=1)
node_damping = np.stack([s.damping for s in systems])
rates_node = np.sort(np.linalg.eigvals(np.linalg.solve(node_mass, node_damping)).real, axis=1)
assert np.allclose(rates_node, rates_joint, rtol=1e-12)
tau = 1.0 / rates_node                     # columns: slow, fast
print(f"slowest time constant {tau[:, 0].min():.3f} s to {tau[:, 0].max():.3f} s; "
      f"fastest {tau[:, 1].min():.3f} s to {tau[:, 1].max():.3f} s")

# %% [markdown]
# ## 3. Every pose in ngspice, grouped 100 circuits to a run, each against its exact solution
#
# The circuits of one run share its time steps, so the error curve steps between groups.

# %%
result = run_batch([scene.replace(q=tuple(row)) for row in poses], "fast", group_size=100)
print(result.summary())
assert not result.failures
assert np.all(result.errors <= 1e-3), "the fast preset stays within 1e-3 of the peak at every pose"

# %% [markdown]
# ## 4. Table and plots

# %%
np.savetxt(out / "many_poses.csv", np.column_stack([q2, c12, tau, result.errors]), delimiter=",",
           header="q2_rad,c12_F,tau_slow_s,tau_fast_s,spice_error_over_peak", comments="")

fig, axes = _lab.figure(3, 1, size=(8.5, 7))
ax_c, ax_t, ax_e = axes[:, 0]
for ax in (ax_c, ax_t):
    ax.sharex(ax_e)
ax_c.plot(q2, c12, color="C3")
ax_c.axhline(0, color="k", lw=0.5)
ax_c.set_ylabel("c12 = −M'12 [F] = [kg·m²]")
ax_c.set_title("MP capacitance: negative where the links fold less than 90 degrees")
ax_t.plot(q2, tau[:, 0], label="slow mode")
ax_t.plot(q2, tau[:, 1], label="fast mode")
ax_t.set_ylabel("time constant [s]")
_lab.legend_outside(ax_t)
ax_e.semilogy(q2, result.errors, ".", ms=2, color="C0", label="one pose")
ax_e.axhline(1e-3, color="r", ls="--", lw=0.8, label="fast preset bound")
ax_e.set_ylabel("SPICE max error / peak [-]")
ax_e.set_xlabel("q2 [rad]")
_lab.legend_outside(ax_e)
for ax in (ax_c, ax_t, ax_e):
    for x in (-np.pi / 2, np.pi / 2):
        ax.axvline(x, ls=":", color="gray")
    ax.grid(alpha=0.3)
_lab.save(fig, out / "many_poses.png")
