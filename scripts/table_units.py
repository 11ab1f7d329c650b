"""Units and descriptions of the tables the study scripts write (method comparison, noise
studies), in the form every vetica table carries in its Parquet metadata (``units``:
column -> unit, '' for a dimensionless or text column; ``descriptions``).

    python scripts/table_units.py      # stamps them on the committed tables (data unchanged)

The scripts that write these tables call :func:`stamp` on what they write.  A long table's
``value``/``truth``/``theory`` columns hold each row's ``quantity`` in that quantity's own unit:
their unit is '' and :data:`QUANTITY_UNITS` (also in the metadata) gives it per quantity.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from vetica_cli.io import read_table, write_table  # noqa: E402

QUANTITY_UNITS = {"tau_c": "s", "tau_r": "s", "k_g": "N/m", "k_r": "N/m", "k0": "N/m", "k_inf": "N/m",
                  "cd": "kg/s", "k_1": "N/m", "cd_1": "kg/s", "k_2": "N/m", "cd_2": "kg/s",
                  "adhesion": "N", "e_dmt": "Pa", "k_dmt": "N/m", "e_diss_tap": "eV", "deformation": "m",
                  "amplitude_obs": "m", "phase_obs": "deg", "e_diss_obs": "eV", "virial_obs": "eV",
                  "tan_delta_am": "", "hamaker_radius": "J m"}  # fmt: skip
COMMON = {
    "surface.cd": ("kg/s", "the point's dashpot cd"),
    "cd": ("kg/s", "the point's dashpot cd"),
    "ratio": ("", "stiffness ratio k0:k_inf (dimensionless)"),
    "surface.stiffness_ratio": ("", "stiffness ratio k0:k_inf (dimensionless)"),
    "surface.vdw_on_surface": ("", "whether the surface feels the tip's van der Waals pull"),
    "numerics.print_step": ("s", "the record's print step"),
    "print_step": ("s", "the record's print step"),
    "numerics.position_noise": ("m", "rms white noise added to the recorded positions"),
    "noise": ("m", "rms white noise added to the recorded positions"),
    "temperature": ("K", "temperature of the thermal noise of the record"),
    "method": ("", "the extraction method"),
    "force_source": ("", "true (the simulator's force) or reconstructed (spectral inversion of z_paddle)"),
    "force": ("", "true (the simulator's force) or reconstructed (spectral inversion of z_paddle)"),
    "status": ("", "the row's status (ok, no_estimate, not_steady, failed)"),
    "sim_status": ("", "the simulation's status"),
    "stop_reason": ("", "why the simulation stopped"),
    "unidentified": ("", "the quantities the method flagged as not identified by the record"),
    "reason": ("", "why a quantity is flagged or missing"),
    "wall_s": ("s", "wall time of the extraction"),
    "quantity": ("", "the quantity of the row (its unit: quantity_units in the metadata)"),
    "value": ("", "the estimate, in the unit of the row's quantity (quantity_units)"),
    "truth": ("", "the true value, in the unit of the row's quantity (quantity_units)"),
    "theory": ("", "the theory value, in the unit of the row's quantity (quantity_units)"),
    "err_pct": ("percent", "signed error of the estimate against the truth"),
    "sigma_pct": ("percent", "the estimate's 1-sigma uncertainty relative to it"),
    "study": ("", "the study the row summarizes"),
    "n_points": ("", "points of the study"),
    "n_ok": ("", "points with status ok"),
    "n_failed": ("", "points with status failed"),
    "W_tau": ("", "decades of cd where the tau_c error is below 30 % (the acceptance regime's width)"),
    "W_cd": ("", "decades of cd where the cd error is below 30 % (status ok)"),
    "W_cd_all": ("", "decades of cd where the cd error is below 30 % (every status)"),
    "cd_lo": ("kg/s", "the acceptance regime's lower cd"),
    "cd_hi": ("kg/s", "the acceptance regime's upper cd"),
    "flagged": ("", "points with a flagged estimate"),
    "extract_s_median": ("s", "median wall time of one extraction"),
    # scripts/trust.py
    "condition": ("", "the record condition: thermal (300 K, reconstructed force), lab (the lab preset), stripped"),
    "material": ("", "index of the drawn material"),
    "k_inf": ("N/m", "the drawn material's relaxed stiffness k_inf"),
    "k0": ("N/m", "the drawn material's instantaneous stiffness k0"),
    "replica": ("", "index of the noisy replica"),
    "seed": ("", "the replica's noise seed"),
    "reference": ("", "the method's answer on the noise-free record of the same path (unit: quantity_units)"),
    "reference_full_band": ("", "the same at the whole band (unit: quantity_units)"),
    "band_bias": ("", "the band term the method estimated on the record (relative; signed where divided out)"),
    "reference_flagged": ("", "the noise-free reference is itself flagged (or missing)"),
    "coverage_sound_ref": ("", "coverage counting only results whose noise-free reference is unflagged"),
    "sigma_rel": ("", "the reported relative 1-sigma"),
    "cutoff_hz": ("Hz", "the reconstruction's low-pass chosen from the record's noise"),
}
for _q in ("tau_c", "k0", "k_inf", "cd"):
    COMMON[f"{_q}_err_pct"] = ("percent", f"signed error of {_q} against the theory value")
for _q in ("k0", "k_inf", "cd"):
    COMMON[f"med_{_q}"] = ("percent", f"median |error| of {_q} over the study's points")
    COMMON[f"med_{_q}_tau"] = ("percent", f"median |error| of {_q} within the acceptance regime")
TABLES = ["results/methods/method_comparison_noisy_reconstructed.parquet",
          "results/methods/method_comparison_summary.parquet",
          "results/noise/stripped_records.parquet", "results/noise/thermal_methods.parquet",
          "results/noise/trust.parquet"]  # fmt: skip


def units_of(columns) -> dict:
    """``{'units': ..., 'descriptions': ..., 'quantity_units': ...}`` for ``columns``; KeyError
    naming a column without a unit (a new column must be added here)."""
    missing = [c for c in columns if c not in COMMON]
    if missing:
        raise KeyError(f"no unit for {missing}; add them to scripts/table_units.py")
    return {"units": {c: COMMON[c][0] for c in columns}, "descriptions": {c: COMMON[c][1] for c in columns},
            "quantity_units": QUANTITY_UNITS}  # fmt: skip


def stamp(path) -> None:
    """Rewrite the table at ``path`` with units and descriptions in its metadata (data unchanged)."""
    df, meta = read_table(path)
    write_table(df, path, {**meta, **units_of(df.columns)})


if __name__ == "__main__":
    for t in TABLES:
        stamp(ROOT / t)
        print(f"stamped {t}")
