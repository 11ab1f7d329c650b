"""The convention every surface model follows, and the registry that collects them.

A surface model is one module (``surfaces/<key>.py``) defining a subclass of
:class:`SurfaceModel` decorated with :func:`register`, in the manner of nanite's
model modules: it declares its ``key``, ``parameter_keys`` and
``parameter_units``, carries its equation and thesis reference in its
docstring, validates its keys of the config's ``surface:`` section, gives the
theory values of the quantities an extraction reports, the fit bounds of its
parameters, the derived sweep keys it offers, and the coefficient arrays the
numba kernel needs (:meth:`SurfaceModel.kernel_arms`) or its own kernel
(:meth:`SurfaceModel.run_kernel`), what its simulation supports (thermal noise, scans,
fits), its ``references`` (where it comes from, as data) and, where it has them, its
acceptance regime and material columns.  Adding a model is adding a module and one import
line in :mod:`vetica_cli.surfaces`; :func:`register` checks its declarations
(:func:`convention_errors`) and :func:`vetica_cli.testing.check_surface_model` runs the
whole convention on it (``tests/test_registries.py`` runs it on every registered model).

The van der Waals attraction is common to every model (thesis eq. 3):
its keys (:data:`COMMON_KEYS`) live in the same ``surface:`` section.
"""

from __future__ import annotations

import copy
import inspect
import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ..checks import Rule, check, coerce, limit, positive
from ..errors import ConfigError

DEFAULT_MODEL = "sls"  # the model of a surface section without a 'model' key (every v0.1 config)


@dataclass(frozen=True)
class Quantity:
    """A quantity an extraction reports for a surface: its SI unit and how tables and figures name it."""

    unit: str  # SI unit, e.g. "N/m"
    label: str  # plain-text name for tables, e.g. "Kg"
    tex: str  # matplotlib name, e.g. r"$K_g$"
    display_unit: str = ""  # unit the figures show (default: the SI unit)
    display_scale: float = 1.0  # SI -> display factor
    plotted: bool = True  # drawn in the study figures of errors and values (thesis figs. 43-47)
    description: str = ""  # one phrase, e.g. "glassy stiffness"

    @property
    def shown_unit(self) -> str:
        return self.display_unit or self.unit


@dataclass(frozen=True)
class DerivedKey:
    """A sweep/config key that sets one model key from another: ``target = value * source``."""

    target: str  # model key it sets, e.g. "k0"
    source: str  # model key it multiplies, e.g. "k_inf"
    description: str  # e.g. "k0 = ratio * k_inf (thesis 4.4.2)"
    label: str = ""  # axis label (matplotlib)
    short: str = ""  # short label for legends (matplotlib)
    fmt: Callable[[float], str] | None = None  # how a value is written (e.g. a ratio as 16:1)


@dataclass(frozen=True)
class CommonKey:
    """A surface key every model has (the attraction of thesis eq. 3)."""

    default: Any
    type: str  # 'float' | 'bool'
    unit: str
    rule: Rule | None = None


# surface keys shared by every model: van der Waals attraction Fa(d) = H R/(6 d^2) (thesis eq. 3)
COMMON_KEYS: dict[str, CommonKey] = {
    "hamaker": CommonKey(0.2e-18, "float", "J", limit("surface.hamaker", "a Hamaker constant")),  # H
    "a0": CommonKey(0.2e-9, "float", "m", limit("surface.a0", "a distance")),  # intermolecular distance
    "vdw_on_surface": CommonKey(True, "bool", ""),  # the attraction also pulls the surface (the SLS surface model)
}


