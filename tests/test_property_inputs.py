"""Bad input over every config surface and command, not only simulate and the sweep: malformed YAML (duplicate keys or sections, anchors and aliases),
out-of-range physics, odd records and unwritable outputs, for ``simulate``, ``sweep``,
``scan``, ``advise`` and ``extract``.  Each gives exit 2, one line ``error: ...``, no
traceback and nothing written (``test_bad_inputs.refused``).

The named cases are the issues' own (a 1 m tip radius, a Hamaker constant of 1e-10 J, a
400-digit feature height through ``scan --set``, a sweep count of 1e12, an alias bomb in a
description, f2 = f1, approach_gap = 1 m, 1 m of RMS noise, ``--arms 50``, a feature
outside the scan area, records with jittered or negative time or lengths in nm); the
property tests draw the rest.
"""

import math
import string

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from test_bad_inputs import KEYS, PROPERTY, bad_value, folder, record, refused  # noqa: F401 - record: fixture
from test_scan import line_config

ALIAS_BOMB = "a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n" \
             "c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b]\n"  # fmt: skip
SWEEP = {"numerics": {"record_cycles": 2, "print_step": 1.0e-9}, "sweep": {"surface.cd": [1.0e-5, 1.0e-4]}}


def _write(d, name, data) -> str:
    path = d / name
    path.write_text(data if isinstance(data, str) else yaml.safe_dump(data, sort_keys=False))
    return str(path)


