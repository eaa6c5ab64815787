# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lab: your robot as a circuit — the UR5 from its URDF file
#
# Run as a script with `python examples/lab_your_robot.py [output-folder]`, or open it as a
# notebook (see examples/README.md). It needs the `example-robot-data` package
# (`pip install 'analogy[robots]'`); for your own arm, give its file to `UrdfModel` or to
# `analogy compare --urdf my_arm.urdf`.
#
# **Physics.** A URDF file lists links (mass, centre of mass, 3-D inertia) and the joints
# between them. From that tree, the composite-rigid-body algorithm gives the joint-space
# mass matrix M(q), whose entry M_ij is the inertia joint i feels when joint j
# accelerates. In the parallel topology every joint is a node: its rate is the node
# voltage, its torque a current. The diagonal of M becomes grounded capacitors only in
# part: node i gets m'_i = Σ_j M_ij (its row sum), and each pair gets a **floating**
# capacitor p'_ij = −M_ij, the mass/pulley (MP) element that couples two joints the way the
# arm's links couple them.
#
# **Steps**
#
# 1. Load the UR5 and print M(q) at two poses: arm stretched and elbow bent.
# 2. Read the MP capacitances: how the shoulder–elbow coupling changes with the pose.
# 3. Draw the element map (six nodes are past a readable schematic).
# 4. Simulate the circuit in ngspice against the ODE and the exact solution.
# 5. Bring the wrist to its singular pose (q5 → 0) and see what M(q) and SPICE do there.
# 6. Run the arm's full nonlinear dynamics inside SPICE, with gravity, against the circuit
#    linearised at the pose it starts from.

# %%
import _lab
import numpy as np

import analogy
from analogy.circuit.element_map import draw_element_map
from analogy.model.urdf import UrdfModel
from analogy.model.urdf_robots import urdf_robot
from analogy.study.horizon import linear_horizon

out = _lab.output_folder()

# %% [markdown]
# ## 1. The mass matrix at two poses
#
# The UR5's joints: shoulder pan (about the vertical), shoulder lift and elbow (parallel
# horizontal axes), and three wrist joints. We turn gravity off (`g = 0`): held by no
# torque, a pose under gravity is an unstable equilibrium and the linear motion grows.

# %%
text, joints = urdf_robot("ur5")
model = UrdfModel(text, joints, g=0.0)
print(model.description)
stretched = [0.0, -np.pi / 2, 0.0, 0.0, np.pi / 2, 0.0]     # upper arm and forearm straight up
bent = [0.0, -1.0, 1.5, 0.0, np.pi / 2, 0.0]                 # elbow bent by 1.5 rad
m_stretched, m_bent = (model.tree.mass_matrix(q) for q in (stretched, bent))
_lab.section("M(q), arm stretched")
_lab.print_matrix("M", m_stretched)
_lab.section("M(q), elbow bent")
_lab.print_matrix("M", m_bent)
for m in (m_stretched, m_bent):
    assert np.array_equal(m, m.T) and np.linalg.eigvalsh(m)[0] > 0, "M is symmetric positive definite"
# The pan joint carries the whole arm: stretched vertically the arm is close to its axis, so
# M11 is smaller than with the elbow bent, when the forearm swings out.
assert m_bent[0, 0] > m_stretched[0, 0]
print(f"M11 (pan inertia): stretched {m_stretched[0, 0]:.4f}, bent {m_bent[0, 0]:.4f} kg·m²")

# %% [markdown]
# ## 2. The MP capacitances of the shoulder and the elbow
#
# Node 2 is the shoulder lift, node 3 the elbow. p'23 = −M23 is the floating capacitor
# between them: the forearm's inertia about the elbow, plus the part of it that the
# shoulder drags along (the term with cos q3). Bending the elbow moves the forearm's
# centre of mass closer to the shoulder, so the coupling falls.

# %%
scene = analogy.Scene.of("ur5", "ur5", q=tuple(bent), parameters={"g": 0.0}, forces=(1.0, 0.5, 0.2, 0.0, 0.0, 0.0),
                         t_stop=2.0)
system = scene.system()
_lab.section(f"node system at q = {tuple(round(x, 3) for x in bent)} (parallel topology: v = r)")
_lab.print_elements(system)
np.testing.assert_allclose(system.mass, m_bent, rtol=0, atol=1e-15 * np.abs(m_bent).max())

q3 = np.linspace(-np.pi, np.pi, 121)
poses = np.tile(bent, (q3.size, 1))
poses[:, 2] = q3
mats = model.tree.mass_matrices(poses)
grounded, floating = _lab.split(mats)
p23 = floating[1, 2]
# M23 = a + b·cos(q3) (+ a wrist part that does not depend on q3): the coupling is largest
# with the arm straight (q3 = 0) and smallest folded back (q3 = ±π)
assert np.argmin(p23) == np.argmin(np.abs(q3)), "the coupling is strongest with the forearm in line"
print(f"p'23 from {p23.min():+.4f} (q3 = 0) to {p23.max():+.4f} (q3 = ±π) F")