# theory values of the surface's linear response at the drive frequency and at the contact's own time
# scale (omega = pi / contact time), for the instrument's comparison methods (the AM-AFM energy balance; SurfaceModel.dynamic_theory)
DYNAMIC_QUANTITIES: dict[str, Quantity] = {
    "k_storage_drive": Quantity("N/m", "k' (drive)", r"$k'(\omega_d)$", description="storage stiffness at the drive frequency"),
    "k_loss_drive": Quantity("N/m", "k'' (drive)", r"$k''(\omega_d)$", description="loss stiffness at the drive frequency"),
    "tan_delta_drive": Quantity("", "tan d (drive)", r"$\tan\delta(\omega_d)$",
                                description="loss tangent k''/k' at the drive frequency"),
    "k_storage_contact": Quantity("N/m", "k' (contact)", r"$k'(\pi/t_c)$",
                                  description="storage stiffness at pi / contact time"),
    "k_loss_contact": Quantity("N/m", "k'' (contact)", r"$k''(\pi/t_c)$", description="loss stiffness at pi / contact time"),
    "tan_delta_contact": Quantity("", "tan d (contact)", r"$\tan\delta(\pi/t_c)$",
                                  description="loss tangent at pi / contact time"),
    "e_storage_drive": Quantity("Pa", "E*' (drive)", r"$E^{*\prime}(\omega_d)$",
                                description="reduced storage modulus at the drive frequency (models with moduli)"),
    "e_loss_drive": Quantity("Pa", "E*'' (drive)", r"$E^{*\prime\prime}(\omega_d)$",
                             description="reduced loss modulus at the drive frequency (models with moduli)"),
    "e_storage_contact": Quantity("Pa", "E*' (contact)", r"$E^{*\prime}(\pi/t_c)$",
                                  description="reduced storage modulus at pi / contact time (models with moduli)"),
    "e_loss_contact": Quantity("Pa", "E*'' (contact)", r"$E^{*\prime\prime}(\pi/t_c)$",
                               description="reduced loss modulus at pi / contact time (models with moduli)"),
}  # fmt: skip


