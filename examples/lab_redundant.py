# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: redundant actuators on one axis (paper Figs. 8-9, eqs. 11-16): masses suffice, if you pick the nodes well
#
# Run as a script with `python examples/lab_redundant.py [output-folder]`, or open it as a
# notebook (see examples/README.md).
#
# **Physics.** Two actuators are stacked on one axis: actuator 1 moves stage 1 (mass
# d1) and, riding on it, actuator 2 moves stage 2 (mass d2) relative to stage 1.
# With joint rates r1 (stage 1) and r2 (stage 2 relative to stage 1) the stage
# velocities are r1 and r1 + r2, so the kinetic energy gives
#
#     M = [[d1 + d2, d2], [d2, d2]]          (independent of the configuration)
#
# In the serial topology the circuit's nodes are the absolute stage velocities,
# v1 = r1 and v2 = r1 + r2, and M' = T⁻ᵀ M T⁻¹ = diag(d1, d2): each stage is a
# plain grounded mass, no MP model is needed (the paper's text says so; its
# printed eq. 15, M'11 = m1 + m2, drops the -2 M12 term: m1 - m2 = d1 is right).
#
# The choice of node velocities is ours, though. With the parallel topology
# (v = r, node 2 carries the relative rate r2) the very same device has
# M' = M, whose off-diagonal d2 needs an MP model p'12 = -d2 < 0. Both circuits
# describe the same mechanics, so they must give the same joint rates.
#
# **Steps**
#
# 1. Derive M' symbolically for both topologies.
# 2. Print M' and the elements of the serial circuit; simulate, compare, draw.
# 3. Do the same for the parallel-topology circuit, with its MP model.
# 4. Overlay the joint rates of the two circuits: they agree.
# M does not depend on the configuration, so there is nothing to sweep over q.

# %%
import _lab
import numpy as np
import sympy as sp

import analogy

out = _lab.output_folder()

# %% [markdown]
# ## 1. Symbolic mass matrix and its node forms

# %%
scene = analogy.scene("redundant")
model = scene.build_model()
d1, d2 = model.symbols["d1"], model.symbols["d2"]
_lab.section("mass matrix M, derived from the kinematics")
_lab.print_symbolic("M", model.mass_matrix)
assert not model.mass_matrix.free_symbols & set(model.coordinates), "M does not depend on q"
print("M does not depend on q: the element values are the same in every configuration.")

serial = scene.system(model)                                  # the model's own topology: serial
parallel = scene.replace(topology="parallel").system(model)   # v = r
serial_node_mass = _lab.symbolic_node_matrix(model.mass_matrix, serial)
parallel_node_mass = _lab.symbolic_node_matrix(model.mass_matrix, parallel)
_lab.print_symbolic("M' (serial)", serial_node_mass)
_lab.print_symbolic("M' (parallel)", parallel_node_mass)
assert serial_node_mass == sp.diag(d1, d2), "serial nodes: each stage is a grounded mass"
_, floating = _lab.symbolic_split(parallel_node_mass)
assert floating["p'1_2"] == -d2, "parallel nodes: an MP model of mass -d2 couples the nodes"

# %% [markdown]
# ## 2. The serial circuit: two masses, two dampers, two sources; no MP model

# %%
_lab.section("serial topology: v1 = r1, v2 = r1 + r2")
_lab.print_matrix("M' = T^-T M T^-1", serial.mass)
_lab.print_elements(serial)
assert not any(e.meaning == "MP model" for e in analogy.elements(serial))
serial_result = _lab.check_solvers(serial, out, "redundant")
_lab.draw_diagrams(serial, out, "redundant")

# %% [markdown]
# ## 3. The parallel circuit of the same device: now an MP model is needed

# %%
_lab.section("parallel topology: v1 = r1, v2 = r2")
_lab.print_matrix("M' = M", parallel.mass)
_lab.print_elements(parallel)
mp = [e for e in analogy.elements(parallel) if e.meaning == "MP model"]
assert len(mp) == 1 and np.isclose(mp[0].value, -model.parameters["d2"], rtol=1e-12)
parallel_result = _lab.check_solvers(parallel, out, "redundant_parallel")
_lab.draw_diagrams(parallel, out, "redundant_parallel")

# %% [markdown]
# ## 4. Same mechanics, same motion
#
# The exact joint rates of the two circuits agree to rounding, and each SPICE run
# agrees with them to 1e-6 of the peak (checked above).

# %%
grid = np.linspace(0.0, scene.t_stop, 2001)
r_serial = analogy.solve_exact(serial, grid).rates
r_parallel = analogy.solve_exact(parallel, grid).rates
gap = np.max(np.abs(r_serial - r_parallel)) / np.max(np.abs(r_serial))
print(f"\nexact joint rates, serial vs parallel circuit: max difference / peak = {gap:.1e}")
assert gap <= 1e-12

fig, axes = _lab.figure(size=(7, 4.2))
ax = axes[0, 0]
for result, name, style in ((serial_result, "serial circuit (2 masses)", dict(lw=3, alpha=0.4)),
                            (parallel_result, "parallel circuit (2 masses + MP)", dict(ls="--", lw=1.2))):
    spice = result.results["spice"]
    for j in range(2):
        ax.plot(spice.time, spice.rates[:, j], color=f"C{j}", label=f"r{j + 1}, {name}", **style)
ax.set_xlabel("time [s]")
ax.set_ylabel("joint rate [m/s] (prismatic joints)")
ax.set_title("Redundant actuators: two circuits, one motion (SPICE)")
ax.grid(alpha=0.3)
_lab.legend_outside(ax)
_lab.save(fig, out / "redundant_topologies.png")
