"""One design-time analysis of a linear scene: monolithic, co-simulated and compensated eigenstructure.

``analyze`` strings together ``compensation.eigenstructure.modes`` and ``compensation.eigenstructure.assignment`` for
one ``LinearModel``, one ``InterfaceModel`` and, optionally, one compensator ``Architecture``;
``Analysis.to_dict`` gives plain JSON types (complex numbers as ``[re, im]``) under the keys
``interface``, ``poles``, ``latent``, ``modal``, ``assignability`` and ``gains``.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from zencosim.compensation.eigenstructure.architecture import Architecture
from zencosim.compensation.eigenstructure.assignment import (
    Assignability,
    CompensatorDesign,
    NotAssignableError,
    design_compensator,
)
from zencosim.compensation.eigenstructure.interface import EXTRAPOLATION_ORDERS, InterfaceModel
from zencosim.compensation.eigenstructure.modes import (
    CosimEigenstructure,
    Eigenstructure,
    cosimulated_eigenstructure,
    monolithic_eigenstructure,
)
from zencosim.compensation.eigenstructure.perturbation import cosimulated_stiffness
from zencosim.compensation.linear_model import LinearModel


@dataclass(frozen=True)
class Analysis:
    """Results of ``analyze``; the compensator fields are None when no architecture was given."""

    interface: InterfaceModel
    pade_order: int
    monolithic: Eigenstructure
    cosimulated: CosimEigenstructure
    architecture: Architecture | None = None
    assignability: Assignability | None = None
    design: CompensatorDesign | None = None  # None also when the architecture is not assignable
    compensated: CosimEigenstructure | None = None

    def to_dict(self) -> dict:
        out = {
            "interface": {
                "extrapolation": EXTRAPOLATION_ORDERS[self.interface.extrapolation_order],
                "macro_step": self.interface.macro_step,
                "send_delay": self.interface.send_delay,
                "receive_delay": self.interface.receive_delay,
                "pade_order": self.pade_order,
            },
            "poles": {
                "monolithic": _pairs(self.monolithic.poles),
                "cosim_pade": _pairs(self.cosimulated.primary_pade),
                "cosim": _pairs(self.cosimulated.primary.poles),
                "compensated": _pairs(self.compensated.primary.poles) if self.compensated else None,
            },
            "latent": {
                "cosim_pade": _pairs(self.cosimulated.latent_pade),
                "compensated_pade": _pairs(self.compensated.latent_pade) if self.compensated else None,
            },
            "modal": {
                "omega_n": self.monolithic.omega_n.tolist(),
                "xi": self.monolithic.xi.tolist(),
                "cosim_e_omega_percent": self.cosimulated.e_omega.tolist(),
                "cosim_e_xi": self.cosimulated.e_xi.tolist(),
            },
            "assignability": None,
            "gains": None,
        }
        if self.assignability is not None:
            out["assignability"] = {
                "architecture": self.architecture.name,
                "rank_L": self.assignability.rank_L,
                "rank_Ln": self.assignability.rank_Ln,
                "assignable": self.assignability.assignable,
                "rtol": self.assignability.rtol,
            }
        if self.design is not None:
            out["gains"] = {
                "labels": list(self.architecture.gain_labels()),
                "d": self.design.d.tolist(),
                "f": self.design.f.tolist(),
                "g": self.design.g.tolist(),
                "rank_used": self.design.rank_used,
                "residual": self.design.residual,
                "latent_abscissa": self.design.latent_abscissa,
                "margin": self.design.margin,
                "margin_met": self.design.margin_met,
                "seed": self.design.seed,
            }
        return out


def _pairs(values: np.ndarray) -> list[list[float]]:
    return [[float(v.real), float(v.imag)] for v in np.asarray(values, dtype=complex)]


def analyze(
    model: LinearModel,
    interface: InterfaceModel,
    pade_order: int = 6,
    architecture: Architecture | None = None,
    margin: float | None = None,
    seed: int = 0,
) -> Analysis:
    """Monolithic and co-simulated eigenstructure; with ``architecture``, also the compensator and
    the compensated eigenstructure (or only the failed assignability report)."""
    monolithic = monolithic_eigenstructure(model)
    cosimulated = cosimulated_eigenstructure(cosimulated_stiffness(model), interface, pade_order, monolithic)
    result = Analysis(interface=interface, pade_order=pade_order, monolithic=monolithic, cosimulated=cosimulated)
    if architecture is None:
        return result
    try:
        design = design_compensator(model, interface, architecture, pade_order, margin, seed)
    except NotAssignableError as error:
        return replace(result, architecture=architecture, assignability=error.assignability)
    T = cosimulated_stiffness(model) + design.stiffness(model.n_dof)
    return replace(
        result,
        architecture=architecture,
        assignability=design.assignability,
        design=design,
        compensated=cosimulated_eigenstructure(T, interface, pade_order, monolithic),
    )
