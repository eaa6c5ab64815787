# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: contact as a diode — a hopper drops, bounces and settles
#
# Run as a script with `python examples/lab_contact.py [output-folder]`, or open it as a notebook
# (see examples/README.md).
#
# **Physics.** The hopper is a body of mass mb on a springy leg (kl, damper bl) with a foot of mass
# mf. Its coordinates are the body's height z and the foot's height d below the body, so the foot
# is at y = z + d. In the serial topology its two nodes are the body's and the foot's velocities:
# each mass is a capacitor to ground and the leg a resistor and a spring between them.
#
# The ground is a **one-port from the foot's node to ground** that conducts only one way: while the
# foot is in the ground (penetration p = −y > 0) it pushes back with a spring and a damper,
# f = kc·p + cc·ṗ; in flight it carries nothing. In a circuit that is a diode in series with a
# parallel L–R. ngspice's Newton iteration needs the switch smooth, so it is smoothed over a stated
# length δ: f = (kc·p + cc·ṗ)·(1 + tanh(p/2δ))/2. The ODE integrates the same law, so SPICE and the
# ODE are compared on one model.
#
# **Steps**
#
# 1. The circuit: the contact's lines in the netlist.
# 2. The drop, in SPICE and the ODE: every output within the bound, the contact force too.
# 3. The closed form: flight is a parabola, stance a damped oscillator. The smoothing departs from
#    the sharp law as δ².
# 4. The diode's characteristic: force against penetration, one-sided, with the damper's loop.
# 5. The energy each impact loses, and where it goes.
# 6. Settling: the foot rests in the ground, the force equal to the weight. Animated.

# %%
import math

import _lab
import numpy as np
from scipy.linalg import expm

import analogy
from analogy.model.legged import HOPPER
from analogy.solvers.ode import solve_ode

out = _lab.output_folder()
p = HOPPER
scene = analogy.scene("hopper")
system = scene.system()
weight = (p["mb"] + p["mf"]) * p["g"]
print(scene.description)
print(f"weight {weight:.4g} N; standing, the foot sinks weight/kc = {1e3 * weight / p['kc']:.3g} mm; "
      f"δ = {1e3 * p['delta']:.3g} mm")

# %% [markdown]
# ## 1. The circuit
#
# C1 and C2 are the body's and the foot's masses (Q = c·v: constant capacitors here). `Bf_foot`
# holds the node `f_foot` at the contact force, and `Bh2` draws it into the foot's node; the body's
# node does not see it. The leg's spring is part of the potential (it rests at its own length
# whatever pose the run starts from), so it is in the B sources, and the leg's damper is `R1_2`.

# %%
_lab.section("1. The circuit")
netlist = analogy.netlist(system)
for line in netlist.splitlines():
    if line[:2] in ("Bf", "Bh", "C1", "C2", "R1"):
        print(line)

# %% [markdown]
# ## 2. The drop: SPICE against the ODE
#
# No exact solution exists (the contact is nonlinear), so the yardstick is the ODE at rtol 1e-13.
# The contact force `f_foot` is an output like the joint rates, judged against its own peak.

# %%
_lab.section("2. The drop")
result = analogy.compare(system, solvers=("spice", "ode", "reference"), preset="accurate")
print(result.table())
assert not result.outside_bound()
assert set(result.errors()["spice"].per_output) == {"r1", "r2", "f_foot"}
result.plot(out / "contact_drop.png")
_lab.show(out / "contact_drop.png")
print(f"wrote {result.to_csv(out / 'contact_drop.csv', every=50)}")

# %% [markdown]
# ## 3. The closed form of each phase
#
# **Flight.** Only gravity acts and the leg's spring rests: both masses fall on the parabola
# z = z0 − g·t²/2 until the foot touches at t = √(2h/g).
#
# **Stance.** With the foot in the ground the law is linear: M·q̈ + C·q̇ + K·q = b, with the ground's
# kc and cc on the foot's height q1 + q2 and the leg's kl and bl on q2. Its solution from the
# touchdown state is y(s) = e^{As}·(y0 + A⁻¹b) − A⁻¹b, a damped oscillation about the pose where
# the foot carries the weight.
#
# The smooth switch starts pushing a few δ before the sharp one and lets go a few δ later; its
# departure s(p) − H(p) is odd about p = 0, so the impulses before and after cancel to first order
# and the motion in mid-stance departs from the closed form as δ².

