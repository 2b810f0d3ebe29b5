"""The component's own solver: a co-simulation FMU advances itself (``doStep``) over each micro-step.

The inputs are held at their value at the micro-step's start, as symplectic Euler and the other
integrators evaluate them there (``subsystems.models.external.fmu`` says why zencosim does not hand
the FMU the polynomial's derivatives). The state is the component's: ``z`` is empty, and saving and
restoring a subsystem goes through the component (``Subsystem.save``).
"""
from __future__ import annotations

import numpy as np

from zencosim.subsystems.inputs import InputPolynomial


class OwnSolver:
    """``model.do_step(t, h, u(τ))`` once per micro-step."""

    name = "own"
    second_order_only = False
    input_nodes = (0.0,)

    def __init__(self, model, z: np.ndarray) -> None:
        if not hasattr(model, "do_step"):
            raise ValueError(f"integrator 'own' needs a model that advances itself (a co-simulation FMU), not "
                             f"{type(model).__name__}")
        self.model = model

    def step(self, t: float, tau: float, h: float, inputs: InputPolynomial) -> None:
        self.model.do_step(t, h, inputs.at(tau))
