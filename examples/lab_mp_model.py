# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: the MP (mass/pulley) model is a floating capacitor (paper Figs. 3-7, eqs. 4-8)
#
# Run as a script with `python examples/lab_mp_model.py [output-folder]`, or open it as
# a notebook (see examples/README.md).
#
# **Physics.** In the analogy force = current and velocity = voltage, a mass is a
# capacitor with one terminal on ground: Newton's law F = M·dv/dt measures the
# acceleration against the ground (an inertial frame). A capacitor, however, can
# also float between two nodes, i = C·d(v2 − v1)/dt. No plain mass does that, so
# the paper combines a mass with pulleys: the MP model.
#
# - **a.** Derive the MP model's terminal forces from its pulley kinematics (sympy).
# - **b.** In ngspice: a grounded mass loads a node driven through a damper; an MP
#   model whose other terminal is free does not (Fig. 3 vs Fig. 7).
# - **c.** Both terminals driven: the MP model carries P·d(v2 − v1)/dt.
# - **d.** Plots of b and c.
#
# Every netlist is written to the output folder (`<name>.cir`, runs in `ngspice -b`)
# together with its results (`<name>.csv`).

# %%
import csv

import _lab
import numpy as np
import sympy as sp

from analogy.circuit.netlist import analysis_lines
from analogy.presets import PRESETS
from analogy.solvers.transient import transient_settings
from analogy.circuit.nodal import nodal_analysis
from analogy.solvers.spice import run_netlist

out = _lab.output_folder()

# %% [markdown]
# ## a. The MP model's terminal forces, from its pulley kinematics
#
# All motion is along one axis, x to the right.
#
# *Fig. 4, a differential pulley:* one cable runs from terminal n1 around a pulley
# (centre x_o) to terminal n2, both runs leaving the pulley to the left. A constant
# cable length gives x_o = (x1 + x2)/2 + const (eqs. 4-5): the sum, halved. With n1
# held (v1 = 0) the pulley moves at half of v2 (eq. 6).
#
# *The MP model (Fig. 5)* makes two changes:
#
# - the run to n1 first goes around a grounded idler (at x_r) and comes back, so n1
#   pulls the other way: x_o = (x2 − x1)/2 + const;
# - a secondary cable runs from a ground anchor (x_g) around a pulley on the primary
#   pulley's axle to the mass, which therefore moves twice as far:
#   x_m = 2·x_o + const = (x2 − x1) + const.
#
# The pulleys and cables are massless, so the kinetic energy is T = ½·P·(dx_m/dt)² and
# Lagrange's equations give the terminal forces F = P·[[1, −1], [−1, 1]]·d²x/dt²,
# exactly the nodal matrix of a floating capacitor C = P (eqs. 7-8). The plain
# differential of Fig. 4 with the same secondary stage gives P·[[1, 1], [1, 1]]
# instead: moving both terminals together would accelerate the mass, so it is still
# tied to ground.

# %%
_lab.section("a. MP model: pulley kinematics -> Lagrange -> terminal forces")
t = sp.Symbol("t", real=True)
P = sp.Symbol("P", positive=True)                       # the MP model's mass
x1, x2 = sp.Function("x1", real=True)(t), sp.Function("x2", real=True)(t)
x_o, x_m = sp.symbols("x_o x_m", real=True)             # primary pulley centre, mass
L1, L2, x_r, x_g = sp.symbols("L1 L2 x_r x_g", real=True)  # cable lengths, idler, anchor


def pulley_kinematics(reversed_terminal=None):
    """x_o and x_m from constant cable lengths; *reversed_terminal* (x1, x2 or None) runs around the idler."""
    runs = []
    for x in (x1, x2):
        # A run straight to its terminal is x_o - x; around the idler it is (x_o - x_r) + (x - x_r).
        runs.append((x_o - x_r) + (x - x_r) if x is reversed_terminal else x_o - x)
    primary = sp.Eq(runs[0] + runs[1], L1)
    secondary = sp.Eq((x_o - x_g) + (x_o - x_m), L2)      # ground anchor -> pulley on x_o's axle -> mass
    solution = sp.solve([primary, secondary], [x_o, x_m], dict=True)[0]
    return solution[x_o], solution[x_m]


