"""The nonlinear ODE of the UR5 and the Panda: cost per right-hand side and per whole solve, side by side.

    .venv/bin/python benchmarks/tree_ode.py [REPEATS]

Paths, each the whole of ``solve_ode`` (DOP853, rtol 1e-12, the accurate preset) on the same
system: the UR5 hanging and the Panda at a stable pose, driven by 0.5 Hz sines for 2 s.

* baseline: the previous main's code, read from git (``rigid_tree.py``, ``nonlinear.py`` and
  ``ode.py`` of the commit before ``articulated_body.py`` was added, or HEAD while it is not
  committed) and run here: M, c and G by the numpy recursions one state at a time, a solve of M'.
* numpy: this tree without Pinocchio, the forward dynamics of one kinematics pass
  (:meth:`RigidTree.forward_dynamics`).
* pinocchio: this tree as it runs with Pinocchio installed (``pinocchio.aba``).
* bare aba: ``pinocchio.aba`` in a minimal right-hand side [q̇, q̈, τ·q̇] driven by
  ``scipy.integrate.solve_ivp`` with the same method, tolerances, state and output times.

Per evaluation: the right-hand side alone at 200 states of the solution. Figures are medians
of REPEATS runs (default 5); ratios are against the bare aba. evals: scipy's count (solve_ivp's
includes its first-step probe); |Δr|/peak: the largest joint-rate difference from the
pinocchio path's run over its peak.
"""

import importlib.util
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from analogy.circuit.nonlinear import NonlinearNodeSystem, nonlinear_system
from analogy.circuit.scales import system_scales
from analogy.model.dynamics import MechanicalFunctions
from analogy.model.urdf import urdf_model
from analogy.model.urdf_robots import urdf_robot
from analogy.solvers import ode
from analogy.waveforms import Sine

ROOT = Path(__file__).resolve().parent.parent
REPEATS = int(sys.argv[1]) if len(sys.argv) > 1 else 5
RTOL, METHOD, T_STOP = 1e-12, "DOP853", 2.0
#: (q0, sine amplitudes about the holding torques G(q0)), as tests/test_urdf_nonlinear.py swings them.
SWINGS = {"ur5": ([0.0, np.pi / 2, 0.0, 0.0, 0.0, 0.0], [5.0, 10.0, 5.0, 1.0, 0.5, 0.1]),
          "panda": ([-2.58, -2.18, 0.11, 0.41, 1.8, 1.41, -2.67], [0.75, 1.5, 0.75, 0.75, 0.0, 0.0, 0.0])}


def git(*args) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True).stdout


def baseline_revision() -> str:
    added = git("log", "--diff-filter=A", "--format=%H", "--", "analogy/model/articulated_body.py").split()
    return f"{added[-1]}^" if added else "HEAD"


def baseline_modules(rev: str) -> dict:
    """The previous main's modules, loaded under other names beside this tree's."""
    out = {}
    for path in ("analogy/model/rigid_tree.py", "analogy/circuit/nonlinear.py", "analogy/solvers/ode.py"):
        package = path[:-3].replace("/", ".").rpartition(".")[0]
        name = f"{package}._baseline_{Path(path).stem}"
        module = importlib.util.module_from_spec(importlib.util.spec_from_loader(name, loader=None))
        module.__package__ = package
        sys.modules[name] = module
        exec(compile(git("show", f"{rev}:{path}"), f"{rev}:{path}", "exec"), module.__dict__)
        out[Path(path).stem] = module
    return out


def median_time(fn, repeats: int = REPEATS) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bare_aba(model, system, hold, amplitudes, times):
    """pinocchio.aba on the same state [q, q̇, W] and tolerances as solve_ode: (rhs, solve)."""
    import pinocchio as pin
    from analogy.model.articulated_body import pinocchio_model
    pm, _ = pinocchio_model(model.text, model.joint_names, None, model.tree.gravity)
    pd = pm.createData()
    n = system.dof
    damping = np.diag(system.functions.damping)
    q0 = system.q0

    def rhs(t, y):
        v = y[n:2 * n]
        tau = hold + amplitudes * np.sin(np.pi * t) - damping * v
        return np.concatenate([v, pin.aba(pm, pd, q0 + y[:n], v, tau), [v @ tau]])
    sc = system_scales(system)
    atol = RTOL * 1e-2 * np.concatenate([sc.position, sc.velocity, [sc.current * sc.peak_velocity * system.t_stop]])
    y0 = np.zeros(2 * n + 1)

    def solve():
        return solve_ivp(rhs, (0.0, system.t_stop), y0, method=METHOD, rtol=RTOL, atol=atol, t_eval=times)
    return rhs, solve