class SurfaceModel(ABC):
    """Base of every surface model (one subclass per module; see the module docstring).

    Subclasses set the class attributes and implement :meth:`theory`,
    :meth:`kernel_arms` and :meth:`log_gradients`.  ``params`` is always the
    dict :meth:`parse` returns (SI values keyed by the model's config keys).
    """

    key: ClassVar[str]  # the surface.model value, e.g. "sls"
    name: ClassVar[str]  # short name for titles and units, e.g. "SLS"
    parameter_keys: ClassVar[tuple[str, ...]]  # fitted/physical parameters, e.g. ("k_inf", "k0", "cd")
    parameter_units: ClassVar[dict[str, str]]
    parameter_labels: ClassVar[dict[str, str]]  # matplotlib labels of the parameters
    parameter_axis_labels: ClassVar[dict[str, str]] = {}  # longer axis labels where they differ
    defaults: ClassVar[dict[str, Any]]  # default value of every config key of the model
    rules: ClassVar[dict[str, Rule]]  # scalar config key -> (predicate, what is allowed)
    quantities: ClassVar[dict[str, Quantity]]  # what an extraction reports, in table order
    fit_bounds: ClassVar[dict[str, tuple[float, float]]]  # parameter -> (lower, upper) [SI]
    derived_keys: ClassVar[dict[str, DerivedKey]] = {}  # e.g. stiffness_ratio -> k0 = ratio * k_inf
    theory_source: ClassVar[str]  # what the theory values are, for the table units
    item_help: ClassVar[str] = ""  # the dotted item keys (item_key), for messages, e.g. "surface.arms.<i>.cd"
    common_defaults: ClassVar[dict[str, Any]] = {}  # COMMON_KEYS defaults the model changes (hertz: no pull on the surface)
    kernel_modules: ClassVar[tuple[str, ...]] = ("tapping", "expm")  # cached core modules its simulation compiles
    supports: ClassVar[frozenset[str]] = frozenset({"thermal", "scan", "fit"})  # what its simulation offers
    # (SUPPORTS: thermal noise in the recorded window, pixels of a raster scan, the whole-cycle fit of its records)
    extra_columns: ClassVar[tuple[str, ...]] = ()  # recorded columns after the dashpots (hertz: contact_radius)
    kernel_info_key: ClassVar[str] = "kernel_grid"  # the run's metadata key of its kernel's info (run_kernel)
    references: ClassVar[tuple[str, ...]] = ()  # where the model and its equations come from (thesis section, paper)
    acceptance: ClassVar[tuple[str, str] | None] = None  # (quantity, swept parameter) of the acceptance regime
    # the thesis's material columns (4.6.2, from Kg, Kr, tau_r) a study table of this model carries
    # besides E_dmt (none by default; the SLS family declares E_glassy, E_rubbery, viscosity)
    material_columns: ClassVar[tuple[str, ...]] = ()

    # ---- the model's own kernel (PyBaMM's BaseModel carries its default solver): the simulation,
    # the scan and the bench ask the model, never which model it is

    def run_kernel(self, cfg, st, spec):
        """Run the kernel of a resolved config ``cfg`` to its steady state (``st``: the kernel
        setup, ``spec``: the run's :class:`~vetica_cli.core.engine.RunSpec`): ``(RunResult, info
        for the run's metadata or None, kernel or None)``; the kernel (for the thermal recording
        of the window) is None when the model does not support ``thermal``.  Default: the
        flat-punch kernel of :meth:`kernel_arms` (:mod:`vetica_cli.core.tapping`)."""
        from ..core import engine

        kern = engine.Kernel(st)
        return engine.run(kern, spec), None, kern

    def line_kernel(self, cfg, st, spec):
        """The kernel of a scan's pixels of this model, ``(kernel, grid info or None)``."""
        from ..core import engine

        return engine.Kernel(st), None

    def pixel_kernel_info(self, cfg, grid: dict, rr, kern) -> dict:
        """A scan pixel's kernel info (its :meth:`line_kernel` grid info judged on the pixel's
        run ``rr``); default: the grid info as it is."""
        return dict(grid)

    def kernel_of_run(self, cfg, st, run):
        """The kernel a finished run used (``vetica bench`` times one period on it)."""
        from ..core import engine

        return engine.Kernel(st)

    def supports_key(self, what: str) -> bool:
        """Whether the model's simulation offers ``what`` (:attr:`supports`)."""
        return what in self.supports

    @property
    def config_keys(self) -> tuple[str, ...]:
        """The model's keys of the ``surface:`` section (besides ``model`` and :data:`COMMON_KEYS`)."""
        return tuple(self.defaults)

    def parse_key(self, name: str, value: Any) -> Any:
        """One config key's value, coerced and checked (ConfigError names ``surface.<name>``).
        Default: a finite number that satisfies ``rules[name]``; a model with
        non-scalar keys (a list of arms) overrides this."""
        key = f"surface.{name}"
        return check(key, value, coerce(key, value, "float"), self.rules.get(name))

    def complete(self, values: dict) -> dict:
        """The full parameter dict: ``values`` (already parsed) with defaults for the missing
        keys, in declaration order; cross-key checks raise ConfigError."""
        return {k: values[k] if k in values else copy.deepcopy(d) for k, d in self.defaults.items()}

    def parse(self, raw: dict) -> dict:
        """Validated parameters from the model's keys of a ``surface:`` section."""
        return self.complete({name: self.parse_key(name, value) for name, value in raw.items()})

    @abstractmethod
    def theory(self, params: dict) -> dict[str, float]:
        """Theory value of every quantity in :attr:`quantities` [SI]."""

    @abstractmethod
    def kernel_arms(self, params: dict) -> tuple[float, np.ndarray, np.ndarray]:
        """The surface for the numba kernel: ``(k_inf [N/m], k [N/m] per Maxwell arm,
        cd [kg/s] per arm)``; ``k`` and ``cd`` are float arrays of equal length >= 1."""

    @abstractmethod
    def log_gradients(self, params: dict) -> dict[str, tuple[float, ...]]:
        """``d ln q / d ln p`` for every quantity q, p over :attr:`parameter_keys` in order
        (propagates a fit's covariance of the log-parameters to every quantity)."""

    def title_items(self, params: dict, swept: set | frozenset = frozenset()) -> list[str]:
        """The surface's parameters for a figure title (matplotlib), leaving out swept keys."""
        return [
            f"{self.parameter_labels[k]} {params[k]:g} {self.parameter_units[k]}"
            for k in self.parameter_keys
            if f"surface.{k}" not in swept and isinstance(params.get(k), (int, float))
        ]

    def study_title_items(self, section: dict, swept: set | frozenset = frozenset()) -> list[str]:
        """The fixed surface of a study (its base ``surface:`` section as written, derived
        keys included) for its figure titles, leaving out swept keys."""
        return self.title_items(section, swept)

    # ---- models whose parameters depend on the config (a list of arms); the defaults suit a
    # model with a fixed set of scalar keys, such as the SLS

    def for_params(self, params: dict) -> SurfaceModel:
        """The model specialised to ``params``: its :attr:`parameter_keys` and
        :attr:`quantities` as that config has them (a Wiechert surface with N arms
        reports ``k_1, cd_1, ..., k_N, cd_N``).  Default: the model itself."""
        return self

    def from_arms(self, k_inf: float, k, cd) -> dict:
        """The parameters (as :meth:`parse` returns them) of the surface with these arms:
        the inverse of :meth:`kernel_arms`.  Default: ``parameter_keys`` = ``(k_inf, then
        (k, cd) of each arm)`` in order."""
        values = [float(k_inf)] + [float(v) for pair in zip(k, cd) for v in pair]
        if len(values) != len(self.parameter_keys):
            raise ValueError(f"{self.key}: {len(k)} arm(s) do not fit the parameters {self.parameter_keys}")
        return dict(zip(self.parameter_keys, values))

    def item_key(self, name: str) -> bool:
        """Whether ``name`` is a dotted path into a non-scalar config key (e.g. a Wiechert
        arm's ``arms.1.cd``), settable with ``--set surface.<name>=`` and sweepable."""
        return False

    def set_items(self, values: dict, items: dict) -> dict:
        """``values`` (parsed keys of a ``surface:`` section) with the dotted ``items``
        (:meth:`item_key`) applied and checked; ConfigError names ``surface.<item>``."""
        if items:
            raise ConfigError(f"unknown key 'surface.{next(iter(items))}'")
        return values

    def get_item(self, params: dict, name: str) -> Any:
        """The value of a dotted item (:meth:`item_key`) in ``params``."""
        raise AttributeError(f"surface ({self.key}) has no key {name!r}")

    def key_parameter(self, name: str) -> tuple[str, SurfaceModel] | None:
        """``(parameter or derived-key name, model declaring it)`` of a ``surface.<name>``
        config key or item, for axis labels; None if the model has no such key."""
        if name in self.parameter_keys or name in self.derived_keys:
            return name, self
        return None

    def describe(self, params: dict) -> str:
        """The surface in a few words for messages, e.g. 'an SLS (one relaxation time)'."""
        return f"a {self.name} surface"

    def check_config(self, cfg) -> None:
        """Checks of the whole config that concern the model (ConfigError); default none."""


    # ---- linear response to a small harmonic displacement (the AM-AFM energy balance): what the instrument's loss
    # tangent and the per-tap DMT modulus are compared with

    def complex_stiffness(self, params: dict, omega: float) -> tuple[float, float] | None:
        """Storage and loss stiffness ``k'(omega), k''(omega)`` [N/m] at angular frequency
        ``omega`` [rad/s] of a surface that is a spring ``k_inf`` in parallel with Maxwell arms
        ``(k_i, cd_i)`` (the AM-AFM energy balance)::

            k*(omega) = k_inf + sum_i k_i (i x_i)/(1 + i x_i),   x_i = omega tau_i,  tau_i = cd_i/k_i
            k'  = k_inf + sum_i k_i x_i^2/(1 + x_i^2)            k'' = sum_i k_i x_i/(1 + x_i^2)

        Default: the springs of :meth:`kernel_arms`.  A model whose contact is not a set of
        springs (a Hertzian half-space) returns None and gives :meth:`complex_modulus`."""
        k_inf, k, cd = self.kernel_arms(params)
        x = omega * np.asarray(cd, dtype=float) / np.asarray(k, dtype=float)
        return float(k_inf + np.sum(k * x * x / (1.0 + x * x))), float(np.sum(k * x / (1.0 + x * x)))

    def complex_modulus(self, params: dict, omega: float) -> tuple[float, float] | None:
        """Reduced storage and loss moduli ``E*'(omega), E*''(omega)`` [Pa] (``E/(1 - nu^2)``) of
        a model that has moduli (a half-space); default None (a model of springs)."""
        return None

    def dynamic_theory(self, params: dict, f_drive: float | None, contact_time: float | None) -> dict:
        """:data:`DYNAMIC_QUANTITIES` at the drive frequency ``f_drive`` [Hz] and at the contact's
        own time scale ``omega_c = pi / contact_time`` [s] (one contact as half a period):
        the stiffnesses of :meth:`complex_stiffness`, the moduli of :meth:`complex_modulus`
        where the model has them, ``tan delta = k''/k'`` (else ``E''/E'``).  None where an input
        or the model's response is unknown."""
        omegas = {
            "drive": 2.0 * math.pi * f_drive if f_drive and f_drive > 0 else None,
            "contact": math.pi / contact_time if contact_time and contact_time > 0 else None,
        }
        out: dict = dict.fromkeys(DYNAMIC_QUANTITIES)
        for where, omega in omegas.items():
            if omega is None:
                continue
            ks, em = self.complex_stiffness(params, omega), self.complex_modulus(params, omega)
            if ks is not None:
                out[f"k_storage_{where}"], out[f"k_loss_{where}"] = ks
            if em is not None:
                out[f"e_storage_{where}"], out[f"e_loss_{where}"] = em
            pair = ks if ks is not None else em
            if pair is not None and pair[0]:
                out[f"tan_delta_{where}"] = pair[1] / pair[0]
        return out


