"""``zencosim analyze``: the eigenstructure of a linear scene as modelled and as run (issue 5, item 7).

For one scene: the monolithic eigenstructure; the co-simulated one from the ``D(s)`` model (Padé
roots and roots polished on the exact ``D``, ``compensation.eigenstructure.analysis``); the exact discrete one of
the runtime's own scheme (``manager.analysis.discrete``); and, when the scene's structure allows one (one
force–displacement coupling, single rate), the compensator (``manager.analysis.compensator``): its
assignability, gains, the ``D(s)``-model poles of its last design and the discrete poles of the
compensated runtime. ``SceneAnalysis.to_dict`` gives the JSON documented in docs/compensation.md;
``write_pole_map`` the PNG.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from zencosim.compensation.eigenstructure.analysis import Analysis, analyze
from zencosim.compensation.eigenstructure.architecture import full_feedback, rank_one
from zencosim.compensation.eigenstructure.interface import EXTRAPOLATION_ORDERS
from zencosim.compensation.eigenstructure.modes import CosimEigenstructure, cosimulated_eigenstructure
from zencosim.compensation.eigenstructure.perturbation import cosimulated_stiffness
from zencosim.manager.analysis import compensator
from zencosim.manager.analysis.compensator import scene_compensator
from zencosim.manager.analysis.discrete import DiscreteScheme, LinearSceneError, uncompensated_scheme
from zencosim.manager.analysis.monolithic import discrete_unavailable, linear_model, linear_unavailable
from zencosim.manager.analysis.stable_step import StableStep, largest_stable_step
from zencosim.manager.scene.checks import check_compensation
from zencosim.manager.scene.load import Scene, SceneError
from zencosim.subsystems.params import Problem, Problems

COMPENSATOR_LIMIT = "compensator: built-in models only (the design needs the monolithic model M, C, K)"

# --architecture: the runtime's (Eq. 24 / 47 without the exchanged acceleration) and the two of §4.3 that
# cannot assign the eigenstructure (ranks 7 != 8 and 4 != 5 for the two-mass systems)
ARCHITECTURES = {
    "full_feedback": compensator.runtime_architecture,
    "without_exchanged_motion": lambda model: full_feedback(model, exchanged_motion=False),
    "rank_one": rank_one,
}


@dataclass(frozen=True)
class Eigenpairs:
    """Primary poles [1/s] paired with the monolithic ones (same order) and their mode shapes (columns)."""

    poles: np.ndarray
    shapes: np.ndarray


@dataclass(frozen=True)
class SceneAnalysis:
    scene: Scene
    dof_names: tuple[str, ...]  # "<subsystem>.<body>", the order of the mode shapes' entries
    model: Analysis  # D(s) model of the uncompensated scene; design fields set when compensated
    uncompensated: DiscreteScheme
    cosim_discrete: Eigenpairs
    compensator: compensator.Compensator | None = None
    compensated_model: CosimEigenstructure | None = None  # D(s) model of the compensator's last design
    compensated: Eigenpairs | None = None  # discrete, the compensated runtime
    not_compensated: str | None = None  # why there is no compensator
    stable_step: StableStep | None = None  # the largest stable macro-step, uncompensated

    @property
    def monolithic(self) -> Eigenpairs:
        return Eigenpairs(self.model.monolithic.poles, self.model.monolithic.vectors)

    def systems(self) -> dict[str, Eigenpairs]:
        """Every eigenstructure reported, monolithic first, by the key it has in ``poles``."""
        cosim = self.model.cosimulated
        result = {"monolithic": self.monolithic,
                  "cosim_pade": Eigenpairs(cosim.primary_pade, cosim.primary.vectors),
                  "cosim": Eigenpairs(cosim.primary.poles, cosim.primary.vectors),
                  "cosim_discrete": self.cosim_discrete}
        if self.compensated is not None:
            result["compensated_model"] = Eigenpairs(self.compensated_model.primary.poles,
                                                     self.compensated_model.primary.vectors)
            result["compensated"] = self.compensated
        return result

    def to_dict(self) -> dict:
        out = self.model.to_dict()
        out["poles"] = {key: _pairs(pairs.poles) for key, pairs in self.systems().items()}
        out["poles"].setdefault("compensated", None)
        out["mode_shapes"] = {key: [_pairs(w) for w in pairs.shapes.T] for key, pairs in self.systems().items()}
        reference = self.monolithic.poles
        out["modal"] = {key: modal_parameters(pairs.poles, reference) for key, pairs in self.systems().items()}
        out["scene"] = self.scene.name
        out["dof_names"] = list(self.dof_names)
        schemes = {"uncompensated": self.uncompensated,
                   "compensated": None if self.compensator is None else self.compensator.scheme}
        out["spectral_radius"] = {k: None if s is None else s.spectral_radius for k, s in schemes.items()}
        out["stable"] = {k: None if s is None else s.stable for k, s in schemes.items()}
        out["growth_rate_per_s"] = {k: None if s is None else s.growth_rate for k, s in schemes.items()}
        out["correction"] = None
        if self.compensator is not None:
            out["correction"] = {"iterations": self.compensator.iterations,
                                 "pole_error": self.compensator.pole_error,
                                 "targets": _pairs(self.compensator.targets)}
        out["not_compensated"] = self.not_compensated
        out["identification"] = {}
        out["largest_stable_step"] = None if self.stable_step is None else self.stable_step.to_dict()
        return out


@dataclass(frozen=True)
class IdentifiedAnalysis:
    """The exact discrete scheme of a scene with identified subsystems (FMUs, Python models): no monolithic model,
    no ``D(s)`` model and no compensator (``COMPENSATOR_LIMIT``); the JSON keeps ``SceneAnalysis``'s keys for what it
    has (``poles.cosim_discrete``: every pole of ``Ψ``, unpaired) and adds ``identification``."""

    scene: Scene
    uncompensated: DiscreteScheme
    stable_step: StableStep

    def systems(self) -> dict[str, Eigenpairs]:
        """The poles of the pole map: the exact discrete scheme's, every one (no mode shapes)."""
        poles = self.uncompensated.poles()
        return {"cosim_discrete": Eigenpairs(poles, np.zeros((0, poles.size)))}

    def to_dict(self) -> dict:
        scheme = self.uncompensated
        return {
            "scene": self.scene.name,
            "interface": {"extrapolation": EXTRAPOLATION_ORDERS[self.scene.manager.extrapolation],
                          "macro_step": self.scene.manager.macro_step, "period": scheme.period},
            "poles": {"cosim_discrete": _pairs(scheme.poles()), "compensated": None},
            "spectral_radius": {"uncompensated": scheme.spectral_radius, "compensated": None},
            "stable": {"uncompensated": scheme.stable, "compensated": None},
            "growth_rate_per_s": {"uncompensated": scheme.growth_rate if scheme.spectral_radius > 0.0 else None,
                                  "compensated": None},  # null: ρ = 0, no loop (JSON has no −∞)
            "correction": None,
            "not_compensated": COMPENSATOR_LIMIT,
            "identification": {i.subsystem: i.to_dict() for i in scheme.identifications},
            "largest_stable_step": self.stable_step.to_dict(),
        }