NAMED = [
    # (what, command builder taking the folder, fragments of the message)
    ("simulate: a 1 m tip radius", lambda d: ["simulate", "--set", "probe.tip_radius=1", "-o", d / "r.parquet"],
     ["probe.tip_radius", "1e-06"]),
    ("simulate: a Hamaker constant of 1e-10 J", lambda d: ["simulate", "--set", "surface.hamaker=1e-10", "-o",
     d / "r.parquet"], ["surface.hamaker"]),
    ("simulate: f2 = f1", lambda d: ["simulate", "--set", "probe.f2=50e3", "-o", d / "r.parquet"], ["probe.f2"]),
    ("simulate: approach_gap = 1 m", lambda d: ["simulate", "--set", "numerics.approach_gap=1", "-o",
     d / "r.parquet"], ["numerics.approach_gap"]),
    ("simulate: 1 m of RMS position noise", lambda d: ["simulate", "--set", "numerics.position_noise=1", "-o",
     d / "r.parquet"], ["numerics.position_noise"]),
    ("simulate: duplicate sections", lambda d: ["simulate", _write(d, "c.yaml", "probe: {f1: 5.0e+4}\n"
     "probe: {k1: 2}\n"), "-o", d / "r.parquet"], ["'probe' appears twice"]),
    ("simulate: a duplicate key", lambda d: ["simulate", _write(d, "c.yaml", "probe:\n  k1: 10\n  k1: 2\n"), "-o",
     d / "r.parquet"], ["'k1' appears twice"]),
    ("sweep: a count of 1e12", lambda d: ["sweep", _write(d, "s.yaml", {"sweep": {"surface.cd": {"logspace":
     [-5, 3, 10**12]}}}), "-o", d / "o.parquet", "--dry-run"], ["logspace count", "at most 1000000"]),
    ("sweep: an alias bomb in the description", lambda d: ["sweep", _write(d, "s.yaml", ALIAS_BOMB.replace(
     "a: ", "description: ", 1) + yaml.safe_dump(SWEEP)), "-o", d / "o.parquet"], ["anchor"]),
    ("sweep: a method twice", lambda d: ["sweep", _write(d, "s.yaml", {**SWEEP, "sweep": {"extract.method":
     ["vetica", "vetica"]}}), "-o", d / "o.parquet"], ["appears twice"]),
    ("sweep: a billion points from three keys", lambda d: ["sweep", _write(d, "s.yaml", {"sweep": {
     "surface.cd": {"logspace": [-5, 3, 1000]}, "surface.k0": {"linspace": [1, 100, 1000]},
     "operation.setpoint": {"linspace": [0.3, 0.8, 1000]}}}), "-o", d / "o.parquet", "--dry-run"], ["points"]),
    ("scan: a 400-digit feature height", lambda d: ["scan", _write(d, "m.yaml", line_config()), "--set",
     "sample.features.0.height=1" + "0" * 400, "-o", d / "m.parquet"], ["sample.features.0.height"]),
    ("scan: a feature outside the scan area", lambda d: ["scan", _write(d, "m.yaml", line_config(feature={
     "corner": [1.0e-3, 0.0]})), "-o", d / "m.parquet"], ["overlaps the scan area"]),
    ("scan: a method twice", lambda d: ["scan", _write(d, "m.yaml", line_config(methods=("vetica", "vetica"))),
     "-o", d / "m.parquet"], ["appears twice"]),
    ("scan: an alias", lambda d: ["scan", _write(d, "m.yaml", "n: &n 4\n" + yaml.safe_dump(line_config())), "-o",
     d / "m.parquet"], ["anchor"]),
    ("advise: a 1 m tip radius", lambda d: ["advise", "--k-inf", "4", "--k0", "64", "--cd", "3e-3", "--set",
     "probe.tip_radius=1", "-o", d / "a.png"], ["probe.tip_radius"]),
    ("advise: a method twice", lambda d: ["advise", "--k-inf", "4", "--k0", "64", "--cd", "3e-3", "--methods",
     "full,full", "-o", d / "a.png"], ["named twice"]),
    ("advise: -o under a file", lambda d: ["advise", "--k-inf", "4", "--k0", "64", "--cd", "3e-3", "-o",
     d / "afile" / "a.png"], ["is a file"]),
    ("extract: --arms 50", lambda d: ["extract", d / "ok.csv", "--method", "full", "--arms", "50"], ["--arms"]),
    ("extract: --option arms=50", lambda d: ["extract", d / "ok.csv", "--method", "full", "--option", "arms=50"],
     ["--option arms", "1..8"]),
    ("extract: an option the method does not take", lambda d: ["extract", d / "ok.csv", "--option", "arms=2"],
     ["--option arms", "it takes: kg_points, kr_guess"]),
    ("extract: an option and its flag", lambda d: ["extract", d / "ok.csv", "--method", "full", "--option",
     "arms=2", "--arms", "1"], ["both given"]),
    ("extract: --tip-radius 1", lambda d: ["extract", d / "ok.csv", "--method", "full", "--tip-radius", "1"],
     ["--tip-radius"]),
]  # fmt: skip


@pytest.mark.parametrize("what, argv, fragments", NAMED, ids=[c[0] for c in NAMED])
def test_each_named_nonsense_is_refused_with_one_line(record, what, argv, fragments):  # noqa: F811
    with folder() as d:
        (d / "afile").write_text("x")
        (d / "ok.csv").write_text(record["csv"])
        refused(argv(d), d, *fragments)


# --------------------------------------------------------------------- malformed YAML, every command

BASES = {
    "simulate": {"numerics": {"record_cycles": 2, "print_step": 1.0e-9}},
    "sweep": SWEEP,
    "scan": line_config(),
}


@st.composite
def malformed_yaml(draw):
    """A valid config of a command, made malformed: a top section or a key written twice, or
    an anchor and its alias.  Returns ``(command, yaml text)``."""
    command = draw(st.sampled_from(sorted(BASES)))
    base = BASES[command]
    text = yaml.safe_dump(base, sort_keys=False, default_flow_style=False)
    lines = text.splitlines()
    kind = draw(st.sampled_from(["section", "key", "alias"]))
    if kind == "section":
        sec = draw(st.sampled_from(list(base)))
        lines += yaml.safe_dump({sec: base[sec]}, sort_keys=False, default_flow_style=False).splitlines()
    elif kind == "key":
        nested = [i for i, ln in enumerate(lines) if ln.startswith("  ") and not ln.startswith("   ")
                  and ":" in ln and not ln.strip().startswith("-")]  # fmt: skip
        i = draw(st.sampled_from(nested))
        lines.insert(i + 1, lines[i])
    else:
        name = draw(st.text(string.ascii_lowercase, min_size=1, max_size=6))
        lines = [f"description: &{name} one", *[ln for ln in lines if not ln.startswith("description")],
                 f"name: *{name}"]  # fmt: skip
    return command, "\n".join(lines) + "\n"


