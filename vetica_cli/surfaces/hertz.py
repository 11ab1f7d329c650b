"""A rigid sphere (radius ``probe.tip_radius``) on a generalized-Maxwell half-space, by the
method of dimensionality reduction (MDR, Popov & Hess 2015; the thesis's outlook 5.3, "more complex linear
viscoelastic materials"); the kernel is :mod:`vetica_cli.core.mdr`."""

from __future__ import annotations

import copy
import re
from functools import cache
from typing import Any, ClassVar

import numpy as np

from ..checks import MAX_ARMS, Rule, limit
from ..errors import ConfigError
from .base import Quantity, SurfaceModel, parse_arm, parse_arm_field, register

ARM_FIELDS: dict[str, tuple[str, Rule]] = {  # field of one arm -> (unit, rule)
    "e": ("Pa", limit("surface.arms.e")),
    "tau": ("s", limit("surface.arms.tau")),
}
ITEM = re.compile(r"^arms\.(\d+)\.(\w+)$")  # surface.arms.<i>.<field>, i the list index (from 0)
MAX_ELEMENTS = 2000


def arm_keys(n_arms: int) -> tuple[str, ...]:
    """Fit/result parameters of ``n_arms`` arms: ``e_1, tau_1, ..., e_N, tau_N``."""
    return tuple(f"{f}_{i}" for i in range(1, n_arms + 1) for f in ("e", "tau"))


def _elements_ok(v) -> bool:
    return v == "auto" or (isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_ELEMENTS)