def modal_parameters(poles: np.ndarray, reference: np.ndarray) -> dict[str, list[float]]:
    """``ω_n = |λ|`` [rad/s], ``ξ = -Re λ / |λ|`` and Table 3's ``e_ω = 100 (ω̃ - ω) / ω`` [%], ``e_ξ = ξ̃ - ξ``."""
    omega, omega_ref = np.abs(poles), np.abs(reference)
    xi, xi_ref = -poles.real / omega, -reference.real / omega_ref
    return {"omega_n": omega.tolist(), "xi": xi.tolist(),
            "e_omega_percent": (100.0 * (omega - omega_ref) / omega_ref).tolist(), "e_xi": (xi - xi_ref).tolist()}


def _pairs(values: np.ndarray) -> list[list[float]]:
    return [[float(v.real), float(v.imag)] for v in np.asarray(values, dtype=complex)]


def analyze_scene(scene: Scene, architecture: str = "full_feedback", pade_order: int = compensator.PADE_ORDER
                  ) -> SceneAnalysis | IdentifiedAnalysis:
    """Analyse ``scene`` (whatever its ``manager.compensation``); ``SceneError`` for a scene whose scheme has no
    transition matrix, a subsystem that cannot be identified, or a compensator that cannot be designed. A scene with
    FMUs or Python models gives an ``IdentifiedAnalysis``."""
    reason = discrete_unavailable(scene)
    if reason:
        raise SceneError(scene.path, [Problem("scene", f"expected a linear scene for the analysis: {reason}")])
    if scene.manager.corrects:
        raise SceneError(scene.path, [Problem("manager.correction", "expected no energy correction: the exact "
                                              "discrete analysis covers the linear scheme only")])
    try:
        uncompensated = uncompensated_scheme(scene)
    except LinearSceneError as error:
        raise SceneError(scene.path, [Problem("scene", str(error))]) from None
    stable_step = largest_stable_step(scene, uncompensated)
    if linear_unavailable(scene):  # identified subsystems
        return IdentifiedAnalysis(scene, uncompensated, stable_step)
    model = linear_model(scene)
    interface = compensator.interface_of(scene)
    analysis = analyze(model, interface, pade_order)
    result = SceneAnalysis(scene, model.dof_names, analysis, uncompensated,
                           Eigenpairs(*uncompensated.primary_eigenstructure(analysis.monolithic.poles)),
                           stable_step=stable_step)
    problems = Problems()
    check_compensation(scene.manager, scene.couplings, scene.subsystems, problems)
    if problems:
        return replace(result, not_compensated="; ".join(p.reason for p in problems))
    chosen = ARCHITECTURES[architecture](model)
    corrected = scene_compensator(scene, chosen)
    design = corrected.design
    T = cosimulated_stiffness(model) + design.stiffness(model.n_dof)
    compensated_model = cosimulated_eigenstructure(T, interface, pade_order, analysis.monolithic)
    return replace(
        result,
        model=replace(analysis, architecture=chosen, assignability=design.assignability, design=design,
                      compensated=compensated_model),
        compensator=corrected,
        compensated_model=compensated_model,
        compensated=Eigenpairs(*corrected.scheme.primary_eigenstructure(analysis.monolithic.poles)),
    )


