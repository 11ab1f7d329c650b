"""results/real_data/: ``vetica fit`` on the force curves shipped in the afmformats 0.18.7 source
distribution, and the comparison with the afmformats example's own double-exponential analysis.

    python scripts/real_data_fit.py SR_FOLDER CC_FOLDER [OUT]
    python scripts/real_data_fit.py --force-distance FOLDER... [--out OUT]
    python scripts/real_data_fit.py --survey FOLDER... [--out OUT]

SR_FOLDER: the 15 curves of ``examples/data/10.1002_btm2.10294_fig5d-cell1.zip`` unpacked;
CC_FOLDER: ``tests/data/fmt-jpk-cc_*.jpk-force``.  Writes ``relaxation.parquet``,
``creep.parquet``, ``comparison.csv`` and the figures folders in OUT (results/real_data).

``--force-distance``: the force-distance curves and maps of the folders (afmformats'
``tests/data`` and ``docs/data``), Ting with the power law and with Maxwell arms:
``force_distance.parquet``, ``force_distance_maxwell.parquet``, ``force_distance_figures/``.

``--survey``: every file of the packages' data folders (each content once) given to ``vetica
fit`` in one batch, as a user would: ``survey.csv`` (per file: rows by status, the first reason) and the
check that the command printed no traceback.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from vetica_cli.curves.batch import fit_files
from vetica_cli.curves.read import read_curves
from vetica_cli.curves.reference import double_exponential


def main(sr: str, cc: str, out: str = "results/real_data") -> None:
    out = Path(out)
    df = fit_files([sr], 5e-6, out / "relaxation.parquet", out / "relaxation_figures", progress=False).table
    fit_files([cc], 5e-6, out / "creep.parquet", out / "creep_figures", progress=False)
    rows = []
    for c in read_curves([sr]):
        dwell = c.segment == 1
        ref = double_exponential(c.t[dwell], c.force[dwell])
        mine = df[(df["file"] == Path(c.source).name)].set_index("arms")
        rows.append({"file": Path(c.source).name, "tau_1": mine.loc[2, "tau_1"], "d1_afmformats": ref["d1"],
                     "tau_2": mine.loc[2, "tau_2"], "d2_afmformats": ref["d2"],
                     "dev_1_percent": 100 * (mine.loc[2, "tau_1"] / ref["d1"] - 1),
                     "dev_2_percent": 100 * (mine.loc[2, "tau_2"] / ref["d2"] - 1),
                     "bic_1arm_minus_2arm": mine.loc[1, "bic"] - mine.loc[2, "bic"],
                     "rms_1arm_nN": 1e9 * mine.loc[1, "residual_rms"], "rms_2arm_nN": 1e9 * mine.loc[2, "residual_rms"],
                     "rms_3arm_nN": 1e9 * mine.loc[3, "residual_rms"],
                     "arms_selected": int(mine.index[mine["selected"]][0])})  # fmt: skip
    comp = pd.DataFrame(rows)
    comp.to_csv(out / "comparison.csv", index=False, float_format="%.5g")
    print(comp.to_string(float_format=lambda v: f"{v:.4g}"))
    print(comp[["dev_1_percent", "dev_2_percent", "bic_1arm_minus_2arm"]].describe().to_string())


def force_distance(folders: list[str], out: str = "results/real_data") -> None:
    out = Path(out)
    files = unique_files(folders, (".jpk-force", ".jpk-force-map", ".jpk-qi-data", ".jpk-qi-series", ".h5", ".tab"))
    pl = fit_files(files, 5e-6, out / "force_distance.parquet", out / "force_distance_figures", progress=False)
    mx = fit_files(files, 5e-6, out / "force_distance_maxwell.parquet", None, modulus="maxwell", progress=False)
    for name, res in (("power law", pl), ("maxwell", mx)):
        df = res.table
        print(name, res.summary())
        print(df.groupby(["modality", "status"]).size().to_string())
    cols = ["file", "curve", "status", "e_hertz", "e0", "se_e0", "beta", "se_beta", "residual_rms", "force_max",
            "fit_cpu_s"]  # fmt: skip
    print(pl.table[[c for c in cols if c in pl.table]].to_string(float_format=lambda v: f"{v:.4g}"))


def unique_files(folders, suffixes=None) -> list[Path]:
    """Every file under the folders (recursively, sorted), each content once."""
    import hashlib

    seen, out = set(), []
    for folder in folders:
        for f in sorted(Path(folder).rglob("*")):
            if not f.is_file() or (suffixes and f.suffix not in suffixes):
                continue
            h = hashlib.sha1(f.read_bytes()).hexdigest()
            if h not in seen:
                seen.add(h)
                out.append(f)
    return out


def survey(folders: list[str], out: str = "results/real_data") -> None:
    import subprocess
    import tempfile

    out = Path(out)
    files = [f for f in unique_files(folders) if "data" in f.parts]  # the packages' data folders (tests, docs, examples)
    with tempfile.TemporaryDirectory() as tmp:
        table = Path(tmp) / "survey.parquet"
        r = subprocess.run([sys.executable, "-m", "vetica_cli", "fit", *map(str, files), "--tip-radius", "5e-6",
                            "-o", str(table), "-q", "-j", "2"], capture_output=True, text=True)  # fmt: skip
        print(f"exit {r.returncode}; stderr lines {len(r.stderr.splitlines())}; traceback: {'Traceback' in r.stderr}")
        df = pd.read_parquet(table)
    rows = []
    for f in files:
        g = df[df["path"] == str(f)]
        counts = g.groupby(["path", "curve"])["status"].agg(lambda s: "ok" if (s == "ok").any() else s.iloc[0])
        bad = g[g["error"] != ""]
        pkg = next(Path(d).name for d in folders if Path(d).resolve() in f.resolve().parents)
        rows.append({"package": pkg,
                     "file": str(f.resolve().relative_to(next(Path(d).resolve() for d in folders
                                                              if Path(d).resolve() in f.resolve().parents))),
                     "curves": int(counts.size) if (g["curve"] >= 0).any() else 0,
                     "ok": int((counts == "ok").sum()),
                     "flagged": int(counts.isin(("not_converged", "tau_beyond_window", "se_exceeds_value")).sum()),
                     "refused": int(counts.isin(("unreadable", "unsuited", "failed")).sum()),
                     "reason": bad["error"].iloc[0] if len(bad) and not (counts == "ok").all() else ""})  # fmt: skip
    sv = pd.DataFrame(rows)
    sv.to_csv(out / "survey.csv", index=False)
    print(sv.to_string())
    print(sv[["curves", "ok", "flagged", "refused"]].sum().to_string())


if __name__ == "__main__":
    args = sys.argv[1:]
    dest = "results/real_data"
    if "--out" in args:
        i = args.index("--out")
        dest = args[i + 1]
        del args[i : i + 2]
    if args and args[0] == "--force-distance":
        force_distance(args[1:], dest)
    elif args and args[0] == "--survey":
        survey(args[1:], dest)
    else:
        main(*args)
