# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: the 2-DOF arm's full nonlinear dynamics, simulated inside SPICE
#
# Run as a script with `python examples/lab_nonlinear.py [output-folder]`, or open it as a
# notebook (see examples/README.md).
#
# **Physics.** The linear circuit freezes the arm at one pose. The real arm has
# M(q)·q̈ + c(q, q̇) + G(q) + B·q̇ = τ, where the Coriolis and centrifugal forces c
# come from the Christoffel symbols of M(q). In node coordinates (v = T·r, x = ∫v)
# the Lagrange equations are
#
#     d/dt(M'(x)·v) − ½·vᵀ(∂M'/∂x)v + ∂U/∂x + B'·v = i.
#
# The circuit keeps the MP split of M' = T⁻ᵀ·M(q)·T⁻¹, but each capacitor now holds a
# charge Q = c(x)·(v_a − v_b) (ngspice's Q= form, whose current is d(cΔv)/dt), the
# −½·vᵀ∂M'v + gravity terms are behavioural currents, and an integrator node per
# joint carries x. The MP capacitance p'12 = −l1·l2·d2·cos(q2) now changes with the
# motion, and changes sign whenever the elbow passes ±π/2.
#
# **Steps**
#
# 1. Swing the arm through large angles with step torques (the default scene, 20 s):
#    SPICE and the ODE against the tight reference (DOP853, rtol 1e-13).
# 2. Follow p'12(t) = −l1 l2 d2 cos q2(t) through its sign changes, and watch the arm
#    swing beside its circuit's values (an animation).
# 3. The energy flows: kinetic energy, the work of the torques and of the dampers,
#    and the balance's residual for every solver.
# 4. Where the linear circuit (frozen at q0) stops holding.
# 5. A double pendulum under gravity, released from the horizontal without damping:
#    chaotic, so the figure is the predictability horizon, not an error.

# %%
import _lab
import numpy as np

import analogy
from analogy.study.horizon import linear_horizon

out = _lab.output_folder()

# %% [markdown]
# ## 1. Large swings: the default arm with its step torques, for 20 s

# %%
scene = analogy.scene("default").replace(t_stop=20.0)
system = scene.replace(dynamics="nonlinear").system()
result = analogy.compare(system, "accurate", ["spice", "ode"])
_lab.section("the nonlinear arm in SPICE, against the reference")
print(result.table())
assert result.errors()["spice"][1] <= 1e-6 and result.errors()["ode"][1] <= 1e-9
result.to_csv(out / "nonlinear.csv")
_lab.save(result.plot(), out / "nonlinear.png")

# %% [markdown]
# ## 2. The MP capacitance during the motion

# %%
ref = result.results["reference"]
q = system.q0 + system.topology.joint_rates(ref.positions)
p = system.parameters
mp = -p["l1"] * p["l2"] * p["d2"] * np.cos(q[:, 1])
crossings = ref.time[1:][np.diff(np.sign(mp)) != 0]
_lab.section("MP capacitance p'12(t) = -l1 l2 d2 cos q2(t)")
print(f"   q2 sweeps {q[:, 1].min():.2f} .. {q[:, 1].max():.2f} rad; p'12 changes sign "
      f"{len(crossings)} times, first at t = {crossings[0]:.3f} s" if len(crossings) else
      "   p'12 keeps its sign")
assert len(crossings) >= 2, "the swing takes the elbow through +-pi/2"
fig, axes = _lab.figure(2, 1, size=(8, 5.5))
axes[0, 0].plot(ref.time, q[:, 1], label="q2 (elbow)")
for k in (-1, 1):
    axes[0, 0].axhline(k * np.pi / 2, color="gray", ls=":", lw=0.8, label="q2 = ±π/2" if k > 0 else None)
