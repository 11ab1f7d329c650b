"""Kelvin-Voigt surface: a spring in parallel with a dashpot (the worked example of
docs/extending.md: a model is this file and one registration line)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ..checks import Rule, limit
from .base import Quantity, SurfaceModel, register

STIFF_ARM = 1e6  # the dashpot's arm spring, in units of k: the arm's time constant is 1e-6 of the retardation time


@register
class KelvinVoigt(SurfaceModel):
    """Kelvin-Voigt solid: spring ``k`` in parallel with dashpot ``c``; massless, so the tip's
    force always balances it, with the van der Waals rules of the SLS (thesis 3.2, appendix C)::

        F_on_surface = k X + c dX/dt            [N]
        tau          = c / k                    retardation time [s]
        k'(w) = k,   k''(w) = w c               storage and loss stiffness [N/m]

    It creeps (retardation time ``tau``) but does not relax: no glassy stiffness, so no
    material moduli of the thesis's kind.  Kernel: the flat-punch kernel of the SLS with the
    dashpot as a Maxwell arm whose spring is ``STIFF_ARM k`` -- the Kelvin-Voigt solid is the
    SLS's limit ``k0 -> inf`` (the arm's time constant ``c/(STIFF_ARM k)``, 1e-6 of ``tau``,
    is far below any step: the exact exponential update follows the imposed motion within
    ``tau/STIFF_ARM``; out of contact ``X = (STIFF_ARM k Xd + Fa)/((1 + STIFF_ARM) k)``
    creeps with ``tau (1 + 1/STIFF_ARM)``).  Defaults: the worked example's equilibrium
    spring and dashpot (``k`` 4 N/m, ``c`` 3e-5 kg/s).
    """

    key = "kelvin-voigt"
    name = "Kelvin-Voigt"
    references = ("Kelvin-Voigt solid: Findley, Lai & Onaran 1976, ch. 5", "thesis 3.2, appendix C (the surface's rules)")
    parameter_keys = ("k", "c")
    parameter_units: ClassVar[dict[str, str]] = {"k": "N/m", "c": "kg/s"}
    parameter_labels: ClassVar[dict[str, str]] = {"k": "$k$", "c": "$c$"}
    parameter_axis_labels: ClassVar[dict[str, str]] = {"c": "dashpot $c$"}
    defaults: ClassVar[dict[str, Any]] = {"k": 4.0, "c": 3e-5}
    rules: ClassVar[dict[str, Rule]] = {"k": limit("surface.k_inf", "a stiffness"), "c": limit("surface.cd", "a dashpot")}
    quantities: ClassVar[dict[str, Quantity]] = {
        "tau": Quantity("s", "tau", r"$\tau$", "µs", 1e6, True, "retardation time c/k"),
        "k": Quantity("N/m", "k", "$k$", description="spring"),
        "c": Quantity("kg/s", "c", "$c$", description="dashpot"),
    }
    fit_bounds: ClassVar[dict[str, tuple[float, float]]] = {"k": (1e-4, 1e6), "c": (1e-13, 1e6)}
    theory_source = "Kelvin-Voigt theory value"

    def theory(self, params: dict) -> dict[str, float]:
        k, c = float(params["k"]), float(params["c"])
        return {"tau": c / k, "k": k, "c": c}

    def kernel_arms(self, params: dict) -> tuple[float, np.ndarray, np.ndarray]:
        """``(k, [STIFF_ARM k], [c])``: the dashpot on a stiff arm (class docstring)."""
        k = float(params["k"])
        return k, np.array([STIFF_ARM * k]), np.array([float(params["c"])])

    def from_arms(self, k_inf: float, k, cd) -> dict:
        return {"k": float(k_inf), "c": float(cd[0])}

    def log_gradients(self, params: dict) -> dict[str, tuple[float, ...]]:
        return {"tau": (-1.0, 1.0), "k": (1.0, 0.0), "c": (0.0, 1.0)}

    def complex_stiffness(self, params: dict, omega: float) -> tuple[float, float]:
        """``k' = k``, ``k'' = omega c`` (exact; the kernel's stiff arm differs by 1e-6)."""
        return float(params["k"]), float(omega * params["c"])

    def describe(self, params: dict) -> str:
        return "a Kelvin-Voigt solid (spring and dashpot in parallel: creep, no relaxation)"
