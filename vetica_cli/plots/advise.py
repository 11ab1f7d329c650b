"""The map of ``vetica advise``: the score of every setting.

One panel per (paddle stiffness k2, print step); in each, drive frequency f1 across and
set point up, each cell coloured by the score (green: every method recovers the
material, the greener the larger the margin; red: at least one does not; grey: no score,
the cell saying why -- a method gave no value for some quantity, no proven periodic
state, or a failed simulation), its value written in the cell and the recovering cells
outlined.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..study.acceptance import ACCEPT_ERR_PCT
from ..advise import PARAM_LIMIT_PCT, Advice
from .style import new_figure, save_png

SCORE_LIMITS = (-1.0, 1.0)  # colour scale of the score (clipped)


def advice_figure(adv: Advice):
    """The figure (module docstring)."""
    t = adv.table
    k2s = sorted(t["probe.k2"].unique())
    steps = sorted(t["numerics.print_step"].unique())
    f1s = sorted(t["probe.f1"].unique())
    sps = sorted(t["operation.setpoint"].unique())
    fig = new_figure(2.6 * len(steps) + 1.6, 2.3 * len(k2s) + 1.3)
    axes = fig.subplots(len(k2s), len(steps), squeeze=False, sharex=True, sharey=True)
    cmap = _cmap()
    image = None
    for i, k2 in enumerate(k2s):
        for j, ps in enumerate(steps):
            ax = axes[i][j]
            g = t[(t["probe.k2"] == k2) & (t["numerics.print_step"] == ps)]
            grid = np.full((len(sps), len(f1s)), np.nan)
            ok = np.zeros_like(grid, dtype=bool)
            why = {}
            for _, r in g.iterrows():
                a, b = sps.index(r["operation.setpoint"]), f1s.index(r["probe.f1"])
                grid[a, b], ok[a, b] = r["score"], bool(r["recovered"])
                why[a, b] = _no_score(r, adv.methods)
            image = ax.imshow(np.clip(grid, *SCORE_LIMITS), origin="lower", cmap=cmap, vmin=SCORE_LIMITS[0],
                              vmax=SCORE_LIMITS[1], aspect="auto")  # fmt: skip
            _annotate(ax, grid, ok, why)
            ax.set_xticks(range(len(f1s)), [f"{f / 1e3:g}" for f in f1s])
            ax.set_yticks(range(len(sps)), [f"{s:g}" for s in sps])
            ax.set_title(f"$k_2$ {k2:g} N/m, PS {ps * 1e9:g} ns", fontsize=9)
            if i == len(k2s) - 1:
                ax.set_xlabel("$f_1$ [kHz] ($f_2 = 15 f_1$)")
            if j == 0:
                ax.set_ylabel("set point $A_{sp}/A_0$")
    m = adv.material
    fig.suptitle(
        f"vetica advise: $k_\\infty$ {m.k_inf:.3g} N/m, $k_0$ {m.k0:.3g} N/m, $c_d$ {m.cd:.3g} kg/s; "
        f"{' and '.join(adv.methods)}, {adv.force} force\n"
        f"score = min over methods of min(1 - |error|/limit): $\\tau_c$ {ACCEPT_ERR_PCT:g} %, "
        f"$k_0, k_\\infty, c_d$ {PARAM_LIMIT_PCT:g} %\n(outlined: recovered; grey: no score, the cell says why)",
        fontsize=9,
    )
    if image is not None:
        fig.colorbar(image, ax=axes, shrink=0.8, label="score (clipped to [-1, 1])")
    return fig


def _cmap():
    import matplotlib

    return matplotlib.colormaps["RdYlGn"].with_extremes(bad="0.8")


def _no_score(r, methods) -> str:
    """Why a setting has no score: its status, else the methods that gave no value."""
    status = str(r.get("status", "ok"))
    if status == "failed":
        return "failed"
    if status == "not_steady":
        return "not\nsteady"
    silent = [m for m in methods if not math.isfinite(float(r.get(f"{m}.margin", math.nan)))]
    return "no value:\n" + "\n".join(silent) if silent else "no score"


def _annotate(ax, grid, ok, why) -> None:
    for a in range(grid.shape[0]):
        for b in range(grid.shape[1]):
            v = grid[a, b]
            text = why.get((a, b), "-") if not math.isfinite(v) else f"{v:.2f}"
            ax.text(b, a, text, ha="center", va="center", fontsize=7 if math.isfinite(v) else 6)
            if ok[a, b]:
                ax.add_patch(_outline(a, b))


def _outline(a: int, b: int):
    from matplotlib.patches import Rectangle

    return Rectangle((b - 0.5, a - 0.5), 1, 1, fill=False, lw=2.0, ec="k")


def write_advice_figure(adv: Advice, path: str | Path) -> Path:
    """Draw :func:`advice_figure` and write it as a PNG (atomically)."""
    return save_png(advice_figure(adv), Path(path))
