"""CPU cost of one extraction (``method="full"`` and ``method="vetica"``, whose referee is the
whole-cycle fit) on three records: the 300 K worked example (10 periods at 0.125 ns, force
reconstructed from the paddle), a pixel-size 300 K record (4 periods at 1 ns) and a noise-free
worked example.  Prints the median CPU ms (``time.process_time``) of ``--repeat`` runs per record
and method, the methods interleaved; ``--dump DIR`` also writes each extraction's JSON
(``vetica extract --json`` without its timings) to DIR, so two versions can be compared
(``--compare DIR_A DIR_B``: the largest relative difference of every number).  For an A/B
comparison of two versions run it alternately with ``PYTHONPATH`` at each version's tree
(``--cache DIR`` simulates the records once and reuses them)."""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path

RECORDS = {
    "300K-long": {"numerics.temperature": 300},
    "300K-pixel": {"numerics.temperature": 300, "numerics.record_cycles": 4, "numerics.print_step": 1e-9},
    "noise-free": {},
}
METHODS = ("full", "vetica")


def record(overrides: dict):
    from vetica_cli.simulation.config import load
    from vetica_cli.simulation.simulate import simulate

    run = simulate(load(None, overrides))
    return run.frame(), run.metadata()


def result_json(res) -> dict:
    """The extraction's JSON without what varies from run to run (timings)."""
    from vetica_cli.extraction.format import to_json

    out = json.loads(json.dumps(to_json(res), default=str))
    out["info"].pop("timing_s", None)
    return out


def numbers(x, path=""):
    """``{path: value}`` of every leaf of a JSON object."""
    if isinstance(x, dict):
        for k, v in x.items():
            yield from numbers(v, f"{path}/{k}")
    elif isinstance(x, list):
        for i, v in enumerate(x):
            yield from numbers(v, f"{path}/{i}")
    else:
        yield path, x


def compare(a: Path, b: Path) -> int:
    """Print the largest relative difference per file; non-numbers must be equal."""
    bad = 0
    for fa in sorted(a.glob("*.json")):
        ja, jb = json.loads(fa.read_text()), json.loads((b / fa.name).read_text())
        na, nb = dict(numbers(ja)), dict(numbers(jb))
        worst, where, other = 0.0, "", []
        for k in sorted(set(na) | set(nb)):
            va, vb = na.get(k), nb.get(k)
            if isinstance(va, float) and isinstance(vb, float) and not isinstance(va, bool):
                d = 0.0 if va == vb else abs(va - vb) / max(abs(va), abs(vb))
                if d > worst:
                    worst, where = d, k
            elif va != vb:
                other.append(k)
        est = {q: v for q, v in ja.items() if isinstance(v, dict) and "value" in v}
        rel = {}
        for q in est:
            for f in ("value", "sigma"):
                va, vb = ja[q].get(f), jb[q].get(f)
                if isinstance(va, float) and isinstance(vb, float):
                    rel[f"{q}.{f}"] = 0.0 if va == vb else abs(va - vb) / max(abs(va), abs(vb))
                elif va != vb:
                    other.append(f"{q}.{f}")
        print(f"{fa.stem}: max rel diff {worst:.3g} ({where or 'all equal'}); estimates+sigmas max "
              f"{max(rel.values(), default=0.0):.3g}; other differences: {other or 'none'}")
        bad += bool(other)
    return bad


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--records", nargs="*", default=list(RECORDS))
    ap.add_argument("--methods", nargs="*", default=list(METHODS))
    ap.add_argument("--dump", type=Path, default=None)
    ap.add_argument("--cache", type=Path, default=None, help="pickle the simulated records here (reused)")
    ap.add_argument("--compare", nargs=2, type=Path, default=None)
    args = ap.parse_args(argv)
    if args.compare:
        return compare(*args.compare)
    from vetica_cli import api

    for name in args.records:
        if args.cache is not None:
            import pickle

            path = args.cache / f"{name}.pkl"
            if path.exists():
                data = pickle.loads(path.read_bytes())
            else:
                data = record(RECORDS[name])
                args.cache.mkdir(parents=True, exist_ok=True)
                path.write_bytes(pickle.dumps(data))
        else:
            data = record(RECORDS[name])
        for m in args.methods:  # compile and warm
            res = api.extract(data, method=m)
            if args.dump is not None:
                args.dump.mkdir(parents=True, exist_ok=True)
                (args.dump / f"{name}.{m}.json").write_text(json.dumps(result_json(res), indent=1))
        times = {m: [] for m in args.methods}
        for _ in range(args.repeat):
            for m in args.methods:
                t = time.process_time()
                api.extract(data, method=m)
                times[m].append(1e3 * (time.process_time() - t))
        for m in args.methods:
            ts = times[m]
            print(f"{name:11s} {m:7s} CPU ms median {statistics.median(ts):7.1f}  (min {min(ts):.1f}, max "
                  f"{max(ts):.1f}, n={len(ts)})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
