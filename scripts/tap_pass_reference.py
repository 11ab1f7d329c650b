"""The tap methods' estimates on a few scan-pixel records, written as the reference the compiled
pass is tested against (tests/test_tap_pass.py, ``tests/data/tap_pass_reference.json``).

The records are the extraction bench's pixels (:data:`vetica_cli.bench.PIXEL`: 4 drive periods at
1 ns) of the stiff (worked example) and soft SLS surfaces (:data:`vetica_cli.bench.SURFACES`),
noise-free and at 300 K (``numerics.temperature=300``); each is extracted with ``vetica`` and
``vetica-prestress`` from the true and the reconstructed force, with error bars and checks.  The
committed file was written by the Python path before the compiled pass (git ad810cf: the Python path with the band term read on the fit's surface; its error bars' tau_c term
then edited as in this version's ``tapsigmas``, the larger of its two propagations), run as

    git archive ad810cf vetica_cli | tar -x -C /tmp/old
    PYTHONPATH=/tmp/old python scripts/tap_pass_reference.py tests/data/tap_pass_reference.json

The two 300 K records' entries were then rewritten by this script on the version whose noisy
recording kernel pulls the surface by the fine kernel's rule (the records changed: their forces
moved by up to 0.5 % of the peak on the stiff surface and 9 % on the soft one, which snaps to the tip,
at the contact onsets) and whose band term declares the
record's noise through its narrower bands, and once more on the version whose Kg error bar carries the
contact-location term of stage 1b's grown window, and once more on the version whose whole-cycle fit
frees the window's start state where an F test says so (the referee's fitted surface, which the band term
reads, moved on the soft 300 K record: its reconstructed-force tau_c +1.9 %), and once more on the version
whose thermal recording takes exact far steps with the sampled noise (another draw of the noise: the
reconstructed-force estimates moved by up to 4.8 % on the stiff record and 15 % on the soft one, the true
force's by up to 0.9 %), and once more on the version whose records drop the approach's first samples to
a length the FFT is fast on (the stiff record's reconstructed-force tau_c +0.22 %, everything else within
5e-5), and once more on the version whose band term tests the record's step to fc/sqrt(2) against the noise
measured on the taps (six sigmas of the stiff record's reconstructed force, by up to 9 %; values and flags as
they were), and once more on the version whose Kg term is a central difference over +-1 sigma (sigmas by up
to 25 %, one flag lifted, values as they were), and -- the two soft records' entries, the noise-free one
too -- once more on the version whose Z1 is the first contact's approach-side well (the soft surface's Z1
moved from its pull-off well to its snap-in, 448 -> 403 pm: its true-force tau_c +32.4 -> +28.9 % off the
truth, k_inf -8.8 -> -6.5 %): for them the file is a regression reference of that version, not the Python
path's (the stiff noise-free entries still are), run as

    PYTHONPATH=. python -c "..."  # estimates() of those records, merged into the file

The file holds ``{"records": {name: config overrides}, "estimates": {name: {"force/method": {quantity:
[value, relative sigma, identifiable]}}}}`` (None where the method gives none).
"""

from __future__ import annotations

import json
import sys

RECORDS = {"stiff": {}, "soft": "soft", "stiff 300 K": {"numerics.temperature": 300.0},
           "soft 300 K": ("soft", {"numerics.temperature": 300.0})}  # fmt: skip
METHODS = ("vetica", "vetica-prestress")
FORCES = ("true", "reconstructed")


def overrides(spec) -> dict:
    """The config overrides of one of :data:`RECORDS`."""
    from vetica_cli.bench import PIXEL, SURFACES

    if spec == "soft":
        return {**PIXEL, **SURFACES["soft"]}
    if isinstance(spec, tuple):
        return {**PIXEL, **SURFACES[spec[0]], **spec[1]}
    return {**PIXEL, **spec}


def estimates(over: dict) -> dict:
    """``{"force/method": {quantity: [value, sigma, identifiable]}}`` of the record the config
    overrides ``over`` simulate."""
    from vetica_cli.extraction import extract
    from vetica_cli.simulation.config import load
    from vetica_cli.simulation.simulate import simulate

    run = simulate(load(None, over))
    df, meta = run.frame(), run.metadata()
    out = {}
    for force in FORCES:
        for method in METHODS:
            res = extract(df, meta, force=force, method=method)
            out[f"{force}/{method}"] = {q: [e.value, e.sigma, e.identifiable] for q, e in res.estimates.items()}
    return out


def main(path: str) -> None:
    records = {name: overrides(spec) for name, spec in RECORDS.items()}
    table = {"records": records, "estimates": {name: estimates(over) for name, over in records.items()}}
    with open(path, "w") as fh:
        json.dump(table, fh, indent=1, allow_nan=True)
        fh.write("\n")


if __name__ == "__main__":
    if len(sys.argv) != 2 or sys.argv[1].startswith("-"):
        sys.exit(f"usage: python {sys.argv[0]} OUT.json  (e.g. tests/data/tap_pass_reference.json)")
    main(sys.argv[1])