@PROPERTY
@given(case=malformed_yaml())
def test_malformed_yaml_is_refused_by_every_command(case):
    command, text = case
    with folder() as d:
        cfg = d / "c.yaml"
        cfg.write_text(text)
        out = d / "o.parquet"
        refused([command, cfg, "-o", out, *(["-q"] if command != "sweep" else ["--dry-run"])], d,
                "appears twice" if "&" not in text else "anchor")  # fmt: skip


# --------------------------------------------------------------------- scan config values

SCAN_KEYS = {
    "scan.pixels": st.one_of(st.just([0, 4]), st.just([5000, 1]), st.just([1]), st.just("x"), st.just([1.5, 2])),
    "scan.size": st.one_of(st.just([0.0, 1e-7]), st.just([-1e-7, 1e-7]), st.just(["a", 1e-7]), st.just(1e-7)),
    "scan.pixel_time": st.one_of(st.floats(-1.0, 0.0), st.just("x"), st.just(float("nan")), st.just([])),
    "scan.steady": st.text(string.ascii_lowercase, min_size=1, max_size=8).filter(
        lambda s: s not in ("transient", "orbit")),
    "scan.methods": st.one_of(st.just(["vetica", "vetica"]), st.just(["nope"]), st.just([]), st.just([1])),
    "sample.background.height": st.one_of(st.just("x"), st.just(float("inf")), st.just(10**400)),
    "sample.features.0.height": st.one_of(st.just(1.0), st.just(-1e-6), st.just(10**400), st.just("h")),
    "sample.features.0.corner": st.one_of(st.just([1.0, 1.0]), st.just([-1.0, -1.0]), st.just("c")),
    "sample.features.0.size": st.one_of(st.just([0.0, 1e-7]), st.just([-1e-7, 1e-7])),
    "sample.features.0.shape": st.text(string.ascii_lowercase, min_size=1, max_size=8).filter(
        lambda s: s not in ("disk", "rectangle")),
}
POINT_KEYS = sorted(k for k, (tp, _) in KEYS.items() if k.split(".")[0] in ("probe", "numerics", "operation")
                    and k not in ("numerics.steady",))  # fmt: skip


@PROPERTY
@given(data=st.data(), via_set=st.booleans())
def test_bad_scan_values_are_refused_before_any_pixel(data, via_set):
    """One value of the scan's own sections, or of its point sections (the sweep's rules),
    out of its rule: through the file or through --set."""
    key = data.draw(st.sampled_from(sorted(SCAN_KEYS) + POINT_KEYS))
    value = data.draw(SCAN_KEYS[key] if key in SCAN_KEYS else bad_value(key))
    raw = line_config()
    with folder() as d:
        out = d / "m.parquet"
        if via_set and not isinstance(value, (list, dict)):
            cfg = _write(d, "m.yaml", raw)
            text = yaml.safe_dump(value, default_flow_style=True).strip().removesuffix("\n...")
            refused(["scan", cfg, "--set", f"{key}={text}", "-o", out, "-q"], d, key.rsplit(".", 1)[0])
            return
        node = raw
        parts = key.split(".")
        for p in parts[:-1]:
            node = node[int(p)] if p.isdigit() else node.setdefault(p, {})
        node[parts[-1]] = value
        refused(["scan", _write(d, "m.yaml", raw), "-o", out, "-q"], d)


# --------------------------------------------------------------------- advise's material and knobs

