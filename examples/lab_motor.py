# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: drive the UR5's elbow from an H-bridge — the robot as a load in a motor's circuit
#
# Run as a script with `python examples/lab_motor.py [output-folder]`, or open it as a notebook
# (see examples/README.md). It needs the `example-robot-data` package (`pip install 'analogy[robots]'`).
#
# **Physics.** A DC motor turns current into torque and speed into voltage with one constant k
# (N·m/A = V·s/rad in SI). Behind a gearbox of ratio N (the motor turns N times per joint turn)
# the joint feels the torque n·i and the winding the back-EMF n·q̇, with n = N·k. In the analogy
# (force = current, velocity = voltage) that is an **ideal transformer** of ratio n between the
# winding's loop and the joint's node. The gear also reflects the rotor: its inertia J appears at
# the joint as N²·J, a capacitor on the joint's node. So the inertia the *motor* feels is
# J + M/N²: a large gear hides the arm from the motor.
#
# **Steps**
#
# 1. The gear: the inertia the motor feels, J + M_elbow/N², and where the rotor takes over.
# 2. A step of voltage: the current's inrush (L/R) and the arm's slower response, in SPICE and exactly.
# 3. An H-bridge of four ngspice switches on the elbow: ±24 V at 2 kHz. The current ripples at the
#    carrier by about 2·V·D·(1 − D)/(L·f); the arm filters it out and moves as under the average.
# 4. The power balance: what the drive puts in is what the winding, the dampers and the stored
#    energy take.

# %%
import _lab
import numpy as np

import analogy
from analogy.model.motors import Motor
from analogy.presets import PRESETS
from analogy.solvers.drive import drive, exact_drive
from analogy.study.drive_run import run_drive

out = _lab.output_folder()
ELBOW = 2                                   # the UR5's third joint, 0-based
scene = analogy.scene("ur5").replace(parameters={"g": 0.0}, q=(0.0, -1.2, 1.5, 0.0, 0.0, 0.0), t_stop=0.3)
system = scene.system()
mass = scene.numeric_model().joint_space(scene.q).mass_matrix


def elbow_motor(gear: float) -> Motor:
    """A small DC motor: 0.6 Ω, 0.5 mH, 0.07 N·m/A, a 10 g·cm² rotor, behind a gear of ratio *gear*."""
    return Motor(resistance=0.6, inductance=5e-4, torque_constant=0.07, rotor_inertia=1e-6, gear_ratio=gear,
                 viscous=1e-6, current_limit=20.0)


def motors(gear: float) -> list:
    return [elbow_motor(gear) if j == ELBOW else None for j in range(6)]


def voltages(wave: str) -> list:
    return [wave if j == ELBOW else None for j in range(6)]


# %% [markdown]
# ## 1. The gear and the inertia the motor feels
#
# The elbow's own inertia at this pose is M_33 (the diagonal of the arm's mass matrix). Seen
# from the motor's shaft it is M_33/N²; the rotor adds its J. The two are equal at N* = √(M_33/J):
# below it the arm dominates what the motor accelerates, above it the rotor does.

# %%
_lab.section("1. The gear")
gears = np.array([1, 5, 10, 20, 50, 100, 200, 500])
felt = 1e-6 + mass[ELBOW, ELBOW] / gears ** 2
crossover = np.sqrt(mass[ELBOW, ELBOW] / 1e-6)
print(f"M_33 = {mass[ELBOW, ELBOW]:.4g} kg·m², J = 1e-6 kg·m², N* = {crossover:.0f}")
for n, j in zip(gears, felt):
    print(f"  N = {n:4d}: the motor feels {j:.3g} kg·m² ({'arm' if n < crossover else 'rotor'} dominated)")
