"""Figures of a ``vetica fit`` batch: data against the fits per curve, histograms of the
selected models' parameters, and a map image when the curves come from a force map."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io import atomic_path


def _save(fig, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=path.suffix[1:], dpi=120)


def write_figures(df, traces, folder) -> list[Path]:
    """``fit_<curve>.png`` per fitted curve, ``parameters.png`` and, for a force map,
    ``map_<param>.png``; returns the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, tr in traces:
        if tr is None:
            continue
        fig, ax = plt.subplots(figsize=(6, 3.6))
        t = tr["t"]
        ax.plot(t, tr["force"] * 1e9, color="k", lw=2.5, label="data")
        sel = df[(df["file"] + "#" + df["curve"].astype(str) == name) & (df["status"] == "ok")]
        for n, color in zip((1, 2, 3), ("tab:blue", "tab:red", "tab:green")):
            if n in tr:
                row = sel[sel["arms"] == n]
                mark = " (selected)" if len(row) and bool(row["selected"].iloc[0]) else ""
                taus = ", ".join(f"{row[f'tau_{k}'].iloc[0]:.3g}" for k in range(1, n + 1)) if len(row) else ""
                ax.plot(t, tr[n] * 1e9, color=color, lw=1, label=f"{n} arm{'s' * (n > 1)}: tau = {taus} s{mark}")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("force [nN]")
        ax.set_title(f"{name}: Lee-Radok fits", fontsize=9)
        ax.legend(fontsize=7)
        fig.tight_layout()
        path = folder / f"fit_{name.replace('#', '_')}.png"
        _save(fig, path)
        plt.close(fig)
        written.append(path)
    ok = df[(df["status"] == "ok") & df["selected"]]
    if len(ok):
        params = [c for c in ("e_inf", "e_1", "e_2", "e_3", "tau_1", "tau_2", "tau_3") if c in ok and ok[c].notna().any()]
        fig, axes = plt.subplots(1, len(params), figsize=(2.4 * len(params), 2.6))
        for ax, p in zip(np.atleast_1d(axes), params):
            v = ok[p].dropna()
            ax.hist(v, bins=max(5, int(np.sqrt(len(v)))), color="0.4")
            ax.set_xlabel(f"{p} [{'s' if p.startswith('tau') else 'Pa'}]")
        np.atleast_1d(axes)[0].set_ylabel("curves (selected model)")
        fig.tight_layout()
        path = folder / "parameters.png"
        _save(fig, path)
        plt.close(fig)
        written.append(path)
        grid = ok[(ok["grid_x"] >= 0) & (ok["grid_y"] >= 0)] if "grid_x" in ok else ok.iloc[:0]
        if len(grid) > 1:
            for p in ("e_inf", "tau_1"):
                img = np.full((int(grid["grid_y"].max()) + 1, int(grid["grid_x"].max()) + 1), np.nan)
                img[grid["grid_y"].astype(int), grid["grid_x"].astype(int)] = grid[p]
                fig, ax = plt.subplots(figsize=(4, 3.4))
                im = ax.imshow(img, origin="lower")
                fig.colorbar(im, ax=ax, label=f"{p} [{'s' if p.startswith('tau') else 'Pa'}]")
                ax.set_xlabel("grid x")
                ax.set_ylabel("grid y")
                path = folder / f"map_{p}.png"
                _save(fig, path)
                plt.close(fig)
                written.append(path)
    return written
