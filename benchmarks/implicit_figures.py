"""The figures of docs/implicit.md (studies, not tests):

    python benchmarks/implicit_figures.py speed          # macro-steps/s of both implicit scenes, both buses
    python benchmarks/implicit_figures.py step-linear    # finite-difference step vs agreement with the recurrence
    python benchmarks/implicit_figures.py step-pendulum  # finite-difference step vs error of the derivatives
    python benchmarks/implicit_figures.py iterations     # corrector iterations vs error (double pendulum, 1 s)
    python benchmarks/implicit_figures.py pendulum       # distance from the reference, every method (0.5 s)
    python benchmarks/implicit_figures.py orders         # convergence in H of the double pendulum
    python benchmarks/implicit_figures.py global-error   # Eq. 72 of the runtime / of the recurrence study, k = 0, 1, 2
    python benchmarks/implicit_figures.py reference      # the monolithic reference against the closed form (test model)
"""
from __future__ import annotations

import argparse
import statistics

import numpy as np

from zencosim.compensation.implicit.convergence import global_error
from zencosim.compensation.implicit.coupling_laws import Baumgarte, Projection, WeightedMultiplier
from zencosim.compensation.implicit.recurrence import build_recurrence
from zencosim.compensation.implicit.two_mass_test_model import DimensionlessTwoMass, TwoMassOscillator
from zencosim.manager.assembly import build_subsystems
from zencosim.manager.results.reference import solve_ivp_reference
from zencosim.manager.run import execute
from zencosim.manager.scene.load import load_scene
from zencosim.manager.scheme.extrapolation import lagrange_coefficients
from zencosim.subsystems.inputs import InputPolynomial

H = 1e-3  # [s]
PAPER_METHODS = {"baumgarte": Baumgarte(2.0, 1.0), "weighted-multiplier": WeightedMultiplier(), "projection": Projection()}
JOINT = ("joint.x2_x", "joint.x2_y")
TOLERANCE = 1e-12  # rtol = atol of the solve_ivp reference here (the summary's default 1e-10 has a floor near 7e-10 m)
CONVERGENCE_MODEL = TwoMassOscillator(m1=1.0, m2=2.0, c1=1000.0, c2=1000.0, d1=10.0, d2=10.0)  # §3.7


def _distance(record, reference, names=JOINT) -> float:
    return max(float(np.nanmax(np.abs(record.signal(n) - reference.signals[n]))) for n in names)


def speed() -> None:
    for name, overrides, bus, repeats in (("constrained_two_mass", [], "inproc", 5), ("double_pendulum", ["manager.duration=1.0"], "inproc", 3),
                                          ("constrained_two_mass", [], "zenoh", 2), ("double_pendulum", ["manager.duration=1.0"], "zenoh", 2)):
        rates = []
        for _ in range(repeats):
            record, wall = execute(load_scene(name, overrides), bus)
            rates.append(record.plan.n_ticks / wall)
        print(f"{name:22} {bus:7} median {statistics.median(rates):6.0f} macro-steps/s over {repeats} runs")


def _test_model_overrides(model, method, decomposition, k, steps, step) -> list[str]:
    return [f"manager.duration={steps * H}", f"manager.extrapolation={k}", f"couplings.joint.decomposition={decomposition}",
            f"manager.implicit.method={method}", f"manager.implicit.mu={H}", f"manager.implicit.sensitivity_step={step}",
            f"subsystems.S2.bodies.m2.mass={model.alpha_m21}", f"subsystems.S1.effects.c1.stiffness={model.c1_bar / H ** 2}",
            f"subsystems.S1.effects.d1.damping={model.d1_bar / H}", f"subsystems.S2.effects.c2.stiffness={model.c2_bar / H ** 2}",
            f"subsystems.S2.effects.d2.damping={model.d2_bar / H}", "subsystems.S2.bodies.m2.x0=0.12", "subsystems.S2.bodies.m2.v0=3.0"]


def _states(record, variables) -> np.ndarray:
    (s1, s2), e = record.trajectories, record.implicit.coupling_variables
    columns = {"x": s1[:, 0], "x1": s1[:, 0], "v": s1[:, 1] * H, "v1": s1[:, 1] * H, "x2": s2[:, 0], "v2": s2[:, 1] * H}
    coupling = iter(e.T)
    return np.column_stack([columns[n] if n in columns else next(coupling) * H ** 2 for n in variables if not n.startswith("mu")])