MODELS: dict[str, SurfaceModel] = {}


def parse_arm(i: int, arm: Any, fields: dict[str, tuple[str, Rule]]) -> dict:
    """One Maxwell arm ``surface.arms.<i>`` of a model whose arm has ``fields`` (name ->
    (unit, rule)): a mapping with exactly those keys, each a float its rule allows; otherwise
    a ConfigError naming the key and the allowed values."""
    spec = ", ".join(f"{f}: {unit}" for f, (unit, _) in fields.items())
    if not isinstance(arm, dict):
        raise ConfigError(f"surface.arms.{i}: {arm!r} is not allowed; expected a mapping {{{spec}}}")
    unknown = [f for f in arm if f not in fields]
    if unknown:
        raise ConfigError(f"unknown key 'surface.arms.{i}.{unknown[0]}'; allowed in an arm: {', '.join(fields)}")
    missing = [f for f in fields if f not in arm]
    if missing:
        both = " and ".join(f"{f} [{unit}]" for f, (unit, _) in fields.items())
        raise ConfigError(f"surface.arms.{i}: {arm!r} has no {missing[0]!r}; expected both {both}")
    return {f: parse_arm_field(i, f, arm[f], fields) for f in fields}


def parse_arm_field(i: int, field: str, value: Any, fields: dict[str, tuple[str, Rule]]) -> float:
    """``surface.arms.<i>.<field>``: a float its rule in ``fields`` allows."""
    key = f"surface.arms.{i}.{field}"
    return check(key, value, coerce(key, value, "float"), fields[field][1])


