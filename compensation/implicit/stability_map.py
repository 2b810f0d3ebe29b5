"""2D stability maps of the implicit co-simulation methods (paper 003, §3, Appendices A–F).

The spectral radius of the recurrence system over a grid of the eigenvalue ``lambda_r1 + i lambda_i1``
of mass 1 (Eq. 71), with the mass ratio and the eigenvalue ratios of mass 2 fixed. The paper plots
``[-2, 0] x [0, 2]`` and marks ``rho <= 1`` as stable.

Numerical resolution: at the origin both masses are free (``x'' = 0``) and the recurrence has a
defective eigenvalue 1, which float64 resolves only to about ``sqrt(eps) ~ 1e-8``; on the undamped
axis ``lambda_r1 = 0`` some methods have ``rho = 1`` up to rounding. The paper computed with 128
digits; here a point counts as stable when ``rho <= 1 + STABILITY_TOLERANCE``, far above that
rounding and far below the instabilities the paper discusses (``rho - 1`` of order 1e-3 and more).
"""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from zencosim.compensation.implicit.coupling_laws import CouplingMethod, check_supported, method_name, resolve_method
from zencosim.compensation.implicit.decompositions import Decomposition, resolve_decomposition
from zencosim.compensation.implicit.recurrence import spectral_radius
from zencosim.compensation.implicit.two_mass_test_model import DimensionlessTwoMass

STABILITY_TOLERANCE = 1e-6  # rho <= 1 + this counts as stable (module docstring)


@dataclass(frozen=True)
class StabilityMap:
    """Spectral radius over the (lambda_r1, lambda_i1) grid; ``spectral_radius[i, j]`` belongs to
    ``(lambda_r1[j], lambda_i1[i])``."""

    method: CouplingMethod
    decomposition: str
    k: int
    alpha_m21: float
    alpha_lambda_r21: float
    alpha_lambda_i21: float
    lambda_r1: np.ndarray  # (n_r,)
    lambda_i1: np.ndarray  # (n_i,)
    spectral_radius: np.ndarray  # (n_i, n_r)

    @property
    def stable(self) -> np.ndarray:
        return self.spectral_radius <= 1.0 + STABILITY_TOLERANCE

    def describe(self) -> str:
        """Method with its parameters, decomposition, k and the fixed parameters, for titles and logs."""
        options = ", ".join(f"{name} = {value:g}" for name, value in dataclasses.asdict(self.method).items())
        method = method_name(self.method) + (f" ({options})" if options else "")
        return (
            f"{method}, {self.decomposition}, k = {self.k}\n"
            f"alpha_m21 = {self.alpha_m21:g}, alpha_lambda_r21 = {self.alpha_lambda_r21:g}, "
            f"alpha_lambda_i21 = {self.alpha_lambda_i21:g}"
        )


def stability_map(
    method: str | CouplingMethod,
    decomposition: str | Decomposition,
    k: int,
    *,
    method_options: dict[str, float] | None = None,
    alpha_m21: float = 1.0,
    alpha_lambda_r21: float = 1.0,
    alpha_lambda_i21: float = 1.0,
    grid_points: int = 41,
    lambda_r1_range: tuple[float, float] = (-2.0, 0.0),
    lambda_i1_range: tuple[float, float] = (0.0, 2.0),
) -> StabilityMap:
    """Spectral radius on a ``grid_points x grid_points`` grid (Eq. 23 at every point).

    ``method`` is a name of ``implicit_coupling_laws.METHODS`` (with ``method_options`` for its
    class, in macro-step units, e.g. ``{"beta": 2.0, "gamma": 1.0}``) or an instance;
    ``decomposition`` a name of ``coupling_decompositions.DECOMPOSITIONS``. Unknown names raise
    ValueError listing the valid ones.
    """
    method = resolve_method(method, **(method_options or {}))
    decomposition = resolve_decomposition(decomposition)
    check_supported(method, decomposition)
    lambda_r1 = np.linspace(*lambda_r1_range, grid_points)
    lambda_i1 = np.linspace(*lambda_i1_range, grid_points)
    radius = np.array(
        [
            [
                spectral_radius(
                    method,
                    decomposition,
                    k,
                    DimensionlessTwoMass.from_eigenvalues(r, i, alpha_m21, alpha_lambda_r21, alpha_lambda_i21),
                )
                for r in lambda_r1
            ]
            for i in lambda_i1
        ]
    )
    return StabilityMap(
        method, decomposition.name, k, alpha_m21, alpha_lambda_r21, alpha_lambda_i21, lambda_r1, lambda_i1, radius
    )


def write_stability_map(result: StabilityMap, png_path: str | Path, json_path: str | Path | None = None) -> tuple[Path, Path]:
    """Write the map as a PNG plot and as JSON (default: the PNG path with suffix ``.json``)."""
    png_path = Path(png_path)
    json_path = png_path.with_suffix(".json") if json_path is None else Path(json_path)
    _write_png(result, png_path)
    json_path.write_text(json.dumps(_as_json(result), indent=1))
    return png_path, json_path


def _as_json(result: StabilityMap) -> dict:
    return {
        "paper": "Schweizer, Li, Lu 2015, ZAMM: implicit co-simulation methods, Sect. 3",
        "method": method_name(result.method),
        "method_parameters": dataclasses.asdict(result.method),
        "decomposition": result.decomposition,
        "k": result.k,
        "alpha_m21": result.alpha_m21,
        "alpha_lambda_r21": result.alpha_lambda_r21,
        "alpha_lambda_i21": result.alpha_lambda_i21,
        "lambda_r1": result.lambda_r1.tolist(),
        "lambda_i1": result.lambda_i1.tolist(),
        "layout": "spectral_radius[i][j] and stable[i][j] belong to (lambda_r1[j], lambda_i1[i])",
        "spectral_radius": result.spectral_radius.tolist(),
        "stability_tolerance": STABILITY_TOLERANCE,
        "stable": result.stable.tolist(),
    }


def _write_png(result: StabilityMap, png_path: Path) -> None:
    """The map as a PNG (matplotlib: zencosim[plots], imported here so that the maps compute without it)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    stable_colour, unstable_colour = "#4caf50", "#e53935"
    figure = Figure(figsize=(6.4, 5.6), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    axes.pcolormesh(
        result.lambda_r1,
        result.lambda_i1,
        (~result.stable).astype(float),
        cmap=ListedColormap([stable_colour, unstable_colour]),
        vmin=0.0,
        vmax=1.0,
        shading="nearest",
    )
    if result.stable.any() and not result.stable.all():
        axes.contour(result.lambda_r1, result.lambda_i1, result.spectral_radius, levels=[1.0 + STABILITY_TOLERANCE], colors="black", linewidths=1.0)
    axes.legend(
        handles=[
            Patch(color=stable_colour, label=f"stable, rho <= 1 (+{STABILITY_TOLERANCE:g})"),
            Patch(color=unstable_colour, label="unstable, rho > 1"),
        ],
        loc="upper left",
    )
    axes.set_xlabel("lambda_r1 (dimensionless real part, mass 1)")
    axes.set_ylabel("lambda_i1 (dimensionless imaginary part, mass 1)")
    axes.set_title(f"{result.describe()}\nmax rho = {result.spectral_radius.max():.4g}", fontsize=9)
    figure.savefig(png_path, dpi=120)
