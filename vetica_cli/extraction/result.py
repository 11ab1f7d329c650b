"""The typed result every extraction method returns (:class:`ExtractionResult`), and
the one place extracted values meet the theory (:func:`estimates`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..surfaces.base import DEFAULT_MODEL

SERIAL_MAX = 0.9  # the largest lag-one correlation Spread.serial_factor credits (a factor of 4.4)


def finite_or_none(v) -> float | None:
    """``float(v)``, or None for None, NaN and infinities (JSON has no NaN)."""
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def error_pct(value: float | None, theory: float | None) -> float | None:
    """Signed error of an extracted value against its theory value [%]:
    ``100 (value - theory) / theory`` (positive = overestimate; the thesis's figures plot its
    magnitude); None when either is unknown."""
    if value is None or not theory:
        return None
    return 100.0 * (value - theory) / theory


@dataclass(frozen=True)
class Spread:
    """Spread of a quantity over the taps of a record (VETICA: one value per tap)."""

    n: int = 0
    mean: float | None = None
    std: float | None = None
    min: float | None = None
    max: float | None = None
    lag1: float | None = None  # correlation of each value with the next (tap order); None below 3 values

    @classmethod
    def of(cls, values) -> Spread:
        """Spread of the finite ``values`` in their order (standard deviation with ddof 1; 0 for
        one value; ``lag1`` the lag-one autocorrelation, ``sum (v_i - m)(v_i+1 - m) / sum (v_i - m)^2``)."""
        v = np.asarray(values, dtype=float)
        v = v[np.isfinite(v)]
        if len(v) == 0:
            return cls()
        d = v - np.mean(v)
        ss = float(d @ d)
        return cls(
            n=len(v),
            mean=float(np.mean(v)),
            std=float(np.std(v, ddof=1)) if len(v) > 1 else 0.0,
            min=float(np.min(v)),
            max=float(np.max(v)),
            lag1=float(d[:-1] @ d[1:]) / ss if len(v) >= 3 and ss > 0 else None,
        )

    def serial_factor(self) -> float:
        """How much wider the standard error of the values' mean is than ``std/sqrt(n)`` when
        neighbouring values are correlated as a lag-one autoregression of correlation ``r``: the
        mean's variance is ``sigma^2/n (1 + 2 S)`` and the sample variance's expectation
        ``sigma^2 (1 - 2 S/(n - 1))``, ``S = sum_k (1 - k/n) r^k`` (k = 1 .. n-1), so the factor is
        ``sqrt((1 + 2 S)/(1 - 2 S/(n - 1)))``; ``r`` the lag-one autocorrelation corrected for its
        small-sample bias (``E[r_hat] = r - (1 + 3 r)/n``, Marriott and Pope 1954:
        ``r = (n r_hat + 1)/(n - 3)``), kept within 0..``SERIAL_MAX`` (an anticorrelation does not
        narrow it); 1 below 5 values."""
        n = self.n
        if self.lag1 is None or n < 5:
            return 1.0
        r = min(max((n * self.lag1 + 1.0) / (n - 3), 0.0), SERIAL_MAX)
        s = sum((1.0 - k / n) * r**k for k in range(1, n))
        return math.sqrt((1.0 + 2.0 * s) / max(1.0 - 2.0 * s / (n - 1), 1e-3))

    def as_dict(self) -> dict:
        return {"n": self.n, "mean": self.mean, "std": self.std, "min": self.min, "max": self.max}


@dataclass(frozen=True)
class Estimate:
    """One extracted quantity with what is known about it."""

    value: float | None  # extracted [unit]; None when the method could not produce one
    unit: str  # SI unit
    theory: float | None = None  # the surface model's theory value when the metadata knows the surface
    error_pct: float | None = None  # 100 (value - theory)/theory [%]
    sigma: float | None = None  # relative 1-sigma uncertainty (fraction; inf = unbounded); None = not reported
    spread: Spread | None = None  # over taps; None = one value for the whole record
    identifiable: bool | None = None  # for fitted parameters: does the record determine it?
    reason: str | None = None  # why (not) identifiable


@dataclass
class ExtractionResult:
    """What any extraction method returns for one record (rendered by :mod:`.format`)."""

    method: str  # key of the extraction method (vetica_cli.extraction registry)
    force: str  # force source analysed: 'true' (f_ts) or 'reconstructed' (spectral inversion)
    taps: int  # complete taps in the record
    estimates: dict[str, Estimate]  # quantity -> estimate, in the surface model's table order
    model: str = DEFAULT_MODEL  # surface model whose quantities these are (vetica_cli.surfaces)
    fitted: tuple[str, ...] = ()  # parameters fitted, in fit order (identifiability reported for these)
    info: dict = field(default_factory=dict)  # Z1 and its source, reconstruction, method details
    diagnostics: dict | None = None  # per-method fit quality numbers
    warnings: list = field(default_factory=list)
    timing_s: dict = field(default_factory=dict)  # wall seconds per stage and 'total'
    material: dict | None = None  # material units (extraction.material): name -> {value, unit, ...}
    contact: dict | None = None  # the contact model and constants behind ``material``
    references: dict = field(default_factory=dict)  # theory-only values the estimates are read against
    # (ExtractionMethod.references: e.g. the surface's k', k'', tan delta at the drive frequency)

    def value(self, name: str) -> float | None:
        e = self.estimates.get(name)
        return None if e is None else e.value


def estimates(
    values: dict, units: dict, truth: dict | None = None, spreads: dict | None = None, sigmas: dict | None = None
) -> dict[str, Estimate]:
    """Estimates of the quantities in ``units`` (their order): value, theory and error
    (:func:`error_pct`) where ``truth`` knows the quantity, per-tap spread and
    relative 1-sigma where given.  Non-finite values become None."""
    out = {}
    for name, unit in units.items():
        v = finite_or_none(values.get(name))
        th = finite_or_none(truth[name]) if truth and name in truth else None
        out[name] = Estimate(
            value=v,
            unit=unit,
            theory=th,
            error_pct=error_pct(v, th),
            sigma=None if sigmas is None else sigmas.get(name),
            spread=None if spreads is None else spreads.get(name),
        )
    return out


def t_factor(n: int) -> float:
    """``t(0.975, n - 1) / 1.96``: the standard error of a mean of ``n`` values scaled so
    that +-2 sigma is its 95 % interval (inf below two values).  The t quantile from
    ``scipy.special.stdtrit`` (not scipy.stats: half a second of imports for one number)."""
    if n < 2:
        return math.inf
    from scipy.special import stdtrit

    return float(stdtrit(n - 1, 0.975) / 1.959963984540054)


def sls_elements(tau_c: float, k_g: float, k_r: float) -> dict:
    """SLS elements from the characteristic constants (thesis eqs. 76, 81-83)."""
    tau_r = tau_c * k_r / k_g
    k0 = k_g - k_r
    return {"tau_c": tau_c, "k_g": k_g, "k_r": k_r, "tau_r": tau_r, "k0": k0, "k_inf": k_r, "cd": tau_r * k0}