# %%
_lab.section("3. Flight and stance in closed form")
mass = np.array([[p["mb"] + p["mf"], p["mf"]], [p["mf"], p["mf"]]])
stiff = np.array([[p["kc"], p["kc"]], [p["kc"], p["kc"] + p["kl"]]])
damp = np.array([[p["cc"], p["cc"]], [p["cc"], p["cc"] + p["bl"]]])
load = -np.array([weight, p["g"] * p["mf"] + p["kl"] * p["l0"]])
inv = np.linalg.inv(mass)
a = np.block([[np.zeros((2, 2)), np.eye(2)], [-inv @ stiff, -inv @ damp]])
b = np.concatenate([np.zeros(2), inv @ load])
shift = np.linalg.solve(a, b)
touchdown = math.sqrt(2 * 0.1 / p["g"])
y0 = np.array([0.3, -0.3, -p["g"] * touchdown, 0.0])
rates = np.linalg.eigvals(a)
print(f"touchdown at t = {touchdown:.5f} s, at {p['g'] * touchdown:.4f} m/s")
print("stance rates:", ", ".join(f"{r:.4g}" for r in rates[np.imag(rates) >= 0]), "1/s")


def stance(s):
    return expm(a * s) @ (y0 + shift) - shift


times = np.linspace(0, 0.25, 501)
flight = times[times < touchdown]
departures = {}
for delta in (1e-4, 1e-5):
    smooth = scene.replace(parameters={"delta": delta}).system()
    run = solve_ode(smooth, times, "DOP853", rtol=1e-12, positions=True)
    q = smooth.q0 + run.positions @ smooth.topology.inverse.T
    mid = int(np.searchsorted(times, touchdown + 0.05))
    closed = stance(times[mid] - touchdown)
    departures[delta] = float(np.max(np.abs(np.concatenate([q[mid], run.rates[mid]]) - closed)
                                    / np.array([0.4, 0.3, 1.4, 1.4])))
    if delta == p["delta"]:
        shown = q
    print(f"δ = {delta:g} m: flight off the parabola by {np.max(np.abs(q[:flight.size, 0] - (0.4 - p['g'] * flight ** 2 / 2))):.1e} m, "
          f"mid-stance off the closed form by {departures[delta]:.2e} of the peaks")
ratio = departures[1e-4] / departures[1e-5]
print(f"ten times smaller δ, {ratio:.1f} times smaller departure: second order")
assert 95 <= ratio <= 105
after = times[times >= touchdown]
closed = np.array([stance(s - touchdown) for s in after])
fig, ((ax,),) = _lab.figure(size=(8, 4.2))
ax.plot(times, shown[:, 0], label="body z (ODE)")
ax.plot(times, shown[:, 0] + shown[:, 1], label="foot y (ODE)")
ax.plot(flight, 0.4 - p["g"] * flight ** 2 / 2, "k:", lw=1.2, label="flight: parabola")
ax.plot(after, closed[:, 0], "k--", lw=1.0, label="stance: damped oscillator")
ax.plot(after, closed[:, 0] + closed[:, 1], "k--", lw=1.0)
ax.axhline(0.0, color="0.4", lw=0.8)
ax.set_ylim(-0.02, 0.42)
ax.set_xlabel("t [s]")
ax.set_ylabel("height [m]")
ax.set_title("the first impact: each phase in closed form")
_lab.legend_outside(ax)
_lab.save(fig, out / "contact_closed_form.png")

# %% [markdown]
# ## 4. The diode's characteristic
#
# Plotted against the penetration, the contact force is a diode's I–V curve: nothing for p < 0,
# a spring's line kc·p beyond. The damper adds cc·ṗ: more force going in than coming out, a loop
# whose area is the energy the ground takes at each impact.

# %%
_lab.section("4. The characteristic")
spice = result.results["spice"]
qs = system.q0 + spice.positions @ system.topology.inverse.T
depth = -(qs[:, 0] + qs[:, 1])
fig, ((ax,),) = _lab.figure(size=(7, 4.2))
ax.plot(1e3 * depth, spice.currents["f_foot"], lw=0.8, label="f_foot (SPICE)")
line = np.linspace(0, depth.max(), 50)
ax.plot(1e3 * line, p["kc"] * line, "k--", lw=1.0, label="the spring alone, kc·p")
ax.axvline(0.0, color="0.5", lw=0.6)
ax.set_xlim(-5, 1e3 * depth.max() * 1.1)
ax.set_xlabel("penetration p [mm]")
ax.set_ylabel("contact force [N]")
ax.set_title("contact as a diode: one-sided, with the damper's loop")
_lab.legend_outside(ax)
_lab.save(fig, out / "contact_diode.png")
# in flight the switch is off to rounding: ngspice's tanh stops short of −1 by an ε, so what is left is
# about ε·|kc·p + cc·ṗ|
away = depth < -40 * p["delta"]
sharp = p["kc"] * np.abs(depth) + p["cc"] * np.abs(spice.voltages[:, 1])
assert np.all(np.abs(spice.currents["f_foot"][away]) <= 2 * np.finfo(float).eps * sharp[away])

