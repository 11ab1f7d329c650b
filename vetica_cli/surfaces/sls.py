"""Zener standard linear solid (SLS): the surface of the thesis (3.2, appendix C)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ..checks import Rule, limit
from .base import DerivedKey, Quantity, SurfaceModel, register


def ratio_label(r: float) -> str:
    """``k0:k_inf`` as the thesis writes it: 16:1, 1:8."""
    return f"{r:.3g}:1" if r >= 1 else f"1:{1 / r:.3g}"


@register
class SLS(SurfaceModel):
    """Zener SLS: spring ``k_inf`` in parallel with a Maxwell arm (spring ``k0`` in series
    with dashpot ``cd``); massless, so the tip's force always balances it (thesis 3.2,
    appendix C)::

        F_on_surface = k_inf X + k0 (X - Xd)        [N]
        cd dXd/dt    = k0 (X - Xd)                  [N]

    Characteristic constants (thesis eqs. 43-44, 68, 75-76)::

        Kg    = k0 + k_inf                 glassy stiffness     [N/m]
        Kr    = k_inf                      rubbery stiffness    [N/m]
        tau_r = cd / k0                    relaxation time      [s]
        tau_c = cd Kg / (k0 k_inf)         retardation time     [s]   (tau_r = tau_c Kr / Kg)

    Under a small harmonic displacement at angular frequency ``omega`` (the
    instrument-methods comparison; :meth:`~.base.SurfaceModel.complex_stiffness`), ``x = omega tau_r``::

        k'  = k_inf + k0 x^2/(1 + x^2)     k'' = k0 x/(1 + x^2)     tan delta = k''/k'

    One Maxwell arm of the Wiechert surface.  Defaults: the thesis's
    worked example (tables 2-4): ``k_inf`` 4 N/m, ``k0`` 128 N/m, ``cd`` 3e-5 kg/s.
    """

    key = "sls"
    name = "SLS"
    references = ("thesis 3.2, appendix C", "thesis eqs. 43-44, 68, 75-76", "thesis tables 2-4 (defaults)")
    acceptance = ("tau_c", "cd")  # the acceptance regime: the cd range where tau_c is within 30 % (thesis fig. 52)
    material_columns = ("E_glassy", "E_rubbery", "viscosity")  # from Kg, Kr, tau_r (thesis 4.6.2)
    parameter_keys = ("k_inf", "k0", "cd")
    parameter_units: ClassVar[dict[str, str]] = {"k_inf": "N/m", "k0": "N/m", "cd": "kg/s"}
    parameter_labels: ClassVar[dict[str, str]] = {"k_inf": r"$k_\infty$", "k0": "$k_0$", "cd": "$c_d$"}
    parameter_axis_labels: ClassVar[dict[str, str]] = {"cd": "dashpot $c_d$"}
    defaults: ClassVar[dict[str, Any]] = {"k_inf": 4.0, "k0": 128.0, "cd": 3e-5}
    rules: ClassVar[dict[str, Rule]] = {
        "k_inf": limit("surface.k_inf"),
        "k0": limit("surface.k0"),
        "cd": limit("surface.cd"),
    }
    quantities: ClassVar[dict[str, Quantity]] = {
        "tau_c": Quantity("s", "tau_c", r"$\tau_c$", "µs", 1e6, True, "retardation time"),
        "k_g": Quantity("N/m", "Kg", r"$K_g$", description="glassy stiffness"),
        "k_r": Quantity("N/m", "Kr", r"$K_r$", plotted=False, description="rubbery stiffness"),
        "tau_r": Quantity("s", "tau_r", r"$\tau_r$", "µs", 1e6, False, "relaxation time"),
        "k0": Quantity("N/m", "k0", "$k_0$", description="Maxwell-arm spring"),
        "k_inf": Quantity("N/m", "k_inf", r"$k_\infty$", description="equilibrium spring"),
        "cd": Quantity("kg/s", "cd", "$c_d$", description="dashpot"),
    }
    fit_bounds: ClassVar[dict[str, tuple[float, float]]] = {"k_inf": (1e-4, 1e6), "k0": (1e-4, 1e6), "cd": (1e-13, 1e6)}
    derived_keys: ClassVar[dict[str, DerivedKey]] = {
        "stiffness_ratio": DerivedKey(
            "k0", "k_inf", "k0 = ratio * k_inf (thesis 4.4.2: k0:k_inf from 1:8 to 32:1 at k_inf = 4 N/m)",
            label=r"stiffness ratio $k_0:k_\infty$", short=r"$k_0:k_\infty$", fmt=ratio_label,
        )
    }  # fmt: skip
    theory_source = "SLS theory value"

    def theory(self, params: dict) -> dict[str, float]:
        """Characteristic constants (class docstring; thesis eqs. 68, 75-76)."""
        k0, k_inf, cd = params["k0"], params["k_inf"], params["cd"]
        kg = k0 + k_inf
        return {
            "tau_c": cd * kg / (k0 * k_inf),
            "k_g": kg,
            "k_r": k_inf,
            "tau_r": cd / k0,
            "k0": k0,
            "k_inf": k_inf,
            "cd": cd,
        }

    def kernel_arms(self, params: dict) -> tuple[float, np.ndarray, np.ndarray]:
        """One arm: ``(k_inf, [k0], [cd])``."""
        return float(params["k_inf"]), np.array([params["k0"]], dtype=float), np.array([params["cd"]], dtype=float)

    def log_gradients(self, params: dict) -> dict[str, tuple[float, ...]]:
        """``d ln q / d ln (k_inf, k0, cd)`` of the characteristic constants."""
        k0, k_inf = params["k0"], params["k_inf"]
        kg = k0 + k_inf
        return {
            "tau_c": (k_inf / kg - 1.0, k0 / kg - 1.0, 1.0),
            "k_g": (k_inf / kg, k0 / kg, 0.0),
            "k_r": (1.0, 0.0, 0.0),
            "tau_r": (0.0, -1.0, 1.0),
            "k0": (0.0, 1.0, 0.0),
            "k_inf": (1.0, 0.0, 0.0),
            "cd": (0.0, 0.0, 1.0),
        }

    def describe(self, params: dict) -> str:
        return "an SLS (one Maxwell arm, one relaxation time)"

    def study_title_items(self, section: dict, swept: set | frozenset = frozenset()) -> list[str]:
        """The fixed surface of a study for its figure titles: ``k_inf``, the ratio
        ``k0:k_inf`` (as the study states it, else from ``k0``) and ``cd``, each unless swept."""

        def num(k):
            v = section.get(k)
            return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None

        items = []
        k_inf, k0, ratio, cd = num("k_inf"), num("k0"), num("stiffness_ratio"), num("cd")
        if "surface.k_inf" not in swept and k_inf is not None:
            items.append(rf"$k_\infty$ {k_inf:g} N/m")
        if ratio is None and k0 and k_inf:
            ratio = k0 / k_inf
        if "surface.stiffness_ratio" not in swept and "surface.k0" not in swept and ratio:
            items.append(f"$k_0:k_\\infty$ {ratio_label(ratio)}")
        if "surface.cd" not in swept and cd is not None:
            items.append(f"$c_d$ {cd:g} kg/s")
        return items
