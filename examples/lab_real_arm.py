# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: a real arm's default experiment — where it rests, how hard to push, how long to watch
#
# Run as a script with `python examples/lab_real_arm.py [output-folder]`, or open it as a
# notebook (see examples/README.md). It needs the `example-robot-data` package
# (`pip install 'analogy[robots]'`).
#
# **Physics.** The circuit of a robot at a pose is its dynamics *linearised* there:
# M·dr/dt + B·r + K·∫r = F, with K = ∂G/∂q the stiffness gravity adds. That circuit is
# exact for small motions about an **equilibrium**, and only there means something. At a
# pose where gravity pulls the arm away (upright, say) K has a negative eigenvalue: the
# circuit holds a *negative inductor*, its motion grows as e^(σt), and after a second it
# says nothing about the arm. So a meaningful default pose is a minimum of the potential
# energy U(q) — the arm hanging — where G = ∂U/∂q = 0 and K = ∂²U/∂q² is positive
# semidefinite. Where the joint limits forbid hanging, gravity is turned off instead.
#
# **Steps**
#
# 1. The Panda upright under gravity: the growth rate of its linear circuit.
# 2. The UR5's potential energy along its shoulder: a maximum upright, a minimum hanging.
# 3. Hanging within the limits, or not: the UR5 hangs; the Panda cannot, so g = 0.
# 4. The push: a step per joint that moves that joint by about 0.1 rad over the run, against
#    its own impedance K + B/T + 2M/T²; the horizon from the slowest mode.
# 5. The default experiment in SPICE, the ODE and the exact solution, every output named
#    after its joint.

# %%
import _lab
import numpy as np

import analogy
from analogy.model.urdf import urdf_model
from analogy.model.urdf_robots import urdf_robot
from analogy.results.modes import system_poles
from analogy.scenes.robot_defaults import MOTION, growth_rate, hanging_pose, robot_defaults

out = _lab.output_folder()


def named(name: str, g: float = 9.80665):
    text, joints = urdf_robot(name)
    return urdf_model(text, joints, None, g, name)


# %% [markdown]
# ## 1. Upright is not a pose to linearise at
#
# The Panda with every joint at 0 stands straight up (its fourth joint cannot reach 0, but the
# potential does not care). There it is nearly balanced: the gravity load G(0) is a few N·m,
# which the circuit carries as constant current sources. But K = ∂G/∂q has negative
# eigenvalues. The poles of det(M·s² + B·s + K) = 0 with a positive real part are growth rates.

# %%
panda = named("panda")
upright = np.zeros(panda.dof)
joint = panda.joint_space(upright)
sigma = growth_rate(joint.mass_matrix, joint.damping, joint.stiffness)
_lab.section("Panda upright, g = 9.81 m/s²")
print(f"largest |G(0)| = {np.abs(joint.gravity).max():.3g} N·m, smallest eigenvalue of K = "
      f"{np.linalg.eigvalsh(joint.stiffness)[0]:.3g} N·m/rad")
print(f"fastest growth rate σ = {sigma:.3g} 1/s: a disturbance grows e^(σ·1 s) = {np.exp(sigma):.3g} times "
      "in a second")
assert joint.unstable and sigma > 1, "upright is an unstable equilibrium"

# %% [markdown]
# ## 2. The potential energy along the shoulder
#
# U(q) = −Σ mᵢ·g·cᵢ(q), summed over the links' centres of mass. Turning the UR5's shoulder
# (joint 2) takes the arm from horizontal through upright to hanging. Its gravity load is
# the slope of U, and its stiffness the curvature: upright is a maximum (negative
# curvature: an unstable pose), hanging a minimum.

# %%
ur5 = named("ur5")
lift = np.linspace(-np.pi, np.pi, 241)
poses = np.zeros((lift.size, ur5.dof))
poses[:, 1] = lift
energy = ur5.tree.potential_energy(poses)
rest = hanging_pose(ur5)
assert rest is not None
low, high = lift[np.argmin(energy)], lift[np.argmax(energy)]
print(f"U is least at q2 = {low:.3f} rad and largest at q2 = {high:.3f} rad; the hanging pose found has "
      f"q2 = {rest[1]:.4f} rad")
assert abs(abs(low - high) - np.pi) < 2 * (lift[1] - lift[0]), "hanging and upright are half a turn apart"

