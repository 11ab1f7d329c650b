"""CPU milliseconds of the tap methods per scan-pixel record, split: ``extract()`` whole, without
the whole-cycle fit as referee, the record alone, and the pass after the record (the method's
stages, its error bars and its checks, without the referee, on a fresh record each time).

The records are the extraction bench's (:func:`vetica_cli.bench.extraction_plan`: 4 drive
periods at 1 ns, reconstructed force; the worked example's stiff surface and the blend's soft
one).  The referee has no option to turn it off (it is what makes the tap methods' flags
honest); "without" replaces :func:`vetica_cli.extraction.methods.tapchecks.referee` by one that
confirms nothing, for this measurement only.  Medians of ``--repeat`` calls after two warm-up
calls; run it against another checkout (``PYTHONPATH=/path/to/it``) for a before/after.

    python scripts/tap_pass_timing.py [--repeat 20]
"""

from __future__ import annotations

import argparse
import statistics
import time


from vetica_cli.bench import cpu_ms  # median CPU ms of fn() over repeat calls


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args(argv)

    from vetica_cli.bench import extraction_plan
    from vetica_cli.extraction import extract, get
    from vetica_cli.extraction.methods import tapchecks
    from vetica_cli.extraction.record import build_record
    from vetica_cli.extraction.sanity import check
    from vetica_cli.extraction.uncertainty import calibrate
    from vetica_cli.simulation.simulate import simulate

    referee = tapchecks.referee
    n = args.repeat
    print(f"CPU ms per pixel record, medians of {n}")
    print(f"{'surface':<6} {'method':<17} {'extract':>8} {'no referee':>11} {'record':>7} {'pass':>7}")
    for name, cfg, _ in extraction_plan(None, ("vetica", "vetica-prestress")):
        run = simulate(cfg)
        df, meta = run.frame(), run.metadata()
        for key in ("vetica", "vetica-prestress"):
            m = get(key)
            opts = m.options({})

            def whole():
                extract(df, meta, force="reconstructed", method=key)

            def record():
                return build_record(df, meta, "reconstructed", need_approach=m.needs_approach, need_z1=m.needs_z1,
                                    tap_windows=m.tap_windows)  # fmt: skip

            for _ in range(2):
                whole()
            total = cpu_ms(whole, max(3, n // 4))
            tapchecks.referee = lambda *a, **k: ({}, set(), set())
            try:
                whole()
                bare = cpu_ms(whole, n)
                rec_ms = cpu_ms(record, n)
                records = [record() for _ in range(n + 2)]
                times = []
                for rec in records:
                    t0 = time.process_time()
                    res = m.run(rec, opts)
                    calibrate(res, rec, m, opts)
                    check(res, rec, opts, m)
                    times.append(time.process_time() - t0)
                pass_ms = 1e3 * statistics.median(times[2:])
            finally:
                tapchecks.referee = referee
            print(f"{name:<6} {key:<17} {total:8.2f} {bare:11.2f} {rec_ms:7.2f} {pass_ms:7.2f}", flush=True)


if __name__ == "__main__":
    main()
