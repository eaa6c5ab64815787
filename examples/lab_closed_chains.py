# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: closed chains inside SPICE — constraint forces as currents, the loop's residual, a singular pose
#
# Run as a script with `python examples/lab_closed_chains.py [output-folder]`, or open it as a
# notebook (see examples/README.md).
#
# **Physics.** Cut the five-bar open at its end effector and it is a tree: two legs of two
# links each, with joint angles θ = (q1, q2, ψ1, ψ2). Its mass matrix M_θ(θ) has a closed
# form, and so do its velocity terms. Closing the loop again takes two equations,
# Φ(θ) = tip of leg 1 − tip of leg 2 = 0, and two forces that hold them: the Lagrange
# multipliers λ, acting on the joints as Jᵀλ with J = ∂Φ/∂θ.
#
# A circuit solves such equations as a matter of course. Every joint is a node (its voltage
# the joint rate), and every multiplier is a node too. Into a multiplier's node flows one
# behavioural current, J(x)·v + α·Φ(x), and nothing else. Kirchhoff's current law at that
# node says this current is zero: that is the constraint, held at velocity level, with a
# small pull α·Φ on any drift of the integrated positions. The node's voltage is then
# whatever force keeps the loop closed. Currents Jᵀλ deliver it to the joints.
#
# The ODE solvers check this circuit with another formulation. They integrate the two motors
# alone and solve the passive angles ψ from the loop at every step (coordinate
# partitioning).
#
# **Steps**
#
# 1. The constrained circuit of the five-bar: its loop-closure lines in the netlist.
# 2. A swing of both motors through about 2 rad: SPICE against the reduced reference.
# 3. The multipliers' node voltages against the constraint forces solved from the reference
#    motion, and the loop's residual |Φ| over the run.
# 4. The built-in scene's longer run, which passes close to a singular pose: how the
#    conditioning of the loop and SPICE's error rise together, and how `compare` flags it.

# %%
import _lab
import numpy as np
import sympy as sp
from matplotlib.figure import Figure

import analogy
from analogy.circuit.constrained_circuit import open_system
from analogy.circuit.description import circuit
from analogy.solvers.ode import solve_ode
from analogy.solvers.spice import solve_spice
from analogy.study.comparison import SINGULAR_CONDITION, compare

out = _lab.output_folder()
swing = analogy.scene("parallel2").replace(dynamics="nonlinear", t_stop=4.0,
                                            forces=("sine(0, 0.02, 0.5)", "sine(0, 0.02, 0.5, 0, 0, 90)"))
system = swing.system()
model = system.model

# %% [markdown]
# ## 1. The circuit: the chain cut open, and two nodes that close it

# %%
_lab.section("the constrained circuit of the five-bar")
text = analogy.netlist(system)
for line in text.splitlines():
    if line.startswith(("* loop closure", "Bloop", "Blam")):
        print(line if len(line) < 160 else line[:157] + "...")
circ = circuit(system)
print(f"{circ.nodes} nodes: n1, n2 the motors, n3, n4 the distal links, n5, n6 the multipliers")
assert circ.nodes == 6 and circ.constraints == 2

# %% [markdown]
# ## 2. A swing across the workspace: SPICE against the motors' own equations

# %%
_lab.section("SPICE (every joint a node) against DOP853 on the motors alone")
c = compare(system, "accurate", solvers=("spice", "reference"))
print(c)
assert c.outside_bound() == {} and not c.singular

# %% [markdown]
# ## 3. Constraint forces as node voltages, and the residual of the loop
#
# From the reference motion the constraint forces follow without any circuit: at each
# instant, [M_θ, −Jᵀ; J, 0]·(θ̈, λ) = (τ − B·θ̇ − c_θ, −J̇·θ̇). SPICE's n5 and n6 should be
# those λ.

# %%
_lab.section("the multipliers: node voltages against the constraint forces")
run = solve_spice(system, save=["n5", "n6"])
tree = open_system(system)
theta = list(model.coordinates) + list(model.passive)
subs = {s: system.parameters[k] for k, s in model.symbols.items()}
phi = model.constraints.subs(subs)
jac = phi.jacobian(theta)
w = sp.symbols("w1:5")
quadratic = sp.lambdify([theta, w], list((jac * sp.Matrix(w)).jacobian(theta) * sp.Matrix(w)))
jac_f = sp.lambdify([theta], jac)
times = np.linspace(0.0, system.t_stop, 401)
ref = solve_ode(system, times, "DOP853", 1e-13, positions=True)
forces = []
for t, q, r in zip(times, system.configuration(ref.positions), ref.rates):
    p, g = model.assemble(q, system.parameters)
    th, th_dot = np.concatenate([q, p]), np.concatenate([r, g @ r])
    j = np.asarray(jac_f(th), dtype=float)
    kkt = np.block([[tree.functions.mass(th), -j.T], [j, np.zeros((2, 2))]])
    load = tree.node_currents(np.array([t]))[0] - tree.functions.damping @ th_dot - tree.functions.velocity(th, th_dot)
    forces.append(np.linalg.solve(kkt, np.concatenate([load, -np.asarray(quadratic(th, th_dot), float)]))[4:])