# %% [markdown]
# ## 5. The energy each impact loses
#
# E = ½·q̇ᵀMq̇ + g·(mb·z + mf·y) + ½·kl·(d + l0)² is the hopper's energy. In flight only the leg's
# damper takes some; in stance the ground's damper takes more. Over each stance, the change of E
# is the ground's work ∫f·ẏ dt plus the leg damper's −∫bl·ḋ² dt.

# %%
_lab.section("5. Energy per impact")
long = scene.replace(t_stop=4.0).system()
t = np.linspace(0, 4.0, 40001)
run = solve_ode(long, t, "DOP853", rtol=1e-11, positions=True)
q = long.q0 + run.positions @ long.topology.inverse.T
r, force = run.rates, run.currents["f_foot"]
foot = q[:, 0] + q[:, 1]
energy = 0.5 * np.einsum("ti,ij,tj->t", r, mass, r) + p["g"] * (p["mb"] * q[:, 0] + p["mf"] * foot) \
    + 0.5 * p["kl"] * (q[:, 1] + p["l0"]) ** 2
ground = np.concatenate([[0.0], np.cumsum(0.5 * np.diff(t) * (force[1:] * (r[1:, 0] + r[1:, 1])
                                                               + force[:-1] * (r[:-1, 0] + r[:-1, 1])))])
leg = np.concatenate([[0.0], np.cumsum(-0.5 * np.diff(t) * p["bl"] * (r[1:, 1] ** 2 + r[:-1, 1] ** 2))])
inside = foot < 0
edges = np.flatnonzero(np.diff(inside.astype(int))) + 1
landings, liftoffs = edges[inside[edges]], edges[~inside[edges]]
print(" impact   t [s]   E before [J]  E after [J]  lost   ground's work  leg damper's work")
for k, (i, j) in enumerate(zip(landings, liftoffs)):
    lost = energy[i] - energy[j]
    print(f"  {k + 1:4d}  {t[i]:7.4f}  {energy[i]:11.5f}  {energy[j]:11.5f}  {lost / energy[i]:5.1%}  "
          f"{ground[j] - ground[i]:12.5f}  {leg[j] - leg[i]:14.5f}")
    # the balance over the stance, to the trapezoidal rule's error on 0.1 ms points
    assert abs((energy[j] - energy[i]) - (ground[j] - ground[i]) - (leg[j] - leg[i])) < 1e-4 * energy[0]
print(f"after t = {t[edges[-1]]:.3f} s the foot stays in the ground")

# %% [markdown]
# ## 6. Settling, and the circuit in motion
#
# Once the foot stays in, the hopper is a linear damped system about the pose where the ground
# carries the weight: the foot sunk weight/kc, the force equal to the weight. What is left of
# the oscillation decays at the stance's slowest rate σ, so |f − weight| shrinks as e^(−σ·t).

# %%
_lab.section("6. Settling")
sigma = float(np.min(-np.real(rates)))
last = t[edges[-1]]
predicted = float(np.max(np.abs(force[t >= last] - weight))) * math.exp(-sigma * (t[-1] - last))
print(f"slowest stance rate σ = {sigma:.3f} 1/s; at t = 4 s the force is {force[-1]:.5f} N against the weight "
      f"{weight:.5f} N (left {abs(force[-1] - weight):.2e} N, the decay allows {predicted:.2e} N); "
      f"the foot is {-1e3 * foot[-1]:.4f} mm in, weight/kc = {1e3 * weight / p['kc']:.4f} mm")
assert abs(force[-1] - weight) <= predicted
fig, ((a1, a2),) = _lab.figure(1, 2, size=(12, 3.8))
a1.plot(t, q[:, 0], label="body z")
a1.plot(t, foot, label="foot y")
a1.axhline(0.0, color="0.4", lw=0.8)
a1.set_xlabel("t [s]")
a1.set_ylabel("height [m]")
a1.set_title("bounces, then rest on the ground's spring")
_lab.legend_outside(a1)
a2.plot(t, force, lw=0.8)
a2.axhline(weight, color="k", ls="--", lw=1.0, label="the weight (mb + mf)·g")
a2.set_xlabel("t [s]")
a2.set_ylabel("contact force [N]")
a2.set_title("the contact force settles on the weight")
_lab.legend_outside(a2)
_lab.save(fig, out / "contact_settling.png")
motion = analogy.motion(system, spice, frames=60)
_lab.animate(motion, out / "contact_motion.gif")
