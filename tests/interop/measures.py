"""What the interop tests measure: the analytic solution of paper 000's two_mass_damped, NRMS, the largest
difference of two trajectories, and the signals of an imported scene by the pair's names."""
from __future__ import annotations

import numpy as np

from tests.interop.peer_pair import STEPS

LIBCOSIM_NRMS = 0.045434  # issue 24: libcosim's NRMS of x2 on two_mass_damped (1 ms, ZOH, symplectic Euler)
AGREEMENT = 1e-12  # largest |zencosim - libcosim| over the signal's largest |value|, where exchange timing agrees


def analytic_x2() -> np.ndarray:
    """x2 of paper 000's two_mass_damped, exact (matrix exponential of the monolithic system), every 1 ms."""
    from scipy.linalg import expm

    k1, k2, kc, c1, c2, cc = 10.0, 1000.0, 100.0, 0.1, 0.1, 0.1
    stiffness = np.array([[k1 + kc, -kc], [-kc, k2 + kc]])
    damping = np.array([[c1 + cc, -cc], [-cc, c2 + cc]])
    system = np.zeros((4, 4))
    system[:2, 2:] = np.eye(2)
    system[2:, :2] = -stiffness  # m1 = m2 = 1 kg
    system[2:, 2:] = -damping
    step = expm(system * 1e-3)
    z = np.array([0.0, 0.0, 100.0, -100.0])
    x2 = np.empty(STEPS + 1)
    x2[0] = z[1]
    for k in range(1, STEPS + 1):
        z = step @ z
        x2[k] = z[1]
    return x2


def nrms(x: np.ndarray, reference: np.ndarray) -> float:
    """paper 000 Eq. 42, as zencosim's summary computes it."""
    return float(np.sqrt(np.mean((x - reference) ** 2)) / (np.max(reference) - np.min(reference)))


def largest_difference(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| over max |b|."""
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def coupling_of(scene) -> str:
    (name,) = scene.couplings
    return name


def zencosim_signals(result, coupling: str) -> dict[str, np.ndarray]:
    """The pair's signals as zencosim names them after an import: ``<coupling>.x`` (the motion side's
    position), ``.v``, ``.f`` (the force output)."""
    return {"x2": result.signal(f"{coupling}.x").values, "v2": result.signal(f"{coupling}.v").values,
            "fc": result.signal(f"{coupling}.f").values}
