"""The convention every extraction method follows, and the registry that collects them.

A method is one module (or package) under :mod:`vetica_cli.extraction.methods` defining a
subclass of :class:`ExtractionMethod` decorated with :func:`register`: it declares its
``key`` (the ``--method`` / ``extract.method`` value), a one-line description, the surface
models it can extract, its ``references`` (where it comes from, as data), each option once
(:class:`Option`: name, type, default, unit, rule, help, and optionally a flag of its own;
``options_default``, the checks, ``vetica extract --option key=value`` and the generated
flags derive from it), and ``run(record, options) -> ExtractionResult``; its error bars and
sanity checks are hooks (:meth:`ExtractionMethod.sigmas`, :meth:`ExtractionMethod.checks`)
whose defaults are the generic ones.  The CLI's ``--method`` choices, the sweep's
``extract.method`` values and the table's ``method`` column all come from :data:`METHODS`.
:func:`register` checks the declarations (:func:`convention_errors`);
:func:`vetica_cli.testing.check_method` runs the method on a record of a model it declares.
"""

from __future__ import annotations

import math

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ..checks import Rule, check, coerce, load_yaml
from ..errors import ConfigError, InputError
from ..signals.taps import KG_WINDOWS
from ..surfaces import MODELS, Quantity, SurfaceModel
from ..surfaces.base import DYNAMIC_QUANTITIES
from .record import Record
from .result import ExtractionResult, t_factor


TYPE_TEXT = {"int": "an integer", "float": "a finite number", "bool": "true or false", "str": "a name"}


def _typed(value: Any, tp: str) -> bool:
    """Whether a typed value (the API's, a config's) has the declared type."""
    if tp == "any":
        return True
    if tp == "bool":
        return isinstance(value, (bool, np.bool_))
    if tp == "str":
        return isinstance(value, str)
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        return False
    if tp == "int":
        return isinstance(value, (int, np.integer))
    return math.isfinite(value)


@dataclass(frozen=True)
class Option:
    """One option of a method, declared once: its name, type ('int', 'float', 'bool', 'str';
    'any' for a value only the API passes, e.g. a start dict), default (None: the method
    decides, e.g. from the record's metadata), unit ('' for none), one line of help, the
    rule its value must satisfy (``(predicate, what is allowed)``) and, for a few, a flag of
    its own on ``vetica extract`` besides ``--option name=value`` (``flag``).  The method's
    ``options_default``, the checks of :meth:`ExtractionMethod.options` and
    :meth:`~ExtractionMethod.parse_options`, the ``extract`` command's flags and help and
    the docs' options table all derive from it."""

    name: str
    type: str
    default: Any = None
    unit: str = ""
    help: str = ""
    rule: Rule | None = None
    flag: str | None = None  # e.g. "--arms": generated on `vetica extract` (cli.py)
    settable: bool = True  # a user may set it with --option (False: the API's only)

    def parse(self, raw: Any, label: str | None = None) -> Any:
        """A value (YAML scalar text, or already typed) coerced and checked; ConfigError (one
        line) naming ``label`` (default ``--option <name>``)."""
        label = label or f"--option {self.name}"
        value = load_yaml(raw, label) if isinstance(raw, str) and self.type != "str" else raw
        return check(label, raw, coerce(label, value, self.type), self.rule)

    def check(self, value: Any) -> None:
        """InputError (one line) unless ``value`` (typed: the API's) has the declared type and
        satisfies the rule; None always passes (the method's default or 'auto')."""
        if value is None:
            return
        if not _typed(value, self.type):
            raise InputError(f"{self.name} {value!r} not allowed; expected {TYPE_TEXT.get(self.type, self.type)}")
        if self.rule is not None and not self.rule[0](value):
            allowed = self.rule[1]
            raise InputError(f"{self.name} {value!r} not allowed; "
                             + (f"choose {allowed}" if allowed.startswith("one of:") else f"expected {allowed}"))

    @property
    def allowed(self) -> str:
        """What the option takes, in words (its rule, else its type)."""
        return self.rule[1] if self.rule is not None else TYPE_TEXT.get(self.type, self.type)


