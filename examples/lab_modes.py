# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: one node per mode, the modal circuit
#
# Run as a script with `python examples/lab_modes.py [output-folder]`, or open it as a
# notebook (see examples/README.md).
#
# **Physics.** The circuit's nodes are ours to choose: any invertible T gives node
# velocities v = T·r, node currents i = T⁻ᵀ·F and node matrices M' = T⁻ᵀ·M·T⁻¹ (B', K'
# alike), with power and energy unchanged. The serial topology makes each node a link's
# absolute velocity, and the coupling of the links shows up as floating capacitors (MP
# models). The modal topology picks instead the mode shapes Φ of K·φ = ω²·M·φ, scaled
# so that Φᵀ·M·Φ = I:
#
#     T = Φᵀ·M  (so r = Φ·v),   M' = I,   K' = Φᵀ·K·Φ = diag(ω²),   i = Φᵀ·F
#
# Each node is then one mode: a 1 F capacitor, an inductor L = 1/ω² and, when the damping
# is proportional (B = α·M + β·K, Rayleigh's), a resistor R = 1/(2ζω). Nothing floats:
# the modes are independent tanks, each driven by its share of the forces, and the joint
# rates are their sum r = Φ·v.
#
# **Steps**
#
# 1. The serial3 arm at a pose, with a spring at each joint and Rayleigh damping: its
#    serial circuit and its modal circuit, element by element.
# 2. Each tank rings at its mode's frequency with its mode's damping ratio.
# 3. Both circuits in ngspice, against the exact solution: one motion.
# 4. The modes' velocities, and the joint rates as their sum.
# 5. What it costs: a 50-DOF circuit, serial against modal.

# %%
import time

import _lab
import numpy as np

import analogy
from analogy.diagnostics.bench import bench_scenes
from analogy.model.joint import JointSpace
from analogy.results.modes import natural_modes

out = _lab.output_folder()

# %% [markdown]
# ## 1. The same arm, two circuits
#
# M is the serial3 arm's at q = (0, 0.4, −0.7). A torsion spring at each joint gives K,
# and B = 0.02·M + 0.01·K is Rayleigh damping, which the modes diagonalise too.

# %%
scene = analogy.scene("serial3").replace(q=(0.0, 0.4, -0.7))
m = scene.system().joint.mass_matrix
k = np.diag([40.0, 25.0, 10.0])
b = 0.02 * m + 0.01 * k
joint = JointSpace(m, b, k)
forces = ["step(1)", "sine(0, 0.5, 1)", "step(0.2, 1, 0.1)"]
serial = analogy.node_system(joint, topology="serial", forces=forces, t_stop=10.0)
modal = analogy.node_system(joint, topology="modal", forces=forces, t_stop=10.0)

_lab.section("serial topology: links' absolute velocities")
_lab.print_matrix("M' = T^-T M T^-1", serial.mass)
_lab.print_elements(serial)
_lab.section("modal topology: one node per mode")
_lab.print_matrix("M' (the identity)", modal.mass)
_lab.print_matrix("K' = diag(omega^2)", modal.stiffness)
_lab.print_elements(modal)
parts = analogy.elements(modal)
floating = [e for e in parts if e.floating]
print(f"\nserial circuit: {sum(e.floating for e in analogy.elements(serial))} floating elements; "
      f"modal circuit: {len(floating)}")
assert not floating, "every element of the modal circuit is grounded: the modes are independent"

# %% [markdown]
# ## 2. Each tank is a mode
#
# A grounded tank C, L, R rings at ω = 1/√(LC) with damping ratio ζ = 1/(2R)·√(L/C).
# `natural_modes` solves K·φ = ω²·M·φ on the joint space: the tanks must agree with it to
# rounding.

# %%
modes = natural_modes(joint)
print(modes.table())
tank = {(e.kind, e.a): e.value for e in parts}
omega = np.array([1 / np.sqrt(tank["L", j] * tank["C", j]) for j in range(1, 4)])
zeta = np.array([np.sqrt(tank["L", j] / tank["C", j]) / (2 * tank["R", j]) for j in range(1, 4)])
print("\ntank  omega [rad/s]  mode omega   tank zeta   mode zeta")
for j in range(3):
    print(f"  n{j + 1}  {omega[j]:13.6f}  {modes.omega[j]:10.6f}  {zeta[j]:10.6f}  {modes.damping_ratio[j]:10.6f}")
# rounding: a 3x3 eigenproblem through M's Cholesky factor, cond(M) about 30
np.testing.assert_allclose(omega, modes.omega, rtol=1e-10)
np.testing.assert_allclose(zeta, modes.damping_ratio, rtol=1e-10)