SUPPORTS = ("thermal", "scan", "fit")  # what a model's simulation may offer (SurfaceModel.supports)


def convention_errors(model: SurfaceModel) -> list[str]:
    """What ``model`` misses of the convention (module docstring), checked on its declarations
    alone (no simulation: :func:`vetica_cli.testing.check_surface_model` runs the rest); empty
    when it follows it.  :func:`register` refuses a model with any."""
    out = []

    def need(ok, text):
        if not ok:
            out.append(text)

    need(isinstance(getattr(model, "key", None), str) and model.key, "a key (the surface.model value)")
    need(isinstance(getattr(model, "name", None), str) and model.name, "a name")
    keys = tuple(getattr(model, "parameter_keys", ()) or ())
    need(keys and all(isinstance(k, str) for k in keys), "parameter_keys")
    units = getattr(model, "parameter_units", {}) or {}
    need(set(units) == set(keys) and all(units.values()), "a unit for every parameter (parameter_units)")
    need(set(getattr(model, "parameter_labels", {}) or {}) >= set(keys), "a label for every parameter (parameter_labels)")
    qs = getattr(model, "quantities", {}) or {}
    need(qs and all(isinstance(q, Quantity) and q.unit is not None and q.label and q.tex for q in qs.values()),
         "quantities, each a Quantity with unit, label and tex")  # fmt: skip
    need(set(getattr(model, "fit_bounds", {}) or {}) == set(keys), "fit_bounds for every parameter")
    need(bool(getattr(model, "theory_source", "")), "a theory_source")
    refs = getattr(model, "references", ())
    need(isinstance(refs, tuple) and refs and all(isinstance(r, str) and r for r in refs),
         "references: a tuple of where the model comes from (e.g. 'thesis 3.2')")  # fmt: skip
    need("=" in doc(model), "its equation in the class docstring")
    need(set(getattr(model, "supports", ())) <= set(SUPPORTS), f"supports within {SUPPORTS}")
    need(isinstance(getattr(model, "defaults", None), dict), "defaults of its config keys")
    for name, dk in (getattr(model, "derived_keys", {}) or {}).items():
        need(dk.target in model.defaults and dk.source in model.defaults, f"derived key {name}: target and source keys")
    acc = getattr(model, "acceptance", None)
    need(acc is None or (acc[0] in qs and acc[1] in keys), "acceptance: (one of its quantities, one of its parameters)")
    return out


def register(cls: type[SurfaceModel]) -> type[SurfaceModel]:
    """Class decorator: add one instance of the model to :data:`MODELS` under its ``key``,
    after checking its declarations against the convention (:func:`convention_errors`)."""
    if cls.key in MODELS:
        raise ValueError(f"surface model {cls.key!r} is registered twice")
    model = cls()
    errors = convention_errors(model)
    if errors:
        raise TypeError(f"surface model {cls.__name__} does not follow the convention: it needs " + "; ".join(errors))
    MODELS[cls.key] = model
    return cls


def get(key: str) -> SurfaceModel:
    """The registered model ``key``; ConfigError (surface.model) listing the registered ones."""
    if not isinstance(key, str) or key not in MODELS:
        raise ConfigError(f"surface.model: {key!r} is not allowed; expected one of: {', '.join(MODELS)}")
    return MODELS[key]


def doc(model: SurfaceModel) -> str:
    """The model's docstring (equation and thesis reference)."""
    return inspect.getdoc(type(model)) or ""
