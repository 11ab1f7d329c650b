"""Per-tap force-curve numbers as HarmoniX / PeakForce-style analysis gives them from a
force-recording probe.  Registered as extraction method ``dmt-fit``.

Each complete tap of the (true or reconstructed) force against the tip position gives:

* adhesion: ``F_adh`` = the force minimum from the peak to the next contact (reported as
  ``-F_adh`` > 0) [N];
* DMT modulus (Derjaguin-Muller-Toporov: Hertz plus a constant adhesion) on the
  **unloading** branch -- the retract, from the tip's lowest position to separation (in
  tapping mode the force peaks before the tip turns: the surface relaxes while the tip
  still descends) -- over the samples whose ``F - F_adh`` lies
  between ``fit_low`` and ``fit_high`` (defaults 0.3 and 0.9) of the peak-to-adhesion
  force ``F_peak - F_adh``::

      F - F_adh = 4/3 E* sqrt(R) (z0 - z_tip)^(3/2)                      [N]

  with the tip radius ``R`` (the option, else the metadata's probe; a record without
  metadata needs ``--tip-radius``): ``E*`` (the contact's reduced modulus, ``e_dmt``)
  and the contact point ``z0``; a straight-line fit of ``(F - F_adh)^(2/3)`` against
  ``z_tip`` refined by least squares of the force;
* ``k_dmt``: the unloading stiffness of the fitted curve where the retract starts,
  ``dF/d delta = 2 E* sqrt(R (z0 - z_low))`` (Oliver-Pharr's contact stiffness) [N/m];
* per-tap dissipation: the loop area ``-int F dz_tip`` over one drive period, from the
  highest tip position before the tap to the next [eV];
* deformation: the tip's travel from the contact force minimum to its lowest position [m].

Values are medians over the taps, with the spread over taps.  Truth (when the metadata
holds it): the adhesion ``Fa(a0) = H R / (6 a0^2)`` (thesis eq. 3); the simulator's exact
sample dissipation per cycle and its maximum penetration below the undeformed surface;
``k_dmt`` against the surface's storage stiffness ``k'`` at ``pi / contact time``
(:meth:`~vetica_cli.surfaces.SurfaceModel.dynamic_theory`); ``e_dmt`` against the reduced
storage modulus there for a model that has moduli (none for the spring surfaces ``sls`` and
``wiechert``, whose contact is a flat punch: a Hertz fit to it measures the model's misfit).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ...constants import EV
from ...errors import InputError
from ...signals.taps import find_taps
from ...surfaces import Quantity
from ..base import ModelFreeMethod, Option, register
from .observables import dynamic_references
from ..record import Record
from ..result import ExtractionResult, Spread, estimates

FIT_LOW, FIT_HIGH = 0.3, 0.9  # default fit range: fractions of the peak-to-adhesion force on the unloading branch
MIN_FIT_POINTS = 3
QUANTITIES: dict[str, Quantity] = {
    "adhesion": Quantity("N", "F_adh", r"$F_{adh}$", "nN", 1e9, True, "adhesion: minus the force minimum of a tap"),
    "e_dmt": Quantity("Pa", "E*_DMT", r"$E^*_{DMT}$", "MPa", 1e-6, True,
                      "reduced modulus of the DMT fit on the unloading branch"),
    "k_dmt": Quantity("N/m", "k_DMT", r"$k_{DMT}$", "N/m", 1.0, True,
                      "unloading stiffness of the DMT fit where the retract starts"),
    "e_diss_tap": Quantity("eV", "E_tap", r"$E_{tap}$", "eV", 1.0, True,
                           "dissipated energy per tap: the loop area -int F dz_tip"),
    "deformation": Quantity("m", "deformation", r"$\delta_{max}$", "nm", 1e9, True,
                            "tip travel from the contact force minimum to its lowest position"),
}  # fmt: skip
THEORY_SOURCES = {
    "adhesion": "Fa(a0) = H R / (6 a0^2), thesis eq. 3 (surface hamaker, a0; probe tip_radius)",
    "e_dmt": "reduced storage modulus E*' at pi / contact time (models with moduli; none for springs)",
    "k_dmt": "the surface's storage stiffness k' at pi / contact time (the AM-AFM energy balance)",
    "e_diss_tap": "the simulator's exact sample dissipation per cycle (observable 'e_diss_ev')",
    "deformation": "the simulator's maximum penetration below the undeformed surface (observable 'max_penetration')",
}


def fit_dmt(z: np.ndarray, f: np.ndarray, f_adh: float, radius: float, low: float = FIT_LOW,
            high: float = FIT_HIGH, f_peak: float | None = None) -> tuple[float, float, int]:  # fmt: skip
    """DMT fit of one unloading branch (``z`` [m], ``f`` [N] from the lowest tip position to
    separation):
    ``(E* [Pa], z0 [m], samples fitted)`` of ``F - F_adh = 4/3 E* sqrt(R) (z0 - z)^1.5`` over
    the samples with ``F - F_adh`` in ``[low, high]`` of ``F_peak - F_adh`` (``f_peak``: the
    tap's largest force, default the branch's; module docstring); nan with fewer than :data:`MIN_FIT_POINTS` samples."""
    from scipy.optimize import least_squares  # lazy: the CLI starts without scipy.optimize

    span = float(f_peak if f_peak is not None else np.max(f)) - f_adh
    rel = (f - f_adh) / span if span > 0 else np.full(len(f), np.nan)
    sel = (rel >= low) & (rel <= high)
    if sel.sum() < MIN_FIT_POINTS:
        return math.nan, math.nan, int(sel.sum())
    zs, fs = z[sel], f[sel] - f_adh
    slope, intercept = np.polyfit(zs, fs ** (2.0 / 3.0), 1)  # (F - F_adh)^(2/3) = c (z0 - z)
    if not slope < 0:
        return math.nan, math.nan, int(sel.sum())
    c, z0 = -slope, -intercept / slope
    scale = float(np.max(fs))

    def resid(x):
        gap = np.clip(x[1] * 1e-9 - zs, 0.0, None)
        return (math.exp(x[0]) * gap**1.5 - fs) / scale

    k0 = 1.5 * math.log(c)  # K = 4/3 E* sqrt(R) = c^1.5
    sol = least_squares(resid, [k0, z0 * 1e9], method="lm", xtol=1e-14, ftol=1e-14)
    k_h, z0 = math.exp(sol.x[0]), sol.x[1] * 1e-9
    return 3.0 * k_h / (4.0 * math.sqrt(radius)), float(z0), int(sel.sum())


def tap_numbers(z: np.ndarray, f: np.ndarray, radius: float, low: float = FIT_LOW, high: float = FIT_HIGH) -> dict:
    """Per-tap arrays (module docstring) of a record: ``adhesion`` [N], ``e_dmt`` [Pa],
    ``k_dmt`` [N/m], ``e_diss_tap`` [J], ``deformation`` [m], ``fit_points``.  InputError
    without two complete taps."""
    taps = find_taps(f)
    n = len(taps.contact)
    if n < 1:
        raise InputError(f"too few taps: no complete tap in the record ({taps.incomplete} cut by its ends)")
    out = {k: np.full(n, math.nan) for k in ("adhesion", "e_dmt", "k_dmt", "e_diss_tap", "deformation", "fit_points")}
    nxt = [*taps.contact[1:], len(f)]
    for i, (ic, ipk, isep) in enumerate(zip(taps.contact, taps.peak, taps.separation)):
        if not ic <= ipk <= isep < nxt[i]:  # taps that overlap (a force read in noise): no numbers from this one
            continue
        f_adh = float(np.min(f[ipk : nxt[i]]))
        ilow = ic + int(np.argmin(z[ic : isep + 1]))  # the retract starts
        e_star, z0, npts = fit_dmt(z[ilow : isep + 1], f[ilow : isep + 1], f_adh, radius, low, high, float(f[ipk]))
        out["adhesion"][i] = -f_adh
        out["e_dmt"][i] = e_star
        out["fit_points"][i] = npts
        if math.isfinite(z0) and z0 > z[ilow]:
            out["k_dmt"][i] = 2.0 * e_star * math.sqrt(radius * (z0 - z[ilow]))
        out["deformation"][i] = float(z[ic] - z[ilow])
    # one loop per drive period: between the highest tip positions either side of a tap
    tops = [s + int(np.argmax(z[s:c])) if c > s else None for s, c in zip(taps.separation[:-1], taps.contact[1:])]
    first = int(np.argmax(z[: taps.contact[0]])) if taps.contact[0] > 0 else None
    last = taps.separation[-1] + int(np.argmax(z[taps.separation[-1] :]))
    bounds = ([first] if first is not None and first > 0 else [None]) + tops + [last if last < len(z) - 1 else None]
    for i in range(n):
        a, b = bounds[i], bounds[i + 1]
        if a is not None and b is not None:
            out["e_diss_tap"][i] = -float(np.trapezoid(f[a : b + 1], z[a : b + 1]))
    return out


def adhesion_theory(record: Record) -> float | None:
    """``Fa(a0) = H R / (6 a0^2)`` [N] of a simulated run (thesis eq. 3), else None."""
    s, r = record.surface, record.probe.get("tip_radius")
    if s.get("hamaker") is None or s.get("a0") is None or r is None:
        return None
    return float(s["hamaker"]) * float(r) / (6.0 * float(s["a0"]) ** 2)


@register
class DmtFit(ModelFreeMethod):
    """Per-tap adhesion, DMT modulus on the unloading branch, dissipation and deformation."""

    per_tap_statistic = "median"  # values are medians over the taps

    key = "dmt-fit"
    description = ("per-tap force-curve analysis (PeakForce/HarmoniX style): adhesion, DMT modulus on the unloading "
                   "branch, loop dissipation, deformation")  # fmt: skip
    title = "per-tap DMT analysis"
    option_specs = (
        Option("fit_low", "float", FIT_LOW, "", "lower end of the unloading branch fitted, a fraction of the "
               "peak-to-adhesion force", (lambda v: 0.0 <= v <= 1.0, "a fraction in [0, 1]")),
        Option("fit_high", "float", FIT_HIGH, "", "upper end of the unloading branch fitted, a fraction of the "
               "peak-to-adhesion force (above fit_low)", (lambda v: 0.0 <= v <= 1.0, "a fraction in [0, 1]")),
        Option("tip_radius", "float", None, "m", "tip radius R of the DMT contact (default: the metadata's)",
               (lambda v: v > 0, "a number > 0 m"), flag="--tip-radius"),
    )  # fmt: skip
    references = ("Derjaguin, Muller & Toporov 1975", "PeakForce QNM / HarmoniX per-tap analysis")
    scan_maps = ("e_dmt", "k_dmt")  # drawn in a scan's instrument figure
    needs_z1 = False
    band_model = "full"  # the whole-cycle fit's surface measures what a noisy record's low-pass does to the numbers
    seconds_per_point = 0.4  # both forces, 10 periods at 0.125 ns: 0.41 CPU s measured
    theory_sources = THEORY_SOURCES
    fixed_quantities = QUANTITIES

    def options(self, given: dict) -> dict:
        opts = super().options(given)
        lo, hi = opts["fit_low"], opts["fit_high"]
        ok = all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in (lo, hi))
        if not (ok and 0.0 <= lo < hi <= 1.0):
            raise InputError(f"fit_low {lo!r}, fit_high {hi!r} not allowed; expected 0 <= fit_low < fit_high <= 1 "
                             "(fractions of the peak-to-adhesion force)")  # fmt: skip
        return opts

    def run(self, record: Record, options: dict) -> ExtractionResult:
        radius, source = options["tip_radius"], "given"
        if radius is None:
            radius, source = record.probe.get("tip_radius"), "metadata"
        if radius is None:
            raise InputError("the DMT fit needs the tip radius, which the record's metadata does not hold: pass --tip-radius")
        t0 = time.perf_counter()
        per = tap_numbers(record.z, record.f, float(radius), options["fit_low"], options["fit_high"])
        per["e_diss_tap"] = per["e_diss_tap"] / EV
        values = {k: float(np.nanmedian(v)) if np.any(np.isfinite(v)) else math.nan
                  for k, v in per.items() if k in QUANTITIES}  # fmt: skip
        refs = dynamic_references(record, record.probe.get("f1"))
        ko = record.observables
        truth = {"adhesion": adhesion_theory(record), "e_dmt": refs.get("e_storage_contact"),
                 "k_dmt": refs.get("k_storage_contact"), "e_diss_tap": ko.get("e_diss_ev"),
                 "deformation": ko.get("max_penetration")}  # fmt: skip
        warnings = list(record.meta_warnings)
        bad = int(np.sum(~np.isfinite(per["e_dmt"])))
        if bad:
            warnings.append(f"{bad} tap(s) with fewer than {MIN_FIT_POINTS} unloading samples between "
                            f"{options['fit_low']:g} and {options['fit_high']:g} of the peak-to-adhesion force: no DMT fit")  # fmt: skip
        diag = {"tip_radius_m": float(radius), "tip_radius_source": source, "fit_low": options["fit_low"],
                "fit_high": options["fit_high"], "fit_points_median": float(np.nanmedian(per["fit_points"]))}  # fmt: skip
        units = {k: q.unit for k, q in QUANTITIES.items()}
        spread = {k: Spread.of(per[k]) for k in QUANTITIES}
        timing = {"reconstruction": record.reconstruction_s, "fits": time.perf_counter() - t0,
                  "total": time.perf_counter() - record.t_start}  # fmt: skip
        return ExtractionResult(method=self.key, force=record.force, taps=len(per["adhesion"]), model=record.model.key,
                                estimates=estimates(values, units, truth, spreads=spread), info=dict(record.info),
                                diagnostics=diag, warnings=warnings, timing_s=timing, references=refs)  # fmt: skip

    def checks(self, res: ExtractionResult, record: Record, options: dict, info: dict) -> None:
        """Every quantity is read from the taps: flagged when the force shows more taps than the
        tip shows cycles (:func:`.tapchecks.taps_against_cycles`)."""
        from .tapchecks import taps_against_cycles

        f = np.asarray(record.f, float)
        taps_against_cycles(res, record, info, info["force_noise_floor_n"], float(np.max(np.abs(f))) or 1.0)

    def detail_lines(self, res: ExtractionResult) -> list[str]:
        d = res.diagnostics or {}
        return [f"DMT fit on the unloading branch between {d.get('fit_low', FIT_LOW):g} and {d.get('fit_high', FIT_HIGH):g} "
                f"of the peak-to-adhesion force ({d.get('fit_points_median', math.nan):.0f} samples per tap), R "
                f"{d.get('tip_radius_m', math.nan) * 1e9:.4g} nm ({d.get('tip_radius_source', '?')}); E* is the "
                "contact's reduced modulus, k_DMT its unloading stiffness at the lowest tip position"]  # fmt: skip
