"""The flags of the method studies' tables against the truth: of the results within 10 % of the
truth, how many are flagged, and the silently wrong ones (unflagged, off the truth by more than 10 %
and more than 3 sigma; every quantity, each with its own flag and sigma), listed.

    python scripts/table_trust.py                    # results/methods/*.parquet as they are now
    python scripts/table_trust.py --rev HEAD~3        # the same tables at a git revision

Counts every method and force source of results/methods' five studies (status ok rows); *right*
counts tau_c, k_g, k_r, tau_r, k0, k_inf and cd.
"""

from __future__ import annotations

import argparse
import io
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parent.parent
STUDIES = ("method_dashpot", "method_stiffness_ratio", "method_noise_reconstructed", "method_low_cd", "method_pull")
RIGHT = ("tau_c", "k_g", "k_r", "tau_r", "k0", "k_inf", "cd")
TOLERANCE_PCT = 10.0


def table(name: str, rev: str | None) -> pd.DataFrame:
    rel = f"results/methods/{name}.parquet"
    if rev is None:
        return pd.read_parquet(ROOT / rel)
    blob = subprocess.run(["git", "show", f"{rev}:{rel}"], cwd=ROOT, check=True, capture_output=True).stdout
    return pd.read_parquet(io.BytesIO(blob))


def count(rev: str | None = None) -> tuple[int, int, list]:
    """``(right, right and flagged, silently wrong rows)`` over the five studies."""
    right = flagged = 0
    silent = []
    for name in STUDIES:
        for _, r in table(name, rev).iterrows():
            if r["status"] != "ok":
                continue
            flags = set(str(r.get("unidentified") or "").split(",")) - {""}
            for q in RIGHT:
                e = r.get(f"{q}_err_pct")
                if e is None or not np.isfinite(e):
                    continue
                s = r.get(f"{q}_sigma_pct")
                if abs(e) <= TOLERANCE_PCT:
                    right += 1
                    flagged += q in flags
                elif q not in flags and not (s is not None and np.isfinite(s) and abs(e) <= 3 * s):
                    silent.append((name, r["point"], r["method"], r.get("force_source"), q, float(e), s))
    return right, flagged, silent


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rev", default=None, help="a git revision (default: the working tree)")
    args = p.parse_args(argv)
    right, flagged, silent = count(args.rev)
    print(f"within 10 % of the truth: {right}, of them flagged: {flagged}; silently wrong: {len(silent)}")
    for name, point, method, force, q, e, s in silent:
        print(f"  {name} {point} {method} {force} force: {q} {e:+.3g} % at a sigma of "
              + ("none" if s is None or not np.isfinite(s) else f"{s:.3g} %"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