# %% [markdown]
# ## 3. Both circuits in ngspice
#
# Each is checked against the exact solution at the `accurate` preset. Ten seconds are four
# periods of the slowest mode, damped only 1.7 %, and the first SPICE run of either circuit
# errs about 1.0e-6 of r3's peak: on the bound. `refine=True` estimates each run's error
# from a run with every step halved and, where the estimate exceeds the bound, keeps the
# finer run (its note says so). The exact joint rates of the two circuits agree to
# rounding: a change of node coordinates changes no motion.

# %%
results = {}
for name, system in (("serial", serial), ("modal", modal)):
    result = results[name] = analogy.compare(system, "accurate", refine=True)
    print(result.table())
    assert not result.failures, result.failures
    result.to_csv(out / f"modes_{name}.csv")
    result.plot(out / f"modes_{name}.png")
    _lab.show(out / f"modes_{name}.png")
    assert result.max_relative_error("spice") <= 1e-6 and result.max_relative_error("ode") <= 1e-9
_lab.draw_diagrams(modal, out, "modes_modal")
grid = np.linspace(0.0, 10.0, 2001)
gap = np.max(np.abs(analogy.solve_exact(serial, grid).rates - analogy.solve_exact(modal, grid).rates))
gap /= np.max(np.abs(analogy.solve_exact(serial, grid).rates))
print(f"\nexact joint rates, serial against modal circuit: max difference / peak = {gap:.1e}")
assert gap <= 1e-12

# %% [markdown]
# ## 4. Mode velocities and their sum
#
# The node voltages of the modal circuit are the modes' velocities, and each answers the
# forces on its own. Mode 1 swings at its 2.5 rad/s after the steps at t = 0 and t = 1 s,
# and hardly decays (time constant 24 s). Modes 2 and 3 ring at their own frequencies at
# first; once that has decayed (time constants 2.1 s and 0.75 s), the 1 Hz sine on joint 2
# keeps them moving at its 6.3 rad/s. The joint rate r1 is Φ's first row times them.

# %%
spice = results["modal"].results["spice"]
phi = np.linalg.inv(modal.topology.matrix)            # r = Φ·v
fig, axes = _lab.figure(2, 1, size=(7, 6))
for j in range(3):
    axes[0, 0].plot(spice.time, spice.voltages[:, j], color=f"C{j}",
                    label=f"mode {j + 1}: {modes.omega[j]:.2f} rad/s, zeta {modes.damping_ratio[j]:.3f}")
axes[0, 0].set_ylabel("node voltage v_k (mode velocity)")
axes[0, 0].set_title("Modal circuit: three independent tanks (ngspice)")
for j in range(3):
    axes[1, 0].plot(spice.time, phi[0, j] * spice.voltages[:, j], color=f"C{j}", lw=1, label=f"Phi_1{j + 1} v_{j + 1}")
axes[1, 0].plot(spice.time, spice.rates[:, 0], color="k", lw=2, alpha=0.5, label="r1 = their sum")
axes[1, 0].set_xlabel("time [s]")
axes[1, 0].set_ylabel("joint rate r1 [rad/s]")
for ax in axes[:, 0]:
    ax.grid(alpha=0.3)
    _lab.legend_outside(ax)
np.testing.assert_allclose(spice.voltages @ phi[0], spice.rates[:, 0], rtol=0, atol=1e-12 * np.max(np.abs(spice.rates)))
_lab.save(fig, out / "modes_velocities.png")

# %% [markdown]
# ## 5. What the modal circuit costs
#
# A dense 50-DOF mass matrix gives the serial circuit 1,225 floating capacitors, and
# ngspice refactors their dense matrix at every step. The modal circuit has 50 grounded
# tanks; the forces into each node are written as one source (their sum). Run times
# depend on the machine, so they are printed, not checked; the errors are checked.

# %%
big = bench_scenes()[2]            # the bench's 50-DOF scene: random SPD M, a sine and 49 steps, 2 s
print(f"\n{'circuit':<8}{'floating C':>11}{'run time [ms]':>15}{'error / peak':>14}")
for name in ("serial", "modal"):
    system = big.replace(topology=name).system()
    floating_caps = sum(e.floating and e.kind == "C" for e in analogy.elements(system))
    start = time.perf_counter()
    result = analogy.compare(system, "fast", ("spice", "exact"))
    seconds = time.perf_counter() - start
    err = result.max_relative_error("spice")
    print(f"{name:<8}{floating_caps:>11}{seconds * 1e3:>15.1f}{err:>14.2e}")
    assert err <= 1e-3, "each circuit keeps the fast preset's bound"