def write_pole_map(result: SceneAnalysis, path: str) -> None:
    """Primary poles in the complex plane (paper 000 Figs. 3, 7, 9): monolithic, co-simulated (``D(s)``
    model and exact discrete) and compensated (discrete)."""
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib import pyplot

    styles = {"monolithic": ("D", "monolithic"), "cosim": ("*", "co-simulated, D(s) model"),
              "cosim_discrete": ("x", "co-simulated, exact discrete"), "compensated": ("o", "compensated, exact discrete")}
    figure, axes = pyplot.subplots(figsize=(6.4, 4.8))
    systems = result.systems()
    for color, (key, (marker, label)) in enumerate((k, v) for k, v in styles.items() if k in systems):
        poles = systems[key].poles
        hollow = {"facecolors": "none", "edgecolors": f"C{color}"} if marker in "Do" else {"color": f"C{color}"}
        axes.scatter(poles.real, poles.imag, marker=marker, label=label, **hollow)
    axes.axvline(0.0, color="grey", linewidth=0.8)
    axes.set_xlabel("Re s [1/s]")
    axes.set_ylabel("Im s [rad/s]")
    axes.set_title(f"{result.scene.name}: primary poles, T_s = {result.scene.manager.macro_step:g} s")
    axes.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    pyplot.close(figure)