# the armature N²·J is what the joint feels of the rotor: it equals the arm's inertia at N*
assert np.isclose(elbow_motor(crossover).armature, mass[ELBOW, ELBOW], rtol=1e-12)
fig, ((ax,),) = _lab.figure(size=(7, 4))
ax.loglog(gears, felt, "o-", label="J + M₃₃/N²")
ax.axhline(1e-6, color="0.5", ls=":", label="the rotor alone, J")
ax.axvline(crossover, color="C1", ls="--", label=f"N* = √(M₃₃/J) = {crossover:.0f}")
ax.set_xlabel("gear ratio N")
ax.set_ylabel("inertia at the motor's shaft [kg·m²]")
ax.set_title("the UR5's elbow seen from its motor")
ax.legend()
fig.savefig(out / "motor_gear.png", dpi=110)
_lab.show(out / "motor_gear.png")

# %% [markdown]
# ## 2. A step of voltage
#
# 12 V on the winding at t = 0. The current jumps toward V/R within L/R = 0.83 ms (the inductor
# holds it back only that long); the torque n·i accelerates the elbow; as it speeds up the
# back-EMF n·q̇ eats the voltage, and the current falls to what the dampers and the coupling to
# the other joints take. SPICE runs the winding's loop around the UR5's subcircuit; the exact
# solution is the matrix exponential of the whole state space.

# %%
_lab.section("2. A step of voltage, N = 100")
step = run_drive(drive(system, motors(100.0), voltages("step(12)")), PRESETS["accurate"])
print(step.table())
assert max(step.errors["spice"].values()) <= PRESETS["accurate"].bound
t, spice = step.time, step.traces["spice"]
fig, ((a, b, c),) = _lab.figure(1, 3, size=(13, 3.6))
a.plot(t * 1e3, spice.currents[:, ELBOW])
a.set_xlim(0, 10)
a.set_xlabel("t [ms]")
a.set_ylabel("winding current [A]")
a.set_title("the inrush: L/R = 0.83 ms")
b.plot(t, elbow_motor(100.0).ratio * spice.currents[:, ELBOW])
b.set_xlabel("t [s]")
b.set_ylabel("torque on the elbow n·i [N·m]")
c.plot(t, spice.rates[:, ELBOW])
c.set_xlabel("t [s]")
c.set_ylabel("elbow rate [rad/s]")
fig.savefig(out / "motor_step.png", dpi=110)
_lab.show(out / "motor_step.png")

# %% [markdown]
# ## 3. An H-bridge of four switches: ±24 V at 2 kHz, duty 0.55
#
# Four ngspice switches (`sw`) join the winding's two ends to a 24 V supply and to ground: while
# one control pulse is high, S_a and S_d put +24 V across the winding; while the other is, S_b and
# S_c put −24 V. Each closed switch is 1 mΩ, so the loop's resistance is R + 2·R_on. On average
# the winding sees (2·0.55 − 1)·24 = 2.4 V. It is an R–L circuit (τ = L/R = 0.83 ms) under a square
# wave of ±V, and the arm's back-EMF barely moves within a period, so in steady state its current
# swings by Δi = (2V/R)·(1 − e^(−DT/τ))·(1 − e^(−(1−D)T/τ))/(1 − e^(−T/τ)): the **ripple** (for
# T ≪ τ the familiar 2·V·D·(1 − D)/(L·f)). The arm, a low-pass filter far slower than 2 kHz,
# moves as under the average voltage.
#
# A switch turns where its control pulse ends its edge (1e-7 of a period), a breakpoint ngspice
# steps to, so the exact solution of the square wave with those instants judges the run. ngspice
# cannot locate a switching instant more finely than its step inside the control's edge: the
# winding's current is off by about (2V/L)·(edge), which is why the edge is that short.

# %%
_lab.section("3. The H-bridge, N = 100")
bridge = run_drive(drive(system.driven(None, 0.02), motors(100.0), voltages("hbridge(24, 0.55, 2000)")),
                   PRESETS["accurate"], ("spice", "exact"))