def terminal_matrix(mass_position):
    """A with F = P A d^2x/dt^2, from Lagrange's equations F_k = d/dt dT/dv_k - dT/dx_k."""
    v = [sp.diff(x, t) for x in (x1, x2)]
    a = sp.Matrix([sp.diff(x, t, 2) for x in (x1, x2)])
    kinetic = P / 2 * sp.diff(mass_position, t) ** 2      # massless pulleys and cables
    forces = sp.Matrix([sp.diff(sp.diff(kinetic, vk), t) - sp.diff(kinetic, xk) for xk, vk in zip((x1, x2), v)])
    matrix = forces.jacobian(a) / P
    assert sp.simplify(forces - P * matrix * a) == sp.zeros(2, 1), "F is linear in the accelerations"
    # Power in = rate of change of kinetic energy: the pulleys store and lose nothing.
    assert sp.simplify((forces.T * sp.Matrix(v))[0] - sp.diff(kinetic, t)) == 0
    return matrix


# Fig. 4 (eqs. 4-6): the plain differential averages the terminal motions.
xo_plain, xm_plain = pulley_kinematics(None)
print("Fig. 4, both runs direct:  x_o =", xo_plain)
assert sp.simplify(sp.diff(xo_plain, t) - (sp.diff(x1, t) + sp.diff(x2, t)) / 2) == 0        # eq. 5
assert sp.simplify(sp.diff(xo_plain.subs(x1, 0), t) - sp.diff(x2, t) / 2) == 0             # eq. 6: v2 = 2 v_o

# The MP model: reversed n1 gives the difference, the grounded secondary stage doubles it.
xo_mp, xm_mp = pulley_kinematics(x1)
print("MP model, n1 reversed:     x_o =", xo_mp, "   x_m =", xm_mp)
assert sp.simplify(sp.diff(xm_mp, t) - (sp.diff(x2, t) - sp.diff(x1, t))) == 0, "mass follows v2 - v1"

a_mp = terminal_matrix(xm_mp)
a_plain = terminal_matrix(xm_plain)
print("MP model:   F = P *", a_mp.tolist(), "* d2x/dt2")
print("plain pair: F = P *", a_plain.tolist(), "* d2x/dt2")

# A floating capacitor C between nodes 1 and 2, by nodal analysis: i = C [[1, -1], [-1, 1]] dv/dt.
floating_c = nodal_analysis([("C", 1, 2, P)]).C
assert P * a_mp == floating_c, "the MP model is a floating capacitor C = P (eqs. 7-8)"
# Two symmetric terminals: reversing n2 instead of n1 only flips the mass's direction.
assert terminal_matrix(pulley_kinematics(x2)[1]) == a_mp
# The plain differential is no two-terminal element: a common motion of both
# terminals (rows do not sum to zero) accelerates its mass.
assert a_plain == sp.Matrix([[1, 1], [1, 1]]) and a_plain * sp.Matrix([1, 1]) != sp.zeros(2, 1)
# Grounding terminal 1 turns the MP model into an ordinary mass on n2: F2 = P d2x2/dt2.
grounded = terminal_matrix(xm_mp.subs(x1, 0))
assert grounded == sp.Matrix([[0, 0], [0, 1]]) and P * grounded[1:, 1:] == nodal_analysis([("C", 1, 0, P)]).C
print("=> the MP model is a floating capacitor C = P; with one terminal grounded, a mass.")

# %% [markdown]
# ## Netlists by hand
#
# The next parts write small netlists directly: the elements, then the package's
# analysis lines (`.ic`, `.options`, `.tran ... uic`, `.save`) and `.end`.

# %%


