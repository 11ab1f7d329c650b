"""What a scan table says about the sample: per-domain statistics of every
extracted quantity against its truth, the apparent height of each domain against its true
height (material contrast in topography), and the width of the edge artefact.

Definitions (all on one pass, i.e. one ``(steady, pixel_time)``):

* **interior pixel** (``margin`` m): every pixel within ``m`` pixels of it (the square of
  side ``2m + 1``, clipped at the raster's border) belongs to its domain;
* **domain statistics**: over the interior pixels of a domain with status other than
  ``failed``, the median of each quantity, its spread (half the 16-84 percentile range,
  in % of the median: the 1-sigma of a normal spread), the truth, and the median signed
  error;
* **apparent height**: the median measured ``topography`` of a domain's interior pixels
  minus the background's, against the true difference (``height_true``); their
  difference is the material contrast in topography;
* **edge artefact width** [pixels]: at every change of domain along a line (the fast
  axis), in scan order, the number of consecutive pixels from the first pixel past the
  edge whose value is off the interior median of its own domain by more than the
  tolerance: ``max(rel_tol |median|, 3 x 1.4826 MAD, abs_floor)`` (``rel_tol`` 5 % for
  the extracted quantities; 0.1 nm floor for the topography); the median and the
  largest over the edges.  0 means the first pixel past the edge already reads its
  domain's interior value.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .. import surfaces

REL_TOL = 0.05  # edge artefact: relative tolerance of an extracted quantity
TOPO_FLOOR = 1e-10  # [m] edge artefact: tolerance floor of the topography (0.1 nm)
MARGIN = 1  # interior pixels: every neighbour within this many pixels is in the same domain
SUMMARY_EXTRA = ("tau_c",)  # quantities shown besides the parameters


def passes(table: pd.DataFrame) -> list[tuple[str, float]]:
    """The passes of a table, in table order: ``(steady, pixel_time)``."""
    seen = []
    for st, pt in zip(table["steady"], table["pixel_time"]):
        key = (st, float(pt))
        if not any(k[0] == key[0] and (k[1] == key[1] or (math.isnan(k[1]) and math.isnan(key[1]))) for k in seen):
            seen.append(key)
    return seen


def pass_rows(table: pd.DataFrame, p: tuple[str, float]) -> pd.DataFrame:
    st, pt = p
    sel = (table["steady"] == st) & ((table["pixel_time"] == pt) | (table["pixel_time"].isna() & math.isnan(pt)))
    return table[sel.to_numpy()]


def pass_label(p: tuple[str, float]) -> str:
    return "orbit" if p[0] == "orbit" else f"{p[1] * 1e3:g} ms"


def grid(rows: pd.DataFrame, column: str, shape: tuple[int, int]) -> np.ndarray:
    """A per-pixel column of one pass, method and force source as an ``(ny, nx)`` array (NaN
    where no row)."""
    out = np.full(shape, np.nan)
    out[rows["iy"].to_numpy(), rows["ix"].to_numpy()] = rows[column].to_numpy(float)
    return out


def interior(domain: np.ndarray, margin: int = MARGIN) -> np.ndarray:
    """Pixels whose neighbours within ``margin`` pixels all share their domain (module docstring)."""
    ny, nx = domain.shape
    ok = np.ones_like(domain, dtype=bool)
    for dy in range(-margin, margin + 1):
        for dx in range(-margin, margin + 1):
            src = domain[max(0, dy) : ny + min(0, dy), max(0, dx) : nx + min(0, dx)]
            dst = (slice(max(0, -dy), ny + min(0, -dy)), slice(max(0, -dx), nx + min(0, -dx)))
            ok[dst] &= src == domain[dst]
    return ok


def shape_of(table: pd.DataFrame) -> tuple[int, int]:
    return int(table["iy"].max()) + 1, int(table["ix"].max()) + 1


def one_per_pixel(rows: pd.DataFrame) -> pd.DataFrame:
    """The first row of every pixel (the pixel columns are the same for every method)."""
    return rows.drop_duplicates(subset=["iy", "ix"], keep="first")


def estimate_names(table: pd.DataFrame) -> list[str]:
    """The quantities the table holds (those with a ``_theory`` column), in table order."""
    return [c[: -len("_theory")] for c in table.columns if c.endswith("_theory") and c[: -len("_theory")] in table]


def summary_names(table: pd.DataFrame) -> list[str]:
    """What the summary and the figures show: the surface models' parameters, then the
    retardation time (VETICA's stage 1a) where the table has it."""
    names = estimate_names(table)
    params = list(dict.fromkeys(k for m in surfaces.MODELS.values() for k in m.parameter_keys if k in names))
    return params + [q for q in SUMMARY_EXTRA if q in names and q not in params]


def _spread_pct(v: np.ndarray, med: float) -> float:
    if len(v) < 2 or not med:
        return math.nan
    lo, hi = np.percentile(v, [16, 84])
    return float(50.0 * (hi - lo) / abs(med))


def domain_stats(table: pd.DataFrame, margin: int = MARGIN) -> pd.DataFrame:
    """Per pass, method, force source, domain and quantity: interior pixels, median, spread,
    truth, median signed error (module docstring)."""
    out = []
    names = estimate_names(table)
    for p in passes(table):
        rows = pass_rows(table, p)
        shape = shape_of(table)
        dom = grid(one_per_pixel(rows), "domain", shape).astype(int)
        inner = interior(dom, margin)
        for (method, source), g in rows.groupby(["method", "force_source"], sort=False):
            keep = inner[g["iy"].to_numpy(), g["ix"].to_numpy()] & (g["status"] != "failed").to_numpy()
            g = g[keep]
            for d, gd in g.groupby("domain"):
                for q in names:
                    v = gd[q].to_numpy(float)
                    v = v[np.isfinite(v)]
                    med = float(np.median(v)) if len(v) else math.nan
                    err = gd[f"{q}_err_pct"].to_numpy(float)
                    err = err[np.isfinite(err)]
                    out.append({"steady": p[0], "pixel_time": p[1], "method": method, "force_source": source,
                                "domain": int(d), "quantity": q, "n": len(v), "median": med,
                                "spread_pct": _spread_pct(v, med), "truth": float(np.median(gd[f"{q}_theory"])),
                                "median_err_pct": float(np.median(err)) if len(err) else math.nan})  # fmt: skip
    return pd.DataFrame(out)


def apparent_heights(table: pd.DataFrame, margin: int = MARGIN) -> pd.DataFrame:
    """Per pass and domain: median measured topography of the interior pixels and the true
    height, each relative to the background's; their difference (material contrast)."""
    out = []
    for p in passes(table):
        px = one_per_pixel(pass_rows(table, p))
        shape = shape_of(table)
        dom = grid(px, "domain", shape).astype(int)
        inner = interior(dom, margin)[px["iy"].to_numpy(), px["ix"].to_numpy()]
        px = px[inner & np.isfinite(px["topography"].to_numpy(float))]
        med = px.groupby("domain")[["topography", "height_true"]].median()
        if 0 not in med.index:
            continue
        for d, r in med.iterrows():
            app = r["topography"] - med.loc[0, "topography"]
            true = r["height_true"] - med.loc[0, "height_true"]
            out.append({"steady": p[0], "pixel_time": p[1], "domain": int(d), "n": int((px["domain"] == d).sum()),
                        "topography_median": float(r["topography"]), "apparent_dh": float(app),
                        "true_dh": float(true), "contrast": float(app - true)})  # fmt: skip
    return pd.DataFrame(out)


def _tolerance(v: np.ndarray, rel: float, floor: float) -> float:
    med = float(np.median(v))
    mad = float(np.median(np.abs(v - med)))
    return max(rel * abs(med), 3.0 * 1.4826 * mad, floor)


def edge_runs(values: np.ndarray, domain: np.ndarray, inner: np.ndarray, rel: float, floor: float) -> list[int]:
    """Length of the artefact after every domain change along the lines (module docstring).
    ``values``, ``domain``, ``inner``: ``(ny, nx)`` arrays of one pass."""
    ref = {}
    for d in np.unique(domain):
        v = values[(domain == d) & inner & np.isfinite(values)]
        if len(v):
            ref[int(d)] = (float(np.median(v)), _tolerance(v, rel, floor))
    runs = []
    for iy in range(domain.shape[0]):
        row, dom = values[iy], domain[iy]
        for ix in np.flatnonzero(dom[1:] != dom[:-1]) + 1:
            d = int(dom[ix])
            if d not in ref:
                continue
            med, tol = ref[d]
            n = 0
            while ix + n < len(row) and dom[ix + n] == d and not abs(row[ix + n] - med) <= tol:
                n += 1
            runs.append(n)
    return runs


def edge_widths(table: pd.DataFrame, margin: int = MARGIN) -> pd.DataFrame:
    """Per pass, method, force source and quantity (and the topography): median and largest
    edge-artefact width in pixels, and the number of edges (module docstring)."""
    out = []
    shape = shape_of(table)
    names = summary_names(table)
    for p in passes(table):
        rows = pass_rows(table, p)
        px = one_per_pixel(rows)
        dom = grid(px, "domain", shape).astype(int)
        inner = interior(dom, margin)
        runs = edge_runs(grid(px, "topography", shape), dom, inner, 0.0, TOPO_FLOOR)
        out.append(_width_row(p, "", "", "topography", runs))
        for (method, source), g in rows.groupby(["method", "force_source"], sort=False):
            ok = g[g["status"] != "failed"]
            for q in names:
                runs = edge_runs(grid(ok, q, shape), dom, inner, REL_TOL, 0.0)
                out.append(_width_row(p, method, source, q, runs))
    return pd.DataFrame(out)


def _width_row(p, method, source, q, runs) -> dict:
    return {"steady": p[0], "pixel_time": p[1], "method": method, "force_source": source, "quantity": q,
            "edges": len(runs), "median_px": float(np.median(runs)) if runs else math.nan,
            "max_px": int(max(runs)) if runs else -1}  # fmt: skip


# ----------------------------------------------------------------------------- text


def _fmt(v: float) -> str:
    return "–" if v is None or not math.isfinite(v) else f"{v:.4g}"


def summary_markdown(table: pd.DataFrame, meta: dict, margin: int = MARGIN) -> str:
    """The three measures as Markdown tables (what ``vetica scan`` prints at the end)."""
    names = (meta.get("scan") or {}).get("domains") or []

    def dname(d: int) -> str:
        return names[d] if d < len(names) else str(d)

    lines = [f"Interior pixels: every neighbour within {margin} pixel(s) in the same domain; errors signed, %.", ""]
    st = domain_stats(table, margin)
    params = summary_names(table)
    if len(st):
        lines += ["| pass | method | force | domain | n | " + " | ".join(f"{q} median (truth) ±spread %, err %" for q in params) + " |",
                  "|---" * (5 + len(params)) + "|"]  # fmt: skip
        for (stdy, pt, method, source, d), g in st.groupby(["steady", "pixel_time", "method", "force_source", "domain"],
                                                            sort=False, dropna=False):  # fmt: skip
            g = g.set_index("quantity")
            cells = [f"{_fmt(g.loc[q, 'median'])} ({_fmt(g.loc[q, 'truth'])}) ±{_fmt(g.loc[q, 'spread_pct'])}, "
                     f"{_fmt(g.loc[q, 'median_err_pct'])}" for q in params if q in g.index]  # fmt: skip
            n = int(g["n"].iloc[0])
            lines.append(
                f"| {pass_label((stdy, pt))} | {method} | {source} | {dname(d)} | {n} | " + " | ".join(cells) + " |"
            )
    else:
        lines.append(f"No interior pixels: the map is too small for a margin of {margin} pixel(s); no per-domain measures.")
    ah = apparent_heights(table, margin)
    if len(ah):
        lines += [
            "",
            "| pass | domain | true Δh [nm] | apparent Δh [nm] | material contrast [nm] |",
            "|---|---|---|---|---|",
        ]
        for _, r in ah[ah["domain"] != 0].iterrows():
            lines.append(f"| {pass_label((r['steady'], r['pixel_time']))} | {dname(int(r['domain']))} | "
                         f"{r['true_dh'] * 1e9:.3f} | {r['apparent_dh'] * 1e9:.3f} | {r['contrast'] * 1e9:+.3f} |")  # fmt: skip
    ew = edge_widths(table, margin)
    if len(ew) and (ew["edges"] > 0).any():
        lines += ["", "Edge artefact width [pixels], median / largest over the edges along x:", "",
                  "| pass | method | force | " + " | ".join(["topography", *params]) + " |",
                  "|---" * (4 + len(params)) + "|"]  # fmt: skip
        for p in passes(table):
            sel = ew[
                (ew["steady"] == p[0]) & ((ew["pixel_time"] == p[1]) | (ew["pixel_time"].isna() & math.isnan(p[1])))
            ]
            topo = sel[sel["quantity"] == "topography"].iloc[0]
            for (method, source), g in sel[sel["quantity"] != "topography"].groupby(
                ["method", "force_source"], sort=False
            ):
                g = g.set_index("quantity")
                cells = [f"{_fmt(topo['median_px'])} / {topo['max_px']}"]
                cells += [f"{_fmt(g.loc[q, 'median_px'])} / {g.loc[q, 'max_px']}" for q in params if q in g.index]
                lines.append(f"| {pass_label(p)} | {method} | {source} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
