"""Wiechert (generalized Maxwell) surface: ``k_inf`` in parallel with N Maxwell arms
(thesis 5.3.2, future outlook)."""

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
    "k": ("N/m", limit("surface.arms.k")),
    "cd": ("kg/s", limit("surface.arms.cd")),
}
ITEM = re.compile(r"^arms\.(\d+)\.(\w+)$")  # surface.arms.<i>.<field>, i from 1


def arm_keys(n_arms: int) -> tuple[str, ...]:
    """The fit/result parameters of ``n_arms`` arms, in kernel order: ``k_1, cd_1, ..., k_N, cd_N``."""
    return tuple(f"{f}_{i}" for i in range(1, n_arms + 1) for f in ("k", "cd"))


@register
class Wiechert(SurfaceModel):
    """Wiechert (generalized Maxwell) surface: spring ``k_inf`` in parallel with N Maxwell
    arms ``(k_i, cd_i)``, massless like the SLS (thesis 5.3.2)::

        F_on_surface = k_inf X + sum_i k_i (X - Xd_i)              [N]
        cd_i dXd_i/dt = k_i (X - Xd_i)                             [N]

    Out of contact (surface pull on) ``X = (sum_i k_i Xd_i + Fa(d))/Kg``: the arms creep
    coupled through the massless surface (a linear system in the ``Xd_i``, advanced
    exactly through its matrix exponential).  In contact ``X = z_tip - a0`` and each arm
    relaxes on its own with ``tau_i = cd_i/k_i``.  Relaxation modulus (stiffness, thesis
    eq. 43 generalised)::

        E(t) = k_inf + sum_i k_i exp(-t/tau_i)     tau_i = cd_i / k_i      [N/m, s]
        Kg   = k_inf + sum_i k_i   (glassy)        Kr = k_inf (rubbery)    [N/m]

    Storage and loss stiffness at angular frequency ``omega``: each arm adds
    ``k_i x_i^2/(1 + x_i^2)`` and ``k_i x_i/(1 + x_i^2)``, ``x_i = omega tau_i``
    (:meth:`~.base.SurfaceModel.complex_stiffness`, the AM-AFM energy balance).

    One arm is the Zener SLS of thesis 3.2 (``k_1 = k0``, ``cd_1 = cd``).  Config::

        surface: {model: wiechert, k_inf: 4.0, arms: [{k: 64.0, cd: 3.0e-5}, {k: 32.0, cd: 1.0e-3}]}

    An arm's field is the key ``surface.arms.<i>.<k|cd>`` (``i`` from 1, as in the result
    names ``k_1, cd_1``) in ``--set``, sweeps and error messages.  Defaults: the two-arm
    example above.  Parameters (fit and result order): ``k_inf, k_1, cd_1, ..., k_N, cd_N``.
    """

    key = "wiechert"
    references = ("thesis 5.3.2 (generalized Maxwell surface)", "thesis eq. 43 (relaxation modulus, generalised)")
    material_columns = ("E_glassy", "E_rubbery", "viscosity")  # from Kg, Kr, tau_r (thesis 4.6.2)
    name = "Wiechert"
    defaults: ClassVar[dict[str, Any]] = {"k_inf": 4.0, "arms": [{"k": 64.0, "cd": 3.0e-5}, {"k": 32.0, "cd": 1.0e-3}]}
    rules: ClassVar[dict[str, Rule]] = {"k_inf": limit("surface.k_inf")}
    theory_source = "Wiechert theory value"
    item_help = "surface.arms.<i>.k, surface.arms.<i>.cd (wiechert, arm i from 1)"
    parameter_axis_labels: ClassVar[dict[str, str]] = {}

    def __init__(self, n_arms: int | None = None):
        n = len(self.defaults["arms"]) if n_arms is None else int(n_arms)
        self.n_arms = n
        arms = arm_keys(n)
        self.parameter_keys = ("k_inf", *arms)
        self.parameter_units = {"k_inf": "N/m", **{a: ARM_FIELDS[a.split("_")[0]][0] for a in arms}}
        self.parameter_labels = {"k_inf": r"$k_\infty$"}
        self.parameter_labels.update({f"k_{i}": f"$k_{i}$" for i in range(1, n + 1)})
        self.parameter_labels.update({f"cd_{i}": f"$c_{{d,{i}}}$" for i in range(1, n + 1)})
        self.parameter_axis_labels = {f"cd_{i}": f"dashpot $c_{{d,{i}}}$ of arm {i}" for i in range(1, n + 1)}
        q = {
            "k_g": Quantity("N/m", "Kg", r"$K_g$", description="glassy stiffness k_inf + sum k_i"),
            "k_r": Quantity("N/m", "Kr", r"$K_r$", plotted=False, description="rubbery stiffness k_inf"),
        }
        for i in range(1, n + 1):
            q[f"tau_{i}"] = Quantity("s", f"tau_{i}", rf"$\tau_{i}$", "µs", 1e6, False, f"relaxation time of arm {i}")
        q["k_inf"] = Quantity("N/m", "k_inf", r"$k_\infty$", description="equilibrium spring")
        for i in range(1, n + 1):
            q[f"k_{i}"] = Quantity("N/m", f"k_{i}", f"$k_{i}$", description=f"spring of arm {i}")
            q[f"cd_{i}"] = Quantity("kg/s", f"cd_{i}", f"$c_{{d,{i}}}$", description=f"dashpot of arm {i}")
        self.quantities = q
        self.fit_bounds = {p: ((1e-13, 1e6) if p.startswith("cd_") else (1e-4, 1e6)) for p in self.parameter_keys}

    # ---- config

    def parse_key(self, name: str, value: Any) -> Any:
        if name != "arms":
            return super().parse_key(name, value)
        if not isinstance(value, list) or not value or len(value) > MAX_ARMS:
            shown = f"a list of {len(value)} arms" if isinstance(value, list) and value else repr(value)
            raise ConfigError(
                f"surface.arms: {shown} is not allowed; expected a list of 1..{MAX_ARMS} arms {{k: N/m, cd: kg/s}}"
            )
        return [parse_arm(i, arm, ARM_FIELDS) for i, arm in enumerate(value, start=1)]

    def item_key(self, name: str) -> bool:
        return ITEM.match(name) is not None

    def set_items(self, values: dict, items: dict) -> dict:
        arms = copy.deepcopy(values.get("arms", self.defaults["arms"]))
        for name, value in items.items():
            m = ITEM.match(name)
            if m is None:
                raise ConfigError(f"unknown key 'surface.{name}'")
            i, field = int(m.group(1)), m.group(2)
            if field not in ARM_FIELDS:
                raise ConfigError(f"unknown key 'surface.{name}'; allowed in an arm: k, cd")
            if not 1 <= i <= len(arms):
                raise ConfigError(
                    f"surface.{name}: no arm {i}; the surface has {len(arms)} arm(s), "
                    f"surface.arms.1 .. surface.arms.{len(arms)}"
                )
            arms[i - 1][field] = parse_arm_field(i, field, value, ARM_FIELDS)
        return {**values, "arms": arms}

    def get_item(self, params: dict, name: str) -> Any:
        m = ITEM.match(name)
        arms = params.get("arms") or []
        if m is None or m.group(2) not in ARM_FIELDS or not 1 <= int(m.group(1)) <= len(arms):
            raise AttributeError(f"surface (wiechert) has no key {name!r}")
        return arms[int(m.group(1)) - 1][m.group(2)]

    def key_parameter(self, name: str):
        m = ITEM.match(name)
        if m is not None and m.group(2) in ARM_FIELDS:
            i = int(m.group(1))
            return f"{m.group(2)}_{i}", self.with_arms(max(i, self.n_arms))
        return super().key_parameter(name)

    # ---- specialisation to a number of arms

    def with_arms(self, n_arms: int) -> Wiechert:
        """The model with ``n_arms`` arms (one shared instance per number)."""
        return self if n_arms == self.n_arms else _wiechert(n_arms)

    def for_params(self, params: dict) -> Wiechert:
        return self.with_arms(len(params.get("arms") or self.defaults["arms"]))

    def from_arms(self, k_inf: float, k, cd) -> dict:
        return {"k_inf": float(k_inf), "arms": [{"k": float(a), "cd": float(b)} for a, b in zip(k, cd)]}

    def describe(self, params: dict) -> str:
        n = len(params.get("arms") or self.defaults["arms"])
        return f"a Wiechert surface with {n} Maxwell arm{'s' if n != 1 else ''} ({n} relaxation time{'s' if n != 1 else ''})"

    # ---- physics

    def theory(self, params: dict) -> dict[str, float]:
        """``Kg = k_inf + sum k_i``, ``Kr = k_inf``, ``tau_i = cd_i/k_i`` and the parameters
        (class docstring), in :attr:`quantities` order for these arms."""
        k_inf = float(params["k_inf"])
        arms = params["arms"]
        out = {"k_g": k_inf + sum(float(a["k"]) for a in arms), "k_r": k_inf}
        for i, a in enumerate(arms, start=1):
            out[f"tau_{i}"] = float(a["cd"]) / float(a["k"])
        out["k_inf"] = k_inf
        for i, a in enumerate(arms, start=1):
            out[f"k_{i}"] = float(a["k"])
            out[f"cd_{i}"] = float(a["cd"])
        return out

    def kernel_arms(self, params: dict) -> tuple[float, np.ndarray, np.ndarray]:
        arms = params["arms"]
        return (
            float(params["k_inf"]),
            np.array([a["k"] for a in arms], dtype=float),
            np.array([a["cd"] for a in arms], dtype=float),
        )

    def log_gradients(self, params: dict) -> dict[str, tuple[float, ...]]:
        """``d ln q / d ln p`` over ``(k_inf, k_1, cd_1, ..., k_N, cd_N)``:
        ``d ln Kg = (k_inf d ln k_inf + sum k_i d ln k_i)/Kg``, ``d ln tau_i = d ln cd_i - d ln k_i``."""
        keys = self.for_params(params).parameter_keys
        th = self.theory(params)
        kg = th["k_g"]

        def vec(**entries):
            return tuple(float(entries.get(k, 0.0)) for k in keys)

        out = {"k_g": vec(k_inf=th["k_inf"] / kg, **{f"k_{i}": th[f"k_{i}"] / kg for i in self._arm_range(params)})}
        out["k_r"] = vec(k_inf=1.0)
        for i in self._arm_range(params):
            out[f"tau_{i}"] = vec(**{f"k_{i}": -1.0, f"cd_{i}": 1.0})
        for p in keys:
            out[p] = vec(**{p: 1.0})
        return {q: out[q] for q in th}

    @staticmethod
    def _arm_range(params: dict) -> range:
        return range(1, len(params["arms"]) + 1)

    # ---- figure titles

    def title_items(self, params: dict, swept: set | frozenset = frozenset()) -> list[str]:
        """``k_inf`` and each arm as ``arm i: k_i, cd_i`` (matplotlib), leaving out swept keys."""
        items = []
        k_inf = params.get("k_inf")
        if "surface.k_inf" not in swept and isinstance(k_inf, (int, float)) and not isinstance(k_inf, bool):
            items.append(rf"$k_\infty$ {float(k_inf):g} N/m")
        arms = params.get("arms")
        for i, arm in enumerate(arms if isinstance(arms, list) else [], start=1):
            if not isinstance(arm, dict) or "surface.arms" in swept:
                continue
            parts = []
            for field, (unit, _) in ARM_FIELDS.items():
                v = arm.get(field)
                if f"surface.arms.{i}.{field}" in swept or isinstance(v, bool) or not isinstance(v, (int, float)):
                    continue
                parts.append(f"{float(v):g} {unit}")
            if parts:
                items.append(f"arm {i} " + ", ".join(parts))
        return items


@cache
def _wiechert(n_arms: int) -> Wiechert:
    if n_arms < 1:
        raise ValueError(f"a Wiechert surface has at least one arm, not {n_arms}")
    return Wiechert(n_arms)
