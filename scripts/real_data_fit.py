"""results/real_data/: ``vetica fit`` on the force curves shipped in the afmformats 0.18.7 source
distribution, and the comparison with the afmformats example's own double-exponential analysis.

    python scripts/real_data_fit.py SR_FOLDER CC_FOLDER [OUT]

SR_FOLDER: the 15 curves of ``examples/data/10.1002_btm2.10294_fig5d-cell1.zip`` unpacked;
CC_FOLDER: ``tests/data/fmt-jpk-cc_*.jpk-force``.  Writes ``relaxation.parquet``,
``creep.parquet``, ``comparison.csv`` and the figures folders in OUT (results/real_data).
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
    df = fit_files([sr], 5e-6, out / "relaxation.parquet", out / "relaxation_figures", progress=False)
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


if __name__ == "__main__":
    main(*sys.argv[1:])
