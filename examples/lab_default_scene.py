# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: the 2-DOF serial arm as a circuit, and why its MP capacitor can be negative
#
# Run as a script with `python examples/lab_default_scene.py [output-folder]`, or open it
# as a notebook (see examples/README.md).
#
# **Physics.** A planar arm with two revolute joints is the MP-model paper's running example
# (eqs. 17-20). Its kinetic energy ½·rᵀM(q)r defines the mass matrix M(q). In the
# circuit a node voltage is a velocity and a current is a force (a torque, for a
# revolute joint), so a capacitance is a mass (a rotational inertia, in kg·m²).
#
# **Steps**
#
# 1. Build the arm at q2 = 0.3 rad.
# 2. Map it to node coordinates v = T·r (serial topology: v1 = r1, v2 = r1 + r2).
# 3. Print the circuit elements: grounded capacitors are masses, the floating
#    capacitor between n1 and n2 is an MP model.
# 4. Simulate with SPICE, the ODE solver and the exact solver and compare.
# 5. Sweep q2 and plot the MP capacitance c12(q2) = −l1·l2·d2·cos q2.

# %%
import _lab
import numpy as np

import analogy

out = _lab.output_folder()

# %% [markdown]
# ## 1-3. The arm, its node system and its elements
#
# M(q) is symbolic; M' = T⁻ᵀ·M·T⁻¹ is evaluated at the scene's pose. The element values
# are in circuit units: read a farad as kg·m² (a joint's inertia) and a resistance R
# as a damper b = 1/R in N·m·s/rad.

# %%
scene = analogy.scene("default")
model = scene.build_model()
print("M(q) =", model.mass_matrix)

system = scene.system(model)
print("\nnode mass matrix M' = T^-T M T^-1 at q2 = 0.3:\n", system.mass)
print("\nelements:")
for e in analogy.elements(system):
    print(f"  {e.name:<6} {e.meaning:<9} {e.value:+.6f} {e.unit}")

# %% [markdown]
# The floating capacitor c12 = −M'12 is negative here. A negative capacitor is no
# physical part, but the circuit is still passive: M' as a whole is positive definite.

# %%
c12 = analogy.mp_capacitance(system.mass)[0, 1]
assert c12 < 0, "for |q2| < pi/2 the MP mass opposes the relative motion of the links"

# %% [markdown]
# ## 4. Three solvers, one answer
#
# The same equations M'·dv/dt + B'·v = i are solved by ngspice, by an ODE solver and
# exactly (matrix exponential). SPICE must agree with the exact solution to 1e-6 of the
# peak joint rate.

# %%
result = analogy.compare(system, "accurate")
print(result.table())
result.to_csv(out / "default.csv")
result.plot(out / "default.png")
_lab.show(out / "default.png")
assert result.max_relative_error("spice") <= 1e-6

# %% [markdown]
# ## 5. The MP capacitance over the elbow angle
#
# c12 = −l1·l2·d2·cos q2: negative while the links fold less than 90°, zero at
# q2 = ±π/2 (M' is diagonal: two plain masses), positive beyond.

# %%
q2 = np.linspace(-np.pi, np.pi, 181)
c = np.array([analogy.mp_capacitance(scene.replace(q=(0.0, x)).system(model).mass)[0, 1] for x in q2])
p = model.parameters
assert np.allclose(c, -p["l1"] * p["l2"] * p["d2"] * np.cos(q2), atol=1e-12)

fig, axes = _lab.figure(size=(7, 3.5))
ax = axes[0, 0]
ax.plot(q2, c, color="C3", label="c12 = −M'12 (MP model)")
ax.axhline(0, color="k", lw=0.5)
for k, x in enumerate((-np.pi / 2, np.pi / 2)):
    ax.axvline(x, ls=":", color="gray", label=None if k else "q2 = ±π/2: c12 = 0")
ax.axvline(scene.q[1], color="gray", ls="--", lw=0.8, label="scene pose")
ax.set_xlabel("elbow angle q2 [rad]")
ax.set_ylabel(_lab.MASS_AXIS)
ax.set_title("2-DOF arm: the MP capacitance changes sign at q2 = ±π/2")
ax.grid(alpha=0.3)
_lab.legend_outside(ax)
_lab.save(fig, out / "mp_capacitance_sweep.png")