axes[0, 0].set_ylabel("elbow angle q2 [rad]")
axes[0, 0].set_title("the elbow swings past π/2 and back: the MP capacitance changes sign twice")
_lab.legend_outside(axes[0, 0])
axes[1, 0].plot(ref.time, mp, color="C3", label="p'12 = −l1·l2·d2·cos q2")
axes[1, 0].axhline(0.0, color="k", lw=0.6)
axes[1, 0].plot(crossings, np.zeros(len(crossings)), "o", color="C3", ms=4, label="sign changes")
axes[1, 0].set_ylabel("MP capacitance [F] = [kg·m²]")
axes[1, 0].set_xlabel("time [s]")
_lab.legend_outside(axes[1, 0])
for a in axes[:, 0]:
    a.grid(alpha=0.3)
_lab.save(fig, out / "nonlinear_mp.png")

# %% [markdown]
# ## 2b. Watch it: the arm swinging beside its node voltages and its capacitances
#
# The pose is q = q0 + T⁻¹·∫v dt, integrated from SPICE's own node voltages. Watch the MP
# capacitance c12 = −M'12 in the lower panel cross zero as the elbow passes ±π/2, while the
# grounded capacitances C1, C2 (the rest of each node's mass) change with it.

# %%
swing = analogy.motion(system, result.results["spice"], frames=48)
print(swing)
_lab.animate(swing, out / "nonlinear_motion.gif")
floating = -swing.capacitances[:, 0, 1]
assert floating.min() < 0 < floating.max(), "c12 changes sign during the swing"

# %% [markdown]
# ## 3. Energy: T(t) - T(0) = W(t), the work of the torques and the dampers

# %%
_lab.section("energy balance T + U - T(0) - W, relative to the energy scale")
for name, value in result.energy.items():
    print(f"   {name:<10}{value:.2e}")
assert result.energy["reference"] <= 1e-9
t, v = ref.time, ref.voltages
kinetic = 0.5 * np.einsum("ti,tij,tj->t", v, np.stack([system.node_mass(x) for x in ref.positions]), v)
drive = np.einsum("ti,ti->t", v, system.node_currents(t))
loss = np.einsum("ti,ij,tj->t", v, system.damping, v)


def integral(power):
    return np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])


fig, axes = _lab.figure(size=(8, 4))
ax = axes[0, 0]
ax.set_title("energy balance of the nonlinear arm (reference solution)")
ax.grid(alpha=0.3)
ax.plot(t, kinetic, label="kinetic energy T")
ax.plot(t, integral(drive), label="work of the torques")
ax.plot(t, integral(loss), label="heat in the dampers")
ax.plot(t, integral(drive) - integral(loss), "k:", label="torques − dampers (= T)")
ax.set_xlabel("time [s]")
ax.set_ylabel("energy [J]")
_lab.legend_outside(ax)
_lab.save(fig, out / "nonlinear_energy.png")

# %% [markdown]
# ## 4. The linear circuit at q0 against the full motion

# %%
horizon = linear_horizon(scene, "accurate", ["ode"])
_lab.section("how long the circuit linearised at q0 holds")
print("\n".join(f"   {line}" for line in horizon.lines()))
assert horizon.held[1e-2] < horizon.held[1e-1] < scene.t_stop
_lab.save(horizon.plot(), out / "nonlinear_linear.png")

# %% [markdown]
# ## 5. Chaos: a double pendulum under gravity (g = 9.81), no damping, from the horizontal

# %%
pendulum = analogy.scene("default").replace(
    parameters={"g": 9.81, "b1": 0.0, "b2": 0.0}, q=(0.0, 0.0), forces=(0.0, 0.0), t_stop=5.0,
    dynamics="nonlinear").system()
chaos = analogy.compare(pendulum, "accurate", ["spice", "ode"])
_lab.section("double pendulum under gravity: predictability horizon (1e-6 of the peak)")
for name in ("spice", "ode"):
    h = chaos.horizon(name, 1e-6)
    print(f"   {name:<6} agrees with the reference until t = "
          f"{'the end' if not np.isfinite(h) else f'{h:.3f} s'}; energy residual {chaos.energy[name]:.1e}")
_lab.save(chaos.plot(), out / "pendulum.png")