forces = np.array(forces)
# a multiplier's node is algebraic: SPICE has no value for it at t = 0, only from its first step
spice_lambda = np.column_stack([np.interp(times[1:], run.time[1:], run.currents[n][1:]) for n in ("n5", "n6")])
gap = np.max(np.abs(spice_lambda - forces[1:])) / np.max(np.abs(forces))
print(f"largest |λ(SPICE) − λ(reference)| over the peak: {gap:.2e}")
# λ is algebraic (index 2): the trapezoidal rule gives it to first order in the step, not the
# second as the rates, so it sits about h·(its rate of change) = 1e-5 from the reference
assert gap < 1e-4
residual, condition = system.loop_residual(run)
print(f"loop residual max |Φ| = {residual:.2e} m, equilibrated cond(Φ_p) at most {condition:.3g}")
fig = Figure(figsize=(8, 4), layout="constrained")
ax = fig.subplots()
for k, style in ((0, "C0"), (1, "C1")):
    ax.plot(run.time, run.currents[f"n{5 + k}"], color=style, lw=1.5, label=f"v(n{5 + k}) in SPICE: λ{k + 1}")
    ax.plot(times[::8], forces[::8, k], "o", color=style, ms=3, label=f"λ{k + 1} from the reference motion")
ax.set_xlabel("t [s]")
ax.set_ylabel("constraint force λ [N]  (node voltage [V])")
ax.set_title("the loop's constraint forces are the multiplier nodes' voltages", fontsize="medium")
ax.grid(alpha=0.3)
_lab.legend_outside(ax)
_lab.save(fig, out / "closed_chain_forces.png")

# %% [markdown]
# ## 4. Near a singular pose
#
# Where the two distal links line up, the loop's passive angles lose their solution: Φ_p
# becomes singular, and the constraint forces needed to keep the loop closed grow without
# bound. Run the built-in scene for its 10 s and watch the conditioning of Φ_p (its rows and
# columns scaled as at the start, so units do not matter) and SPICE's error side by side.
# At t = 1.42 s both legs fold flat, the distal links in line: the error jumps there and
# never recovers, since the motion after it depends on how the pass was resolved.

# %%
_lab.section("the built-in scene's 10 s: close to a singular pose")
long = analogy.scene("parallel2").replace(dynamics="nonlinear").system()
near = solve_spice(long, preset="accurate")
q = long.configuration(near.positions)
p0, _ = model.assemble(long.q0, long.parameters)
p = p0 + np.column_stack([near.currents["x3"], near.currents["x4"]])
_, cond = model.loop_closure(np.column_stack([q, p])[::4], long.parameters)
ref_long = solve_ode(long, near.time[::4], "DOP853", 1e-13)
error = np.max(np.abs(near.rates[::4] - ref_long.rates) / np.max(np.abs(ref_long.rates), axis=0), axis=1)
worst = int(np.argmax(cond))
jump = int(np.argmax(error > 1e-6))
print(f"cond(Φ_p) peaks at {cond[worst]:.3g} at t = {near.time[::4][worst]:.3g} s; SPICE's error first passes "
      f"1e-6 at t = {near.time[::4][jump]:.3g} s and reaches {error.max():.2e} of the peak")
assert abs(near.time[::4][jump] - near.time[::4][worst]) < 0.05
assert cond.max() > SINGULAR_CONDITION and error.max() > 1e-6
flagged = compare(long, "fast", solvers=("spice",))
print("compare says:", flagged.singular)
assert flagged.singular
fig = Figure(figsize=(8, 5), layout="constrained")
top, bottom = fig.subplots(2, 1, sharex=True)
top.semilogy(near.time[::4], cond, color="C3")
top.axhline(SINGULAR_CONDITION, color="k", ls=":", lw=1, label=f"flagged past {SINGULAR_CONDITION:g}")
top.set_ylabel("cond(Φ_p), equilibrated")
top.legend(loc="upper right", fontsize="small")
top.grid(alpha=0.3)
bottom.semilogy(near.time[::4], np.maximum(error, 1e-12), color="C0")
bottom.axhline(1e-6, color="k", ls=":", lw=1, label="the accurate bound")
bottom.set_ylabel("SPICE error / peak")
bottom.set_xlabel("t [s]")
bottom.legend(loc="upper left", fontsize="small")
bottom.grid(alpha=0.3)
fig.suptitle("five-bar, built-in scene over 10 s: the error jumps where the loop nears a singular pose",
             fontsize="medium")
_lab.save(fig, out / "closed_chain_singular.png")