KG_POINTS = Option("kg_points", "int", 10, "", "samples of the contact's initial slope fitted for Kg (thesis 3.3.2: "
                   "10); at least 2 and fewer than the longest contact of the record",
                   (lambda v: v >= 2, "an integer >= 2"), flag="--kg-points")  # fmt: skip


KG_WINDOW = Option("kg_window", "str", "noise", "", "stage 1b's window: noise (the thesis's kg_points samples where "
                   "the record's noise allows them, a window grown from the noise otherwise) or thesis (always kg_points)",
                   (lambda v: v in KG_WINDOWS, f"one of: {', '.join(KG_WINDOWS)}"))  # fmt: skip


KG_SCALE = Option("kg_scale", "float", 1.0, "", "stage 1b's slopes multiplied by this factor (1: as measured; the "
                  "error bars move it to see how every quantity follows Kg)", (lambda v: 0.5 <= v <= 2.0, "a factor in [0.5, 2]"))  # fmt: skip


FIXED_COST = 0.1  # part of a method's seconds_per_point that does not scale with the record's samples


def record_cost_scale(record_cycles: float, print_step: float, fixed: float = FIXED_COST) -> float:
    """An extraction's cost relative to its ``seconds_per_point`` (a record of 10 periods at
    0.125 ns): a fixed part (taps, stages, checks; measured 5-17 % of the reference cost for
    the tap methods and the whole-cycle fit, 2-8 % for the observables and the DMT fit; a
    sweep point's, ``fixed``, also carries its task and part file) plus a part in proportion
    to the record's samples."""
    return fixed + (1.0 - fixed) * (record_cycles / 10.0) * (0.125e-9 / print_step)