def step_linear() -> None:
    """Deviation of the runtime from the recurrence (35 steps from step 5), worst of 12 cases."""
    cases = [("weighted-multiplier", "force-displacement", 0), ("weighted-multiplier", "force-force", 2),
             ("baumgarte", "force-force", 1), ("projection", "displacement-displacement", 2)]
    for step in (1e-8, 1e-6, 1e-4, 1e-2, 1.0):
        worst = 0.0
        for lambda_r1, lambda_i1 in ((-0.6, 1.0), (-0.05, 0.2), (-1.5, 1.8)):
            model = DimensionlessTwoMass.from_eigenvalues(lambda_r1, lambda_i1, 2.0, 2.0, 2.0)
            for method, decomposition, k in cases:
                recurrence = build_recurrence(PAPER_METHODS[method], decomposition, k, model)
                record = execute(load_scene("constrained_two_mass", _test_model_overrides(model, method, decomposition, k, 40, step)))[0]
                kept = [i for i, n in enumerate(recurrence.variables) if not n.startswith("mu")]
                states = _states(record, recurrence.variables)
                n = len(recurrence.variables)
                full = np.zeros((len(states), n))
                full[:, kept] = states
                history = np.concatenate([full[5 - j] for j in range(k + 1)])
                recurred = []
                for _ in range(6, len(states)):
                    history = recurrence.companion_matrix() @ history
                    recurred.append(history[:n][kept])
                worst = max(worst, np.abs(states[6:] - recurred).max() / np.abs(states[6:]).max())
        print(f"sensitivity_step {step:7.0e}: worst relative deviation from the recurrence {worst:.1e}")


def step_pendulum() -> None:
    """Forward differences of the outputs at T_{N+1} w.r.t. e*_x against a Richardson central difference."""
    for decomposition in ("force-force", "force-displacement"):
        scene = load_scene("double_pendulum", [f"couplings.joint.decomposition={decomposition}"])
        for name, sub in build_subsystems(scene).items():
            w = np.array([[5.0, 12.0]]) if sub.model.sides[0].drive == "force" else np.array([[-3.0, -8.0]])
            for j in range(400):  # a state in motion
                sub.advance(j * 1_000_000, (j + 1) * 1_000_000, InputPolynomial(w))
            saved = sub.save()
            history = np.array([w[0] * 0.98, w[0] * 0.99, w[0]])

            def outputs(candidate):
                nodes = history.copy()
                nodes[2] = candidate
                sub.restore(saved)
                coefficients = lagrange_coefficients(nodes, slice(None), 2, 1, 1_000_000, -1_000_000)
                return sub.advance(400_000_000, 401_000_000, InputPolynomial(coefficients))[:8]

            def central(d):
                return (outputs(history[2] + [d, 0.0]) - outputs(history[2] - [d, 0.0])) / (2 * d)

            reference = (4 * central(1e-3) - central(2e-3)) / 3
            scale = np.maximum(np.abs(reference), 1e-3 * np.abs(reference).max())  # rows that are not zero
            line = []
            for step in (1e-10, 1e-8, 1e-6, 1e-4, 1e-2, 1e-1):
                d = step * max(abs(history[2][0]), 1.0)
                forward = (outputs(history[2] + [d, 0.0]) - outputs(history[2])) / d
                line.append(f"{step:.0e}: {np.max(np.abs(forward - reference) / scale):.1e}")
            print(f"{decomposition:20} {name} ({sub.model.sides[0].drive}-driven)  " + "  ".join(line))


def iterations() -> None:
    reference = solve_ivp_reference(load_scene("double_pendulum", ["manager.duration=1.0"]), rtol=TOLERANCE, atol=TOLERANCE)
    for decomposition in ("force-force", "force-displacement"):
        for method in PAPER_METHODS:
            for runs, tolerance in ((1, 1e-8), (5, 1e-8), (5, 1e-10), (5, 1e-12)):
                record = execute(load_scene("double_pendulum", [
                    "manager.duration=1.0", f"couplings.joint.decomposition={decomposition}", f"manager.implicit.method={method}",
                    f"manager.implicit.max_iterations={runs}", f"manager.implicit.tolerance={tolerance}"]))[0]
                print(f"{decomposition:20} {method:20} max {runs} at {tolerance:.0e}: position {_distance(record, reference):.2e} m, "
                      f"force {_distance(record, reference, ('joint.f1_x', 'joint.f1_y')):.2e} N, "
                      f"runs per step {np.bincount(record.implicit.corrector_runs)[1:].tolist()}")