fig, axes = _lab.figure(size=(7, 3.8))
ax = axes[0, 0]
ax.plot(lift, energy - energy.min(), color="C0", lw=2, label="U(q2) − U_min (other joints at 0)")
ax.axvline(low, color="C2", ls="--", label=f"minimum: hanging (q2 = {low:.2f})")
ax.axvline(high, color="C3", ls=":", label=f"maximum: upright (q2 = {high:.2f})")
ax.set_xlabel("q2, the UR5's shoulder lift [rad]")
ax.set_ylabel("potential energy [J]")
ax.set_title("UR5: gravity's potential energy along the shoulder")
_lab.legend_outside(ax)
_lab.save(fig, out / "real_arm_potential.png")

# %% [markdown]
# ## 3. Hanging within the joint limits — or not
#
# At the UR5's hanging pose G vanishes to rounding and K is positive semidefinite: the
# circuit has inductors, no negative one. Its zero eigenvalues belong to joints whose axes
# gravity does not load (the pan, about the vertical), which stay where they are.
#
# The Panda's limits keep its shoulder within ±1.76 rad: it cannot hang. Its default is
# g = 0 with every joint at the middle of its range.

# %%
k = ur5.tree.gravity_stiffness(rest)
print(f"UR5 hanging: |G| = {np.abs(ur5.tree.gravity_load(rest)).max():.1e} N·m, eigenvalues of K from "
      f"{np.linalg.eigvalsh(k)[0]:.2e} to {np.linalg.eigvalsh(k)[-1]:.3g} N·m/rad")
assert np.linalg.eigvalsh(k)[0] >= -1e-9 * np.abs(k).max()
for name in ("ur5", "panda"):
    d = robot_defaults(named(name), label=name)
    print(f"{name}: g = {d.g:g}; {d.note.partition(': ')[2]}")
assert hanging_pose(panda) is None and robot_defaults(panda).g == 0.0

# %% [markdown]
# ## 4. How hard to push, how long to watch
#
# Over a run of length T a joint alone resists a step F with its spring K, its damper B and
# its inertia M: it moves about F/(K + B/T + 2M/T²) (a static deflection, a drift, or
# F·T²/2M from rest). The default step moves each joint by 0.1 rad that way, so that the
# nonlinear motion stays near the pose the circuit is taken at. T is three times the
# slowest period or time constant of the modes (the UR5 hanging rings; the Panda at g = 0 has only
# its dampers' slow decays, so its horizon is capped at 10 s).

# %%
rows = []
for robot, model in (("ur5", ur5), ("panda", panda)):
    d = robot_defaults(model, label=robot)
    joint = model.with_parameters({"g": d.g}).joint_space(d.q)
    m, b, kk = joint.mass_matrix, joint.damping, joint.stiffness
    kk = np.zeros_like(m) if kk is None else kk
    impedance = np.clip(np.diag(kk), 0, None) + np.diag(b) / d.t_stop + 2 * np.diag(m) / d.t_stop ** 2
    forces = np.array([float(f[5:-1]) for f in d.forces])
    periods = sorted(2 * np.pi / abs(s.imag) for s in system_poles(m, b, kk) if s.imag > 0)
    _lab.section(f"{robot} defaults: g = {d.g:g}, T = {d.t_stop:g} s (periods: "
                 f"{', '.join(f'{p:.3g}' for p in periods) or 'none'} s)")
    for name, f, z in zip(model.joint_names, forces, impedance):
        print(f"{name:<22} step {f:>9.3g} N·m  impedance {z:>9.3g} N·m/rad  moves {f / z:.3f} rad")
        rows.append((robot, name, float(f), float(z), float(f / z)))
    np.testing.assert_allclose(forces / impedance, MOTION["revolute"], rtol=0.05)     # two digits written
with (out / "real_arm_forces.csv").open("w") as fh:
    fh.write("robot,joint,step_N_m,impedance_N_m_per_rad,motion_rad\n")
    fh.writelines(f"{r},{n},{f!r},{z!r},{x!r}\n" for r, n, f, z, x in rows)

# %% [markdown]
# ## 5. The default experiment, three ways
#
# `analogy.scene("panda")` is the Panda's default experiment, as `analogy compare --robot
# panda` runs it. The table, the CSV columns and the plot name the joints.

# %%
result = analogy.compare(analogy.scene("panda").system(), "accurate")
print(result.table())
assert all(result.errors()[s][1] <= 1e-6 for s in ("spice", "ode")), "SPICE and the ODE keep accurate"
result.to_csv(out / "real_arm_panda.csv")
result.plot(out / "real_arm_panda.png")
_lab.show(out / "real_arm_panda.png")
frame = result.to_frame()
assert "panda_joint1_rate_spice" in frame.columns and frame.attrs["outputs"]["panda_joint1_rate_spice"] == "r1_spice"