class ExtractionMethod(ABC):
    """Base of every extraction method (one subclass per module; see the module docstring)."""

    key: ClassVar[str]  # e.g. "vetica"
    description: ClassVar[str]  # one line, e.g. "VETICA (thesis 3.3): creep, initial slope, superposition fit"
    title: ClassVar[str]  # heading of the text table, e.g. "VETICA"
    surface_models: ClassVar[tuple[str, ...]]  # surface models (vetica_cli.surfaces) it can extract
    needs_approach: ClassVar[bool] = False  # analyse the approach segment even when Z1 is given
    needs_z1: ClassVar[bool] = True  # a record without Z1 (no approach segment, no metadata) is an error
    surface_note: ClassVar[str] = ""  # why it extracts only its surface_models (for the refusal message)
    uniform_sampling: ClassVar[bool] = False  # needs a constant time step in the steady record
    tap_windows: ClassVar[bool] = False  # reads a reconstructed force only in the tap windows (signals.tapforce)
    kernel_modules: ClassVar[tuple[str, ...]] = ()  # cached core modules it compiles (simulation.jit)
    seconds_per_point: ClassVar[float] = 1.0  # both force sources, 10 periods at 0.125 ns (dry-run estimate)
    option_specs: ClassVar[tuple[Option, ...]] = ()  # every option the method takes, declared once (Option)
    options_default: ClassVar[dict[str, Any]] = {}  # derived from option_specs: {name: default}
    references: ClassVar[tuple[str, ...]] = ()  # where the method comes from (thesis section, paper): data, not docstring

    def __init_subclass__(cls, **kw):
        super().__init_subclass__(**kw)
        cls.options_default = {o.name: o.default for o in cls.option_specs}

    def option(self, name: str) -> Option | None:
        """The declaration of option ``name`` (None: the method takes no such option)."""
        return next((o for o in self.option_specs if o.name == name), None)

    def parse_options(self, given: dict) -> dict:
        """``{name: raw value}`` (``--option key=value``) typed and checked by :attr:`option_specs`;
        InputError (one line) naming the options the method takes."""
        specs = {o.name: o for o in self.option_specs if o.settable}
        out = {}
        for name, raw in given.items():
            if name not in specs:
                raise InputError(f"--option {name}: method {self.key!r} takes no such option; it takes: "
                                 f"{', '.join(specs) or 'none'}")  # fmt: skip
            try:
                out[name] = specs[name].parse(raw)
            except ConfigError as exc:
                raise InputError(str(exc)) from None
        return out

    def quantities(self, model: SurfaceModel) -> dict[str, Quantity]:
        """The quantities the method reports for a surface of ``model``, in table order."""
        return model.quantities

    def reference_quantities(self, model: SurfaceModel) -> dict[str, Quantity]:
        """Theory-only quantities the method reports beside its estimates (no value of their
        own: ``<name>_theory`` in a study table, ``theory`` in the JSON); default none."""
        return {}

    def options(self, given: dict) -> dict:
        """``given`` options checked and completed with the defaults; InputError (one line)
        for an option the method does not take or a bad value."""
        unknown = [k for k in given if k not in self.options_default]
        if unknown:
            raise InputError(
                f"method {self.key!r} takes no option {unknown[0]!r}; options: {', '.join(self.options_default)}"
            )
        specs = {o.name: o for o in self.option_specs}
        for name, value in given.items():
            specs[name].check(value)
        return {**self.options_default, **given}

    @abstractmethod
    def run(self, record: Record, options: dict) -> ExtractionResult:
        """Extract the surface from one prepared record (options as :meth:`options` returns them)."""

    per_tap_statistic: ClassVar[str] = "mean"  # what a value is of its per-tap (per-period) values: mean | median

    def sigmas(self, res: ExtractionResult, record: Record, options: dict) -> tuple[dict, dict]:
        """``({quantity: relative 1-sigma}, bookkeeping)`` of the estimates that carry no sigma of
        their own (the hook of :func:`vetica_cli.extraction.uncertainty.calibrate`).  Default: the
        standard error of the per-tap (or per-period) values' mean, ``s/sqrt(n)`` (times
        ``sqrt(pi/2)`` = 1.2533 for a median: its asymptotic efficiency on Gaussian values),
        scaled by ``t(0.975, n-1)/1.96`` and widened where neighbouring taps' values are correlated
        (:meth:`~.result.Spread.serial_factor`: the cantilever's thermal motion, which it remembers for its
        ring-down time, tens of drive periods, moves the tip's lowest point, and with it a tap's
        deformation, from tap to tap together: at 300 K on dev draw 21 dmt-fit's deformation scattered
        1.75x its tap-independent sigma over replicas; the lag-one correlation read 0.27 on average over
        nine taps); a quantity with fewer than two values has none."""
        scale = math.sqrt(math.pi / 2.0) if self.per_tap_statistic == "median" else 1.0
        out, serial = {}, {}
        for q, e in res.estimates.items():
            sp = e.spread
            if e.value is None or e.sigma is not None or sp is None or sp.std is None or not e.value:
                continue
            serial[q] = sp.serial_factor()
            out[q] = (scale * serial[q] * sp.std / math.sqrt(sp.n) * t_factor(sp.n) / abs(e.value) if sp.n >= 2
                      else math.inf)  # fmt: skip
        return out, {"source": f"spread over taps (standard error of the {self.per_tap_statistic}, t-scaled, widened "
                               "by the taps' serial correlation)", "serial_factor": serial}  # fmt: skip

    scan_maps: ClassVar[tuple[str, ...]] = ()  # its quantities drawn in a scan's instrument figure (plots.scanmaps)
    reads_force: ClassVar[bool] = True  # reads the force: judged by whether the force's band resolves the contact
    referee: ClassVar[str | None] = None  # a method whose fit on the same record judges this one's (tap family: 'full')
    band_model: ClassVar[str | None] = None  # a method whose fitted surface measures the band's bias (default: referee)
    compared_with: ClassVar[str | None] = None  # a variant whose difference flags this one's quantities

    def continuation(self, res: ExtractionResult) -> dict:
        """Options that start a re-run of this method on a slightly changed copy of the record (the
        band term's narrower bands) from its answer ``res``, so the re-run measures how that answer
        moves rather than finding another one.  Default: none (a method without a start)."""
        return {}

    def checks(self, res: ExtractionResult, record: Record, options: dict, info: dict) -> None:
        """The method's own identifiability and sanity checks (the hook of
        :func:`vetica_cli.extraction.sanity.check`, run before the generic ones): flag what the
        record does not determine with :func:`vetica_cli.extraction.sanity.flag` (in place) and
        put the numbers behind each check in ``info`` (``info['sanity']`` of the result).  Default:
        none (the generic checks -- the band's bias, a relative 1-sigma above 100 % -- apply to
        every method)."""

    def flag_dependents(self, res: ExtractionResult) -> None:
        """After every check: flag the quantities computed from flagged ones (default: none)."""

    def detail_lines(self, res: ExtractionResult) -> list[str]:
        """Lines the text table adds about what the method did, e.g. what was fitted and what
        assumed (default: none)."""
        return []

    def timing_line(self, timing_s: dict) -> str:
        """One line of the text table: where the time went."""
        return "time: " + ", ".join(f"{k} {v:.2f} s" for k, v in timing_s.items() if isinstance(v, (int, float)))