def pendulum() -> None:
    reference = solve_ivp_reference(load_scene("double_pendulum", ["manager.duration=0.5"]), rtol=TOLERANCE, atol=TOLERANCE)
    for k in (0, 1, 2):
        for decomposition in ("force-force", "force-displacement"):
            for method in PAPER_METHODS:
                record = execute(load_scene("double_pendulum", [
                    "manager.duration=0.5", f"couplings.joint.decomposition={decomposition}",
                    f"manager.implicit.method={method}", f"manager.extrapolation={k}"]))[0]
                stop = record.implicit.diverged_at
                outcome = f"diverges at {(stop + 1) * H:.3f} s" if stop is not None else f"{_distance(record, reference):.1e} m"
                print(f"k = {k} {decomposition:20} {method:20} {outcome}")


def orders() -> None:
    for decomposition, method in (("force-force", "baumgarte"), ("force-displacement", "baumgarte"), ("force-displacement", "projection")):
        for k in (0, 1):
            errors = []
            for step in (2e-3, 1e-3, 5e-4):
                scene = load_scene("double_pendulum", [
                    "manager.duration=0.5", f"manager.macro_step={step}", f"subsystems.L1.micro_step={step}",
                    f"subsystems.L2.micro_step={step}", f"manager.implicit.mu={step}", f"manager.extrapolation={k}",
                    f"couplings.joint.decomposition={decomposition}", f"manager.implicit.method={method}"])
                errors.append(_distance(execute(scene)[0], solve_ivp_reference(scene, rtol=TOLERANCE, atol=TOLERANCE)))
            slopes = np.diff(np.log(errors)) / np.log(0.5)
            print(f"{decomposition:20} {method:10} k = {k}: H = 2, 1, 0.5 ms: {['%.2e' % e for e in errors]} m, "
                  f"slopes {np.round(slopes, 2).tolist()}")


def global_error_ratio() -> None:
    """§3.7 model over 1 s: Eq. (72) of the runtime divided by that of compensation.implicit.convergence."""
    laws = {"baumgarte": Baumgarte.from_mu(5e-3), "weighted-multiplier": WeightedMultiplier(), "projection": Projection()}
    for method, law in laws.items():
        for k in (0, 1, 2):
            overrides = [f"manager.extrapolation={k}", f"manager.implicit.method={method}", "manager.implicit.mu=0.005"]
            record = execute(load_scene("constrained_two_mass", overrides))[0]
            x, v, _, _ = CONVERGENCE_MODEL.monolithic_solution(0.1, 0.0, np.arange(record.plan.n_ticks + 1) * H)
            squared = sum(np.sum((exact[1:] - trajectory[1:, column]) ** 2) / np.sum((exact[1:] - exact[1:].mean()) ** 2)
                          for trajectory in record.trajectories for column, exact in ((0, x), (1, v)))
            expected = global_error(law, "force-force", k, CONVERGENCE_MODEL, H, 1.0, 0.1, 0.0)
            print(f"{method:20} k = {k}: runtime {np.sqrt(squared):.4e}, recurrence {expected:.4e}, "
                  f"ratio {np.sqrt(squared) / expected:.4f}")


def reference() -> None:
    """The monolithic reference of constrained_two_mass against the closed-form solution (1 s)."""
    ref = solve_ivp_reference(load_scene("constrained_two_mass"), rtol=TOLERANCE, atol=TOLERANCE)
    x, v, a, force = CONVERGENCE_MODEL.monolithic_solution(0.1, 0.0, np.arange(len(ref.energy)) * H)
    for name, exact in (("joint.x1", x), ("joint.x2", x), ("joint.v1", v), ("joint.a2", a), ("joint.f1", force)):
        print(f"{name}: largest difference {np.max(np.abs(ref.signals[name] - exact)):.1e}")


STUDIES = {"speed": speed, "step-linear": step_linear, "step-pendulum": step_pendulum, "iterations": iterations,
           "pendulum": pendulum, "orders": orders, "global-error": global_error_ratio, "reference": reference}

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("study", choices=STUDIES)
    STUDIES[parser.parse_args().study]()