@register
class Hertz(SurfaceModel):
    """Sphere of radius ``R`` (``probe.tip_radius``) on a linear-viscoelastic half-space with
    the Young's relaxation modulus of a Prony series and Poisson ratio ``nu`` (MDR, Popov & Hess 2015; the
    thesis names such materials as its next step, 5.3)::

        E(t)  = e_inf + sum_i e_i exp(-t/tau_i)                  [Pa, s]
        E*(t) = E(t) / (1 - nu^2)
        F     = (4/3) E* sqrt(R) delta^(3/2)   (elastic limit, Hertz; a = sqrt(R delta))

    computed by the method of dimensionality reduction (Popov & Hess 2015): ``M`` elements
    at ``x_i`` (spacing ``dx``, both sides of ``x = 0`` counted: weight ``2 dx``) under the
    1-D profile ``g(x) = x^2/R``, each the Wiechert node of the Wiechert model with
    ``k_inf = E_inf* 2dx``, ``k_i = e_i* 2dx``, ``cd_i = e_i* tau_i 2dx``.  While the contact
    grows this is Lee-Radok's solution, while it shrinks Ting's; the surface left behind
    recovers element by element with its own dashpots (:mod:`vetica_cli.core.mdr`).
    Van der Waals (thesis eq. 3) acts on the tip only (``vdw_on_surface: false``, DMT).
    Config::

        surface: {model: hertz, e_inf: 5.0e8, arms: [{e: 1.5e9, tau: 1.0e-6}], nu: 0.5,
                  elements: auto, vdw_on_surface: false}

    ``elements: auto``: the fewest elements whose elastic force is within 0.1 % of Hertz at
    the deepest tap, over ``1.5 sqrt(R delta_max)`` (:func:`vetica_cli.core.mdr.auto_elements`;
    ``delta_max`` measured on a first run).  An arm's field is ``surface.arms.<i>.<e|tau>``
    with ``i`` its list index (from 0); results name them ``e_1, tau_1, ...``.
    """

    key = "hertz"
    name = "Hertz (MDR)"
    defaults: ClassVar[dict[str, Any]] = {
        "e_inf": 5.0e8,
        "arms": [{"e": 1.5e9, "tau": 1.0e-6}],
        "nu": 0.5,
        "elements": "auto",
    }
    rules: ClassVar[dict[str, Rule]] = {
        "e_inf": limit("surface.e_inf"),
        "nu": limit("surface.nu"),
    }
    common_defaults: ClassVar[dict[str, Any]] = {"vdw_on_surface": False}
    kernel_modules: ClassVar[tuple[str, ...]] = ("mdr", "tapping", "expm")
    supports: ClassVar[frozenset[str]] = frozenset({"scan", "fit"})  # no thermal recording (the flat-punch kernel's)
    extra_columns: ClassVar[tuple[str, ...]] = ("contact_radius",)
    kernel_info_key = "mdr"  # the run's metadata: its element grid
    material_columns = ("E_glassy", "E_rubbery", "viscosity")  # from Kg, Kr, tau_r (thesis 4.6.2)
    references = ("Popov & Hess 2015 (MDR)", "thesis 5.3 (outlook: more complex linear viscoelastic materials)")
    theory_source = "Prony-series modulus of the hertz surface (MDR, Popov & Hess 2015)"
    item_help = "surface.arms.<i>.e, surface.arms.<i>.tau (hertz, i the list index from 0)"

    def __init__(self, n_arms: int | None = None):
        n = len(self.defaults["arms"]) if n_arms is None else int(n_arms)
        self.n_arms = n
        arms = arm_keys(n)
        self.parameter_keys = ("e_inf", *arms)
        self.parameter_units = {"e_inf": "Pa", **{a: ARM_FIELDS[a.split("_")[0]][0] for a in arms}}
        self.parameter_labels = {"e_inf": r"$E_\infty$"}
        self.parameter_labels.update({f"e_{i}": f"$E_{i}$" for i in range(1, n + 1)})
        self.parameter_labels.update({f"tau_{i}": rf"$\tau_{i}$" for i in range(1, n + 1)})
        self.parameter_axis_labels = {f"tau_{i}": rf"relaxation time $\tau_{i}$ of arm {i}" for i in range(1, n + 1)}
        q = {
            "e_g": Quantity("Pa", "Eg", r"$E_g$", "MPa", 1e-6, description="glassy modulus e_inf + sum e_i"),
            "e_inf": Quantity("Pa", "e_inf", r"$E_\infty$", "MPa", 1e-6, description="relaxed modulus"),
        }
        for i in range(1, n + 1):
            q[f"e_{i}"] = Quantity("Pa", f"e_{i}", f"$E_{i}$", "MPa", 1e-6, description=f"modulus of arm {i}")
            q[f"tau_{i}"] = Quantity("s", f"tau_{i}", rf"$\tau_{i}$", "µs", 1e6, description=f"relaxation time of arm {i}")
        self.quantities = q
        self.fit_bounds = {p: ((1e-12, 1e3) if p.startswith("tau_") else (1e3, 1e13)) for p in self.parameter_keys}

    # ---- its kernel: the MDR elements on a grid checked at the deepest tap (.hertz_run)

    def run_kernel(self, cfg, st, spec):
        from .hertz_run import run_hertz

        rr, info = run_hertz(cfg, st, spec)
        return rr, info, None

    def line_kernel(self, cfg, st, spec):
        from .hertz_run import line_kernel

        return line_kernel(cfg, st, spec)

    def pixel_kernel_info(self, cfg, grid: dict, rr, kern) -> dict:
        """The line's grid with its elastic accuracy at the pixel's deepest tap."""
        from .hertz_run import deepest, grid_accuracy

        dmax = deepest(rr, kern.setup.a0)
        return {**grid, "delta_max_m": dmax,
                "elastic_force_error_at_delta_max": grid_accuracy(cfg.probe.tip_radius, kern.g, kern.w, dmax)
                if dmax > 0 else None}  # fmt: skip

    def kernel_of_run(self, cfg, st, run):
        from .hertz_run import kernel_of_run

        return kernel_of_run(cfg, st, run)

    # ---- config

    def parse_key(self, name: str, value: Any) -> Any:
        if name == "arms":
            if not isinstance(value, list) or not value or len(value) > MAX_ARMS:
                shown = f"a list of {len(value)} arms" if isinstance(value, list) and value else repr(value)
                raise ConfigError(
                    f"surface.arms: {shown} is not allowed; expected a list of 1..{MAX_ARMS} arms {{e: Pa, tau: s}}"
                )
            return [parse_arm(i, arm, ARM_FIELDS) for i, arm in enumerate(value)]
        if name == "elements":
            if isinstance(value, float) and value.is_integer():
                value = int(value)
            if not _elements_ok(value):
                raise ConfigError(
                    f"surface.elements: {value!r} is not allowed; expected auto or an integer 1 .. {MAX_ELEMENTS}"
                )
            return value
        return super().parse_key(name, value)

    def item_key(self, name: str) -> bool:
        m = ITEM.match(name)
        return m is not None and m.group(2) in ARM_FIELDS

    def set_items(self, values: dict, items: dict) -> dict:
        arms = copy.deepcopy(values.get("arms", self.defaults["arms"]))
        for name, value in items.items():
            m = ITEM.match(name)
            if m is None:
                raise ConfigError(f"unknown key 'surface.{name}'")
            i, field = int(m.group(1)), m.group(2)
            if field not in ARM_FIELDS:
                raise ConfigError(f"unknown key 'surface.{name}'; allowed in an arm: e, tau")
            if not 0 <= i < len(arms):
                raise ConfigError(
                    f"surface.{name}: no arm {i}; the surface has {len(arms)} arm(s), "
                    f"surface.arms.0 .. surface.arms.{len(arms) - 1}"
                )
            arms[i][field] = parse_arm_field(i, field, value, ARM_FIELDS)
        return {**values, "arms": arms}

    def get_item(self, params: dict, name: str) -> Any:
        m = ITEM.match(name)
        arms = params.get("arms") or []
        if m is None or m.group(2) not in ARM_FIELDS or not 0 <= int(m.group(1)) < len(arms):
            raise AttributeError(f"surface (hertz) has no key {name!r}")
        return arms[int(m.group(1))][m.group(2)]

    def key_parameter(self, name: str):
        m = ITEM.match(name)
        if m is not None and m.group(2) in ARM_FIELDS:
            i = int(m.group(1)) + 1
            return f"{m.group(2)}_{i}", self.with_arms(max(i, self.n_arms))
        return super().key_parameter(name)

    def check_config(self, cfg) -> None:
        """Cross-section checks: the attraction acts on the tip only."""
        if cfg.surface.vdw_on_surface:
            raise ConfigError(
                "surface.vdw_on_surface: True is not allowed for surface.model hertz; expected false "
                "(the attraction acts on the tip only, DMT)"
            )

    # ---- specialisation

    def with_arms(self, n_arms: int) -> Hertz:
        return self if n_arms == self.n_arms else _hertz(n_arms)

    def for_params(self, params: dict) -> Hertz:
        return self.with_arms(len(params.get("arms") or self.defaults["arms"]))

    def from_arms(self, k_inf: float, k, cd, nu: float | None = None) -> dict:
        """Inverse of :meth:`kernel_arms` for the Poisson ratio ``nu`` (default: the default's)."""
        nu = self.defaults["nu"] if nu is None else nu
        s = 1.0 - nu * nu
        return {
            "e_inf": float(k_inf) * s,
            "arms": [{"e": float(a) * s, "tau": float(b) / float(a)} for a, b in zip(k, cd)],
            "nu": nu,
            "elements": "auto",
        }

    def describe(self, params: dict) -> str:
        n = len(params.get("arms") or self.defaults["arms"])
        return f"a sphere on a generalized-Maxwell half-space with {n} arm{'s' if n != 1 else ''} (MDR)"

    # ---- physics

    @staticmethod
    def plane_strain(params: dict) -> tuple[float, np.ndarray, np.ndarray]:
        """``(E_inf*, e_i*, tau_i)`` with ``* = /(1 - nu^2)`` [Pa, Pa, s]."""
        s = 1.0 - float(params["nu"]) ** 2
        arms = params["arms"]
        return (
            float(params["e_inf"]) / s,
            np.array([a["e"] for a in arms], dtype=float) / s,
            np.array([a["tau"] for a in arms], dtype=float),
        )

    def theory(self, params: dict) -> dict[str, float]:
        arms = params["arms"]
        e_inf = float(params["e_inf"])
        out = {"e_g": e_inf + sum(float(a["e"]) for a in arms), "e_inf": e_inf}
        for i, a in enumerate(arms, start=1):
            out[f"e_{i}"] = float(a["e"])
            out[f"tau_{i}"] = float(a["tau"])
        return out

    def kernel_arms(self, params: dict) -> tuple[float, np.ndarray, np.ndarray]:
        """The element node per unit length: ``(E_inf*, [e_i*], [e_i* tau_i])`` [Pa, Pa, Pa s]."""
        e_inf, e, tau = self.plane_strain(params)
        return e_inf, e, e * tau

    def log_gradients(self, params: dict) -> dict[str, tuple[float, ...]]:
        keys = self.for_params(params).parameter_keys
        th = self.theory(params)
        eg = th["e_g"]

        def vec(**entries):
            return tuple(float(entries.get(k, 0.0)) for k in keys)

        n = len(params["arms"])
        out = {"e_g": vec(e_inf=th["e_inf"] / eg, **{f"e_{i}": th[f"e_{i}"] / eg for i in range(1, n + 1)})}
        for p in keys:
            out[p] = vec(**{p: 1.0})
        return {q: out[q] for q in th}

    def title_items(self, params: dict, swept: set | frozenset = frozenset()) -> list[str]:
        items = []
        e_inf = params.get("e_inf")
        if "surface.e_inf" not in swept and isinstance(e_inf, (int, float)) and not isinstance(e_inf, bool):
            items.append(rf"$E_\infty$ {float(e_inf) / 1e6:g} MPa")
        arms = params.get("arms")
        for i, arm in enumerate(arms if isinstance(arms, list) else []):
            if not isinstance(arm, dict):
                continue
            parts = []
            if f"surface.arms.{i}.e" not in swept and isinstance(arm.get("e"), (int, float)):
                parts.append(f"{float(arm['e']) / 1e6:g} MPa")
            if f"surface.arms.{i}.tau" not in swept and isinstance(arm.get("tau"), (int, float)):
                parts.append(f"{float(arm['tau']):g} s")
            if parts:
                items.append(f"arm {i + 1} " + ", ".join(parts))
        return items


@cache
def _hertz(n_arms: int) -> Hertz:
    if n_arms < 1:
        raise ValueError(f"a hertz surface has at least one arm, not {n_arms}")
    return Hertz(n_arms)