METHODS: dict[str, ExtractionMethod] = {}
DEFAULT_METHOD = "vetica"  # --method and extract.method when not given


class ModelFreeMethod(ExtractionMethod):
    """A method that does not model the surface (the instrument's methods): it runs on records
    of every surface model, reports its own ``fixed_quantities`` whatever the model, and the
    dynamic references (loss tangent, dissipation) beside them."""

    fixed_quantities: ClassVar[dict[str, Quantity]]

    @property
    def surface_models(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(MODELS)

    def quantities(self, model: SurfaceModel) -> dict[str, Quantity]:
        return dict(self.fixed_quantities)

    def reference_quantities(self, model: SurfaceModel) -> dict[str, Quantity]:
        return dict(DYNAMIC_QUANTITIES)


def convention_errors(method: ExtractionMethod) -> list[str]:
    """What ``method`` misses of the convention (module docstring), checked on its declarations
    alone (:func:`vetica_cli.testing.check_method` runs it on a record); empty when it follows
    it.  :func:`register` refuses a method with any."""
    out = []

    def need(ok, text):
        if not ok:
            out.append(text)

    need(isinstance(getattr(method, "key", None), str) and method.key, "a key (the --method value)")
    need(isinstance(getattr(method, "title", None), str) and method.title, "a title")
    d = getattr(method, "description", "")
    need(isinstance(d, str) and d and "\n" not in d, "a one-line description")
    models = tuple(method.surface_models) if hasattr(method, "surface_models") else ()
    need(models and set(models) <= set(MODELS), "surface_models among the registered models")
    need(getattr(method, "seconds_per_point", 0) > 0, "seconds_per_point > 0 (the dry-run estimate)")
    refs = getattr(method, "references", ())
    need(isinstance(refs, tuple) and refs and all(isinstance(r, str) and r for r in refs),
         "references: a tuple of where the method comes from (e.g. 'thesis 3.3')")  # fmt: skip
    names = [o.name for o in method.option_specs]
    need(len(names) == len(set(names)), "one declaration per option")
    for o in method.option_specs:
        need(isinstance(o, Option) and o.help, f"option {o.name}: an Option with help")
        need(o.type in TYPE_TEXT or (o.type == "any" and not o.settable), f"option {o.name}: a type of {tuple(TYPE_TEXT)}")
        try:
            o.check(o.default)
        except InputError as exc:
            out.append(f"option {o.name}: a default its own rule allows ({exc})")
    return out


def register(cls: type[ExtractionMethod]) -> type[ExtractionMethod]:
    """Class decorator: add one instance of the method to :data:`METHODS` under its ``key``,
    after checking its declarations against the convention (:func:`convention_errors`)."""
    if cls.key in METHODS:
        raise ValueError(f"extraction method {cls.key!r} is registered twice")
    method = cls()
    errors = convention_errors(method)
    if errors:
        raise TypeError(f"extraction method {cls.__name__} does not follow the convention: it needs " + "; ".join(errors))
    METHODS[cls.key] = method
    return cls


def get(key: str) -> ExtractionMethod:
    """The registered method ``key``; InputError listing the registered ones."""
    if key not in METHODS:
        raise InputError(f"method {key!r} not available; choose one of: {', '.join(METHODS)}")
    return METHODS[key]
