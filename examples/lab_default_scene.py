"""Lab: the 2-DOF serial arm as a circuit, and why its MP capacitor can be negative.

Run:  python examples/lab_default_scene.py [output-folder]

1. Build the arm of the MP-model paper (eqs. 17-20) at q2 = 0.3 rad.
2. Map it to node coordinates v = T r (serial topology: v1 = r1, v2 = r1 + r2).
3. Print the circuit elements: grounded capacitors are masses, the floating
   capacitor between n1 and n2 is an MP model.
4. Simulate with SPICE, the ODE solver and the exact solver and compare.
5. Sweep q2 and plot the MP capacitance c12(q2) = -l1 l2 d2 cos(q2).
"""

import sys
from pathlib import Path

import numpy as np

import analogy

out = Path(sys.argv[1] if len(sys.argv) > 1 else "lab-output")
out.mkdir(parents=True, exist_ok=True)

scene = analogy.scene("default")
model = scene.build_model()
print("M(q) =", model.mass_matrix)

system = scene.system(model)
print("\nnode mass matrix M' = T^-T M T^-1 at q2 = 0.3:\n", system.mass)
print("\nelements:")
for e in analogy.elements(system):
    print(f"  {e.name:<6} {e.meaning:<9} {e.value:+.6f} {e.unit}")

c12 = analogy.mp_capacitance(system.mass)[0, 1]
assert c12 < 0, "for |q2| < pi/2 the MP mass opposes the relative motion of the links"

result = analogy.compare(system, "accurate")
print()
print(result.table())
result.to_csv(out / "default.csv")
result.plot(out / "default.png")
assert result.max_relative_error("spice") <= 1e-6

# Sweep the configuration: the MP capacitance crosses zero at q2 = +-pi/2.
q2 = np.linspace(-np.pi, np.pi, 181)
c = np.array([analogy.mp_capacitance(scene.replace(q=(0.0, x)).system(model).mass)[0, 1] for x in q2])
p = model.parameters
assert np.allclose(c, -p["l1"] * p["l2"] * p["d2"] * np.cos(q2), atol=1e-12)

from matplotlib.figure import Figure  # noqa: E402  (plotting only when the lab runs)

fig = Figure(figsize=(6, 3.5), layout="constrained")
ax = fig.subplots()
ax.plot(q2, c, label="c12 = -M'12 (MP model)")
ax.axhline(0, color="k", lw=0.5)
for x in (-np.pi / 2, np.pi / 2):
    ax.axvline(x, ls=":", color="gray")
ax.set_xlabel("q2 [rad]")
ax.set_ylabel("capacitance [F] = mass [kg m^2]")
ax.legend()
fig.savefig(out / "mp_capacitance_sweep.png", dpi=110)
print(f"\nwrote {out / 'default.png'}, {out / 'default.csv'} and {out / 'mp_capacitance_sweep.png'}")