fig, axes = _lab.figure(size=(7, 4.2))
_lab.plot_sweep(axes[0, 0], q3, {
    "m'2 (grounded: shoulder)": (grounded[:, 1], dict(color="C0")),
    "m'3 (grounded: elbow)": (grounded[:, 2], dict(color="C1")),
    "p'23 (floating: shoulder–elbow MP)": (p23, dict(color="C3", lw=2)),
}, xlabel="q3 (elbow) [rad]", title="UR5: shoulder and elbow elements over the elbow angle", here=bent[2])
_lab.save(fig, out / "ur5_elbow_sweep.png")

# %% [markdown]
# ## 3. The element map
#
# Six nodes and their 15 pairs are past what a schematic keeps readable: the map shows
# every capacitor by node pair (red is negative), as `analogy draw --robot ur5` does.

# %%
draw_element_map(system, out / "ur5_elements.png")
_lab.show(out / "ur5_elements.png")

# %% [markdown]
# ## 4. Three solvers, one answer
#
# Step torques on the pan, the shoulder and the elbow. The exact solution is the matrix
# exponential of the linear circuit; ngspice and the ODE must agree with it to 1e-6 and
# 1e-9 of each joint's own peak.

# %%
_lab.section("SPICE vs ODE vs exact (accurate preset)")
_lab.check_solvers(system, out, "ur5")

# %% [markdown]
# ## 5. The wrist at its singular pose
#
# At q5 = 0 the UR5's first and last wrist axes line up: the arm loses a direction of
# motion of its tool, a singularity of the kinematics. The joint-space mass matrix does
# not see it. M(q) stays positive definite with a bounded condition number: every joint
# still moves its own links' inertia. So the circuit is as well posed as anywhere, and
# SPICE keeps its bound there. (The singularity lives in the Jacobian that maps joint
# rates to the tool's velocity, which the joint-space circuit never forms.)

# %%
q5 = np.linspace(0.0, np.pi / 2, 61)
poses = np.tile(bent, (q5.size, 1))
poses[:, 4] = q5
mats = model.tree.mass_matrices(poses)
eig = np.linalg.eigvalsh(mats)
cond = eig[:, -1] / eig[:, 0]
print(f"cond(M) from {cond.min():.1f} to {cond.max():.1f} over q5 in [0, π/2]; smallest eigenvalue "
      f"{eig[:, 0].min():.4f} kg·m²")
assert eig[:, 0].min() > 0 and cond.max() < 1e4, "M stays well conditioned at the wrist singularity"

fig, axes = _lab.figure(size=(7, 3.8))
ax = axes[0, 0]
ax.plot(q5, cond, color="C0", label="cond(M)")
ax.set_xlabel("q5 (wrist 2) [rad]")
ax.set_ylabel("cond(M)")
ax.set_ylim(0, 1.2 * cond.max())
ax.axvline(0.0, color="C3", ls=":", label="q5 = 0: the wrist singularity")
ax.set_title("UR5: the mass matrix does not see the wrist singularity")
_lab.legend_outside(ax)
_lab.save(fig, out / "ur5_wrist.png")

singular = scene.replace(q=tuple(bent[:4]) + (0.0, 0.0), name="ur5_singular").system()
_lab.section("SPICE vs ODE vs exact at the wrist singularity")
_lab.check_solvers(singular, out, "ur5_singular")

# %% [markdown]
# ## 6. The full nonlinear dynamics inside SPICE
#
# The linear circuit freezes the arm at one pose. The nonlinear circuit lets M(q) change
# as the arm moves: its capacitors are charge-defined, Q = c(x)·Δv, and their values are
# node voltages computed in the circuit itself. A six-joint arm's M(q) written out in
# full would be thousands of terms; instead the netlist follows the tree, one behavioural
# node per quantity: each link's rotation and position, its velocity and momentum, the
# composite inertia of the links it carries, and finally the entries M_ij as nodes
# ``m1_1 … m6_6`` that the capacitors read.
#
# Hanging down (q2 = π/2) the arm is at a stable pose under gravity. Sine torques on the
# pan and the shoulder turn the pan through 2.5 rad in a second; the shoulder swings
# 0.4 rad, and the wrist, driven by no torque, turns 1.2 rad as the arm drags it along.

# %%
hanging = (0.0, np.pi / 2, 0.0, 0.0, 0.0, 0.0)
swing = analogy.Scene.of("ur5_swing", "ur5", q=hanging, forces=("sine(0, 5, 0.5)", "sine(0, 10, 0.5)", 0, 0, 0, 0),
                         t_stop=1.0)
nonlinear = swing.replace(dynamics="nonlinear").system()
text = analogy.netlist(nonlinear, "fast")
nodes = sum(line.startswith("B") and " V={" in line for line in text.splitlines())
print(f"nonlinear netlist: {len(text.splitlines())} lines, {len(text) / 1000:.0f} kB, {nodes} behavioural nodes")
print("\n".join(line for line in text.splitlines() if line.startswith(("C2_3 ", "Bm2_3 "))))

horizon = linear_horizon(swing, "fast", ["spice"])
_lab.section("the nonlinear UR5 in SPICE, and how long the circuit linearised at q0 holds")
print(horizon.nonlinear.table())
print("\n".join(f"   {line}" for line in horizon.lines()))
assert horizon.nonlinear.errors()["spice"][1] <= analogy.PRESETS["fast"].bound
_lab.save(horizon.plot(), out / "ur5_nonlinear_linear.png")