def main() -> None:
    rev = baseline_revision()
    old = baseline_modules(rev)
    print(f"baseline: {git('rev-parse', '--short', rev).strip()} ({rev}); {REPEATS} repeats; {METHOD} rtol {RTOL:g}, "
          f"t_stop {T_STOP:g} s, 1001 output points\n")
    header = f"{'robot':6} {'path':10} {'µs/eval':>9} {'×aba':>7} {'solve ms':>9} {'×aba':>7} {'evals':>6}  {'|Δr|/peak':>9}"
    print(header)
    print("-" * len(header))
    for name, (q0, amplitudes) in SWINGS.items():
        text, joints = urdf_robot(name)
        model = urdf_model(text, joints)
        q0, amplitudes = np.array(q0), np.array(amplitudes)
        hold = model.tree.gravity_load(q0)
        forces = [[Sine(float(h), a, 0.5)] for h, a in zip(hold, amplitudes)]
        system = nonlinear_system(model, q0, forces=forces, t_stop=T_STOP)
        b = system.functions.damping
        tree = old["rigid_tree"].RigidTree(model.tree.parents, model.tree.kinds, model.tree.axes,
                                           model.tree.placements, model.tree.inertias, model.tree.gravity)
        # the previous main's UrdfModel.mechanical_functions
        before = MechanicalFunctions(tree.mass_matrix, tree.velocity_load, tree.gravity_load, b, None,
                                     masses=tree.mass_matrices, gravities=tree.gravity_load)
        args = (system.q0, system.topology, system.forces, system.initial_rates, T_STOP)
        paths = {"baseline": (old["nonlinear"].NonlinearNodeSystem(before, *args), old["ode"]),
                 "numpy": (NonlinearNodeSystem(model.tree.functions(b), *args), ode),
                 "pinocchio": (system, ode)}
        times = system.time_points()
        reference = ode.solve_ode(system, times, METHOD, RTOL, positions=True)
        index = np.linspace(0, times.size - 1, 200).astype(int)
        states = np.column_stack([reference.positions[index], reference.voltages[index], reference.work[index]])
        rows = {}
        for label, (s, module) in paths.items():
            force = module._SegmentForces(s.forces)
            force.segment(0.0, T_STOP)
            rhs = module._nonlinear(s, force)[0]
            per_eval = median_time(lambda: [rhs(times[k], y) for k, y in zip(index, states)]) / len(states)
            runs = []
            whole = median_time(lambda: runs.append(module.solve_ode(s, times, METHOD, RTOL)))
            rates = runs[-1].rates
            rows[label] = (per_eval, whole, runs[-1].stats.evaluations,
                           np.abs(rates - reference.rates).max() / np.abs(reference.rates).max())
        rhs, solve = bare_aba(model, system, hold, amplitudes, times)
        per_eval = median_time(lambda: [rhs(times[k], y) for k, y in zip(index, states)]) / len(states)
        runs = []
        whole = median_time(lambda: runs.append(solve()))
        rows["bare aba"] = (per_eval, whole, runs[-1].nfev,
                            np.abs(runs[-1].y[system.dof:2 * system.dof].T - reference.rates).max()
                            / np.abs(reference.rates).max())
        base_eval, base_solve = rows["bare aba"][:2]
        for label, (e, w, nfev, diff) in rows.items():
            print(f"{name:6} {label:10} {e * 1e6:9.1f} {e / base_eval:7.2f} {w * 1e3:9.1f} {w / base_solve:7.2f} "
                  f"{nfev:6d}  {diff:9.1e}")
        print(f"{'':6} baseline/pinocchio: {rows['baseline'][0] / rows['pinocchio'][0]:.0f}× per evaluation, "
              f"{rows['baseline'][1] / rows['pinocchio'][1]:.0f}× per solve\n")


if __name__ == "__main__":
    main()