def simulate(name, title, elements, t_stop, ic, save):
    """Write <name>.cir, run it in ngspice with the accurate preset, write <name>.csv; return the vectors."""
    settings = transient_settings(PRESETS["accurate"], t_stop, None)
    text = "\n".join([f"* {title}", *elements, *analysis_lines(settings, ic, save), ".end"]) + "\n"
    (out / f"{name}.cir").write_text(text)
    data = run_netlist(text)
    columns = ["time"] + sorted(k for k in data if k != "time")   # node voltages, then "<source>#branch" currents
    with open(out / f"{name}.csv", "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(columns)
        writer.writerows(zip(*(map(repr, map(float, data[k])) for k in columns)))
    print(f"{name}: {data['time'].size} time points; wrote {name}.cir and {name}.csv")
    return data


# %% [markdown]
# ## b. Fig. 3 vs Fig. 7: does a capacitor (mass or MP model) load the node n1?
#
# A velocity source (an ideal voltage source, e.g. a hand moving one end of a damper
# at a prescribed speed) drives node n0; a damper b (resistor R = 1/b) joins n0 to n1.
# We load n1 with
#
# - (i) a grounded capacitor C (a mass M = C on the link n1),
# - (ii) a floating capacitor C from n1 to a node n2 that is connected to nothing else
#   (an MP model with its other terminal free), or
# - (iii) nothing.
#
# A velocity source makes the comparison direct: an unloaded n1 simply follows it.
# With the mass, n1 lags: M·dv1/dt = b·(v0 − v1), a first-order response with time
# constant M/b. The open MP model carries no current (its free end transmits no
# force), so it cannot load n1: the cable runs freely through the pulley and the mass
# stays at rest, v2 − v1 = 0. An ordinary mass cannot be "left unconnected": that is
# the limitation of the paper's section 2.1.

# %%
_lab.section("b. loading of n1: grounded mass vs open MP model vs nothing")
b = 2.0          # damper [N s/m]   -> R = 1/b = 0.5 Ohm
mass = 1.0       # mass or MP mass [kg] -> C = 1 F
v_max, t_rise, t_stop = 1.0, 0.2, 3.0      # the source ramps to 1 m/s in 0.2 s, then holds
tau = mass / b
drive = [f"V0 n0 0 PWL(0 0 {t_rise!r} {v_max!r})", f"R1 n0 n1 {1 / b!r}"]
save = ["v(n0)", "v(n1)", "i(v0)"]
# With uic ngspice skips the DC operating point and starts from the .ic values.
# That matters for case (ii): n2 is reached only through a capacitor, so it has
# no DC path and the operating point would be singular ("check node n2"). Its
# .ic is physics, not a workaround: v2(0) - v1(0) = 0 says the MP's mass starts at rest.
mass_run = simulate("mp_grounded_mass", "Fig. 3 mechanical reading: grounded mass on n1",
                    drive + [f"C1 n1 0 {mass!r}"], t_stop, {"n1": 0.0}, save)
open_run = simulate("mp_open", "Fig. 7: MP model (floating C) from n1 to an open n2",
                    drive + [f"C12 n1 n2 {mass!r}"], t_stop, {"n1": 0.0, "n2": 0.0}, save + ["v(n2)"])
free_run = simulate("mp_unloaded", "n1 driven through the damper, nothing else",
                    drive, t_stop, {"n1": 0.0}, save)


def ramp_hold(time):
    """The source velocity v0(t)."""
    return v_max * np.minimum(time / t_rise, 1.0)


def mass_response(time):
    """v1(t) of M dv1/dt = b (v0 - v1), v1(0) = 0: a ramp through a first-order lag, then a decay."""
    during = v_max / t_rise * (time - tau * (1 - np.exp(-time / tau)))
    at_end = v_max / t_rise * (t_rise - tau * (1 - np.exp(-t_rise / tau)))
    after = v_max + (at_end - v_max) * np.exp(-(np.maximum(time, t_rise) - t_rise) / tau)
    return np.where(time <= t_rise, during, after)


peak = v_max
err_mass = np.max(np.abs(mass_run["n1"] - mass_response(mass_run["time"]))) / peak
err_open = np.max(np.abs(open_run["n1"] - ramp_hold(open_run["time"]))) / peak
err_free = np.max(np.abs(free_run["n1"] - ramp_hold(free_run["time"]))) / peak
# The unloaded v1 is piecewise linear with its corner at t_rise, a breakpoint ngspice
# steps onto, so interpolating it onto the other run's time points is exact.
free_on_open_grid = np.interp(open_run["time"], free_run["time"], free_run["n1"])
open_vs_free = np.max(np.abs(open_run["n1"] - free_on_open_grid)) / peak
mp_mass_velocity = np.max(np.abs(open_run["n2"] - open_run["n1"])) / peak
mass_vs_free = np.max(np.abs(mass_run["n1"] - ramp_hold(mass_run["time"]))) / peak
# The source's force is the current it drives into n0: -i(V0) (SPICE counts a
# source's current from its + node through the source).
force_peak = np.max(np.abs(mass_run["v0#branch"]))
open_force = np.max(np.abs(open_run["v0#branch"])) / force_peak
print(f"(i)   grounded mass: v1 vs analytic lag         max error / peak = {err_mass:.1e}")
print(f"(ii)  open MP model: v1 vs v0 (analytic)        max error / peak = {err_open:.1e}")
print(f"(iii) unloaded:      v1 vs v0 (analytic)        max error / peak = {err_free:.1e}")
print(f"open MP vs unloaded: max |v1 difference| / peak = {open_vs_free:.1e}")
print(f"open MP: mass velocity v2 - v1, max / peak      = {mp_mass_velocity:.1e}; "
      f"source force / that of case (i) = {open_force:.1e}")
print(f"grounded mass vs unloaded: max |v1 difference| / peak = {mass_vs_free:.3f} (the mass loads n1)")
assert err_mass <= 1e-6 and err_open <= 1e-6 and err_free <= 1e-6
assert open_vs_free <= 1e-6, "the open MP model does not load n1"
assert mp_mass_velocity <= 1e-6 and open_force <= 1e-6, "its mass stays at rest, the source does no work"
assert mass_vs_free >= 0.1, "a grounded mass clearly loads n1"

# %% [markdown]
# ## c. Both terminals driven: the MP model carries P·d(v2 − v1)/dt
#
# Two velocity sources move the terminals with different sines; the force each needs
# is P·d(v2 − v1)/dt (with opposite signs), read as the current through the sources.

# %%
_lab.section("c. MP model between two driven nodes")
p_mass = 1.0                                  # P [kg] = C [F]
a1, f1, a2, f2 = 1.0, 0.5, 0.7, 1.3           # v1 = a1 sin(2 pi f1 t), v2 = a2 sin(2 pi f2 t)
t_both = 2.0
# ngspice gets a capacitor's current from the trapezoidal rule, which has no damping:
# between two ideal sources the current alternates around the true value from one
# step to the next by about 1e-7 of the peak (the error plot below shows its envelope).
both = simulate("mp_driven", "MP model (floating C) between two velocity sources",
                [f"V1 n1 0 SIN(0 {a1!r} {f1!r})", f"V2 n2 0 SIN(0 {a2!r} {f2!r})", f"C12 n1 n2 {p_mass!r}"],
                t_both, {"n1": 0.0, "n2": 0.0}, ["v(n1)", "v(n2)", "i(v1)", "i(v2)"])
tb = both["time"]
w1, w2 = 2 * np.pi * f1, 2 * np.pi * f2
force = p_mass * (a2 * w2 * np.cos(w2 * tb) - a1 * w1 * np.cos(w1 * tb))     # P d(v2 - v1)/dt
force_at_n2 = -both["v2#branch"]     # V2 pushes this current into n2: the force on terminal 2
force_at_n1 = -both["v1#branch"]     # ... and V1 into n1: the reaction on terminal 1
current_peak = np.max(np.abs(force))
err_n2 = np.max(np.abs(force_at_n2 - force)) / current_peak
err_n1 = np.max(np.abs(force_at_n1 + force)) / current_peak
print(f"source current into n2 vs P d(v2 - v1)/dt: max error / peak = {err_n2:.1e}")
print(f"source current into n1 vs -P d(v2 - v1)/dt: max error / peak = {err_n1:.1e}")
assert err_n2 <= 1e-6 and err_n1 <= 1e-6

# %% [markdown]
# ## d. Plots
#
# `mp_loading.png`: the three loads of part b and their errors against the analytic
# responses. `mp_current.png`: part c, the sources' currents against P·d(v2 − v1)/dt.

# %%
fig, axes = _lab.figure(2, 1, size=(10, 7))
ax, ax_err = axes[:, 0]
ax.plot(free_run["time"], free_run["n0"], color="k", ls=":", lw=1.2, label="v0: velocity source")
ax.plot(free_run["time"], free_run["n1"], color="C0", lw=4, alpha=0.35, label="v1, (iii) unloaded")
ax.plot(open_run["time"], open_run["n1"], color="C0", ls="--", lw=1.4, label="v1, (ii) open MP model (Fig. 7)")
ax.plot(mass_run["time"], mass_run["n1"], color="C3", lw=1.4, label="v1, (i) grounded mass (Fig. 3)")
ax.plot(mass_run["time"], mass_response(mass_run["time"]), color="k", ls="--", lw=0.8,
        label=f"analytic lag, M/b = {tau} s")
ax.plot(open_run["time"], open_run["n2"] - open_run["n1"], color="C2", lw=1.2,
        label="v2 − v1: MP mass velocity in (ii)")
ax.set_ylabel("velocity [m/s] = voltage [V]")
ax.set_title("A damper drives node n1: a grounded mass loads it, an open MP model does not")
_lab.legend_outside(ax)
ax.grid(alpha=0.3)
for run, label, style in ((mass_run, "(i) grounded mass vs analytic", dict(color="C3")),
                          (open_run, "(ii) open MP vs v0", dict(color="C0", ls="--")),
                          (free_run, "(iii) unloaded vs v0", dict(color="C0", lw=3, alpha=0.35))):
    exact = mass_response(run["time"]) if run is mass_run else ramp_hold(run["time"])
    ax_err.semilogy(run["time"], np.maximum(np.abs(run["n1"] - exact) / peak, 1e-16), label=label, **style)
ax_err.axhline(1e-6, color="k", lw=0.8, ls=":", label="limit 1e-6")
ax_err.set_title("errors of exactly 0 are drawn at 1e-16", fontsize="small", loc="left")
ax_err.set_xlabel("time [s]")
ax_err.set_ylabel("|v1 − analytic| / peak [-]")
_lab.legend_outside(ax_err)
ax_err.grid(alpha=0.3)
_lab.save(fig, out / "mp_loading.png")

# %% [markdown]
# The trapezoidal rule gets a capacitor's current from the change of its voltage over
# one step, and it does not damp: between two ideal sources the current alternates
# around the true value from step to step. Drawn point by point that ringing fills the
# error panel as a solid band, so the panel shows its envelope instead: the largest
# error within each of 100 windows.

# %%
fig, axes = _lab.figure(3, 1, size=(10, 8.5))
ax_v, ax_i, ax_err = axes[:, 0]
ax_v.plot(tb, both["n1"], color="C0", label=f"v1 = {a1} sin(2π·{f1} t)")
ax_v.plot(tb, both["n2"], color="C1", label=f"v2 = {a2} sin(2π·{f2} t)")
ax_v.plot(tb, both["n2"] - both["n1"], color="C2", ls="--", label="v2 − v1: MP mass velocity")
ax_v.set_ylabel("velocity [m/s] = voltage [V]")
ax_v.set_title(f"MP model (P = {p_mass} kg) between two velocity sources")
ax_i.plot(tb, force, color="k", lw=4, alpha=0.3, label="P·d(v2 − v1)/dt, analytic")
ax_i.plot(tb, force_at_n2, color="C1", ls="--", label="current V2 drives into n2 (SPICE)")
ax_i.plot(tb, force_at_n1, color="C0", ls="--", label="current V1 drives into n1 (SPICE)")
ax_i.set_ylabel("force [N] = current [A]")
windows = 100
for error, label, style in ((np.abs(force_at_n2 - force), "at n2", dict(color="C1")),
                            (np.abs(force_at_n1 + force), "at n1", dict(color="C0", ls="--"))):
    centre, top = _lab.envelope(tb, error / current_peak, windows)
    ax_err.semilogy(centre, top, label=label, **style)
ax_err.axhline(1e-6, color="k", lw=0.8, ls=":", label="limit 1e-6")
ax_err.set_title(f"error envelope: the largest |SPICE − analytic| / peak in each of {windows} windows "
                 f"of {t_both / windows * 1e3:g} ms (trapezoidal ringing lies below it)", fontsize="small")
ax_err.set_xlabel("time [s]")
ax_err.set_ylabel("error / peak current [-]")
for a in axes[:, 0]:
    a.grid(alpha=0.3)
    _lab.legend_outside(a)
_lab.save(fig, out / "mp_current.png")