@PROPERTY
@given(data=st.data())
def test_bad_advise_inputs_are_refused_before_any_simulation(data):
    good = {"--k-inf": "4", "--k0": "64", "--cd": "3e-3"}
    kind = data.draw(st.sampled_from(["material", "knob", "set"]))
    args = dict(good)
    extra: list = []
    if kind == "material":
        opt = data.draw(st.sampled_from(sorted(good)))
        args[opt] = data.draw(st.sampled_from(["0", "-1", "nan", "inf", "x", "1e400"]))
    elif kind == "knob":
        opt = data.draw(st.sampled_from(["--f1", "--setpoint", "--print-step", "--k2"]))
        extra = [opt, data.draw(st.sampled_from(["0", "-1", "1e9", "x", "nan"]))]
    else:
        key = data.draw(st.sampled_from([k for k in POINT_KEYS if k.startswith("probe.") and k not in
                                         ("probe.f1", "probe.f2", "probe.k2")]))  # fmt: skip
        value = data.draw(bad_value(key))
        assume(not isinstance(value, (list, dict)))
        extra = ["--set", f"{key}={yaml.safe_dump(value, default_flow_style=True).strip().removesuffix(chr(10) + '...')}"]
    with folder() as d:
        refused(["advise", *[a for kv in args.items() for a in kv], *extra, "-o", d / "a.png"], d)


# --------------------------------------------------------------------- records an instrument does not write

@settings(max_examples=12, deadline=None)  # a CSV of the record is written and read per example (~0.7 s)
@given(kind=st.sampled_from(["negative", "jitter", "time in us", "z in nm", "f in nN", "decreasing"]),
       size=st.floats(0.05, 0.5))
@pytest.mark.slow
def test_odd_records_are_refused_with_one_line(record, kind, size):  # noqa: F811
    """A record with negative or non-uniform (jittered) time, time in microseconds, lengths
    in nm or forces in nN: one line naming the column, before any extraction."""
    df = pd.read_csv(pd.io.common.StringIO(record["csv"]))
    rng = np.random.default_rng(int(size * 1e6))
    h = float(np.diff(df["t"]).mean())
    if kind == "negative":
        df["t"] -= df["t"].iloc[-1] * (1 + size)
    elif kind == "jitter":
        df["t"] += rng.uniform(-size, size, len(df)) * h * 0.9
    elif kind == "time in us":
        df["t"] *= 1e6
    elif kind == "z in nm":
        df["z_tip"] *= 1e9
    elif kind == "f in nN":
        df["f_ts"] *= 1e9
    else:
        df.loc[len(df) // 2, "t"] = df["t"].iloc[len(df) // 2 - 2]
    column = {"z in nm": "z_tip", "f in nN": "f_ts"}.get(kind, "'t'")
    with folder() as d:
        df.to_csv(d / "odd.csv", index=False)
        z1 = record["z1"] * (1e9 if kind == "z in nm" else 1.0)
        assume(math.isfinite(z1))
        refused(["extract", d / "odd.csv", "--force", "true", "--z1", repr(z1)], d, column)


def test_an_option_by_name_is_the_option_by_flag(record):  # noqa: F811
    """``--option kg_points=12`` (the registry's declaration) gives what ``--kg-points 12`` gives."""
    from typer.testing import CliRunner

    from vetica_cli.cli import app

    with folder() as d:
        (d / "ok.csv").write_text(record["csv"])
        common = ["extract", str(d / "ok.csv"), "--force", "true", "--z1", repr(record["z1"]), "--json"]
        a = CliRunner().invoke(app, [*common, "--option", "kg_points=12"])
        b = CliRunner().invoke(app, [*common, "--kg-points", "12"])
        c = CliRunner().invoke(app, common)
    assert a.exit_code == b.exit_code == c.exit_code == 0, a.output
    import json

    va, vb, vc = (json.loads(r.stdout) for r in (a, b, c))
    assert va["k_g"]["value"] == vb["k_g"]["value"] != vc["k_g"]["value"]