print(bridge.table())
assert max(bridge.errors["spice"].values()) <= PRESETS["accurate"].bound
print("the bridge in the netlist:")
print("\n".join(line for line in bridge.netlist.splitlines() if line[:2] in ("S3", "Vc", ".m", "Vb")))
t, i = bridge.time, bridge.traces["spice"].currents[:, ELBOW]
late = t > 0.015                               # past the inrush, a few periods
ripple = float(np.ptp(i[late]))
tau, period, duty = 5e-4 / (0.6 + 2e-3), 1 / 2000, 0.55
expected = (2 * 24 / (0.6 + 2e-3)) * (1 - np.exp(-duty * period / tau)) * (1 - np.exp(-(1 - duty) * period / tau)) \
    / (1 - np.exp(-period / tau))
print(f"current ripple {ripple:.4g} A; the R-L circuit's steady ripple {expected:.4g} A")
# that formula holds the back-EMF constant over a period: the elbow's rate changes by under 1% in one
assert abs(ripple - expected) < 0.02 * expected
average = drive(system.driven(None, 0.02), motors(100.0), voltages("step(2.4)"))
r_pwm, r_avg = bridge.traces["exact"].rates[:, ELBOW], exact_drive(average, t)[0][:, ELBOW]
# within a period the arm hardly feels the carrier: its rate ripples far less than the current
grid = np.linspace(0.0195, 0.02, 201)                   # the last period, 200 steps
last = exact_drive(bridge.drive, np.concatenate([[0.0], grid]))[0][1:, ELBOW]
wobble = float(np.ptp(last - np.polyval(np.polyfit(grid, last, 1), grid)) / np.max(np.abs(r_pwm)))
print(f"over the last period the elbow's rate ripples by {wobble:.3%} of its peak, its current by "
      f"{ripple / np.max(np.abs(i)):.0%} of its own")
assert wobble < 0.05 * ripple / np.max(np.abs(i))         # at least twenty times less
gap = float(np.max(np.abs(r_pwm - r_avg)[late]) / np.max(np.abs(r_avg)))
print(f"the bridge's motion and the 2.4 V average's differ by {gap:.1%} of the peak rate at 15-20 ms")
fig, ((a, b, c),) = _lab.figure(1, 3, size=(14, 3.8))
a.plot(t * 1e3, i, lw=0.8, label="H-bridge")
a.plot(t * 1e3, exact_drive(average, t)[1][:, ELBOW], label="2.4 V steady")
a.set_xlim(15, 20)
a.set_ylim(1.2 * i[late].min(), 1.2 * i[late].max())      # the carrier's swing, not the inrush
a.set_xlabel("t [ms]")
a.set_ylabel("winding current [A]")
a.set_title(f"ripple {ripple:.2f} A at 2 kHz")
a.legend()
b.plot(t * 1e3, elbow_motor(100.0).ratio * i, lw=0.8)
b.set_xlim(15, 20)
b.set_ylim(1.2 * elbow_motor(100.0).ratio * i[late].min(), 1.2 * elbow_motor(100.0).ratio * i[late].max())
b.set_xlabel("t [ms]")
b.set_ylabel("torque on the elbow n·i [N·m]")
c.plot(t * 1e3, r_pwm, label="H-bridge")
c.plot(t * 1e3, r_avg, ls="--", label="2.4 V steady")
c.set_xlabel("t [ms]")
c.set_ylabel("elbow rate [rad/s]")
c.legend()
fig.savefig(out / "motor_pwm.png", dpi=110)
_lab.show(out / "motor_pwm.png")
print(f"wrote {bridge.to_csv(out / 'motor_pwm.csv', every=20)}")

# %% [markdown]
# ## 4. Where the power goes
#
# The drive puts in Σ V·i. The winding's resistance takes R·i², its inductance stores ½·L·i², the
# arm stores ½·vᵀ·M″·v (the rotors included) and its dampers take vᵀ·B″·v. Their difference from
# the power put in is the balance's residual: zero but for the run's error and the time
# derivative's finite differences.

# %%
_lab.section("4. The power balance")
for name, run in (("step", step), ("H-bridge", bridge)):
    print(f"{name}: residual {run.balance_error():.2e} of the largest power put in "
          f"({np.max(np.abs(run.power_in())):.3g} W)")
assert step.balance_error() < 1e-5
