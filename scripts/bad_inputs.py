"""Bad inputs as a new user types them, and how each ended: one line and exit status 2 with
nothing written (``clean``), a Python traceback (``traceback``), accepted without a word
(``accepted``, exit 0), stopped by the time limit (``runaway``), or something else (``other``).

The kinds: a quantity outside its range or in another unit (config keys, options of every
command, record inputs, a record whose time is in ms or us), a runaway (a scan, advice, simulation
or bench past the cost threshold, long option lists, deep nesting, a large config file), and
files a reader cannot read (CSV, Parquet, YAML).  Every case runs the real ``vetica`` command in
a subprocess (its own process group, killed at the time limit) on a small record it makes first
(``vetica simulate`` of a cheap point, ~5 s warm); nothing is written outside ``--work``.
Prints one line per case and the tallies; exit status 1 when a case did not end clean.

    python scripts/bad_inputs.py [--work /tmp/bad_inputs] [--timeout 60] [-k SUBSTRING] [--command CMD]
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

ROOT = Path(__file__).resolve().parents[1]
CHEAP = ["--set", "numerics.dt=0.05e-9", "--set", "numerics.record_cycles=3", "--set", "numerics.print_step=0.5e-9"]


COMMAND: list[str] = []  # how to run vetica (--command); default the installed console script


def vetica() -> list[str]:
    if COMMAND:
        return COMMAND
    exe = shutil.which("vetica")
    return [exe] if exe else [sys.executable, "-m", "vetica_cli"]


def make_inputs(w: Path) -> dict:
    """The files the cases use: a cheap run, records derived from it, bad configs and files."""
    run = w / "run.parquet"
    if not run.exists():
        subprocess.run([*vetica(), "simulate", *CHEAP, "-o", str(run), "-q"], check=True, cwd=w)
    df = pd.read_parquet(run)
    steady = df[df["segment"] == "steady"][["t", "z_tip", "f_ts"]].reset_index(drop=True)
    files = {"run": run}

    def csv(name, frame):
        files[name] = w / f"{name}.csv"
        frame.to_csv(files[name], index=False)

    csv("record", steady)
    csv("t_ms", steady.assign(t=steady["t"] * 1e3))  # time in ms
    csv("t_us", steady.assign(t=steady["t"] * 1e6))  # time in us
    csv("z_nm", steady.assign(z_tip=steady["z_tip"] * 1e9))  # position in nm
    csv("paddle", df[df["segment"] == "steady"][["t", "z_tip", "z_paddle"]])
    (w / "semicolon.csv").write_text("t;z_tip;f_ts\n0;1e-9;0\n1e-9;2e-9;0\n")
    files["semicolon"] = w / "semicolon.csv"
    (w / "garbage.csv").write_bytes(os.urandom(4096))
    files["garbage"] = w / "garbage.csv"
    (w / "quoted.csv").write_text('t,z_tip,f_ts\n"0,1",1e-9,0\n')
    files["quoted"] = w / "quoted.csv"
    raw = run.read_bytes()
    (w / "truncated.parquet").write_bytes(raw[: len(raw) // 2])
    files["truncated"] = w / "truncated.parquet"
    (w / "empty.parquet").write_bytes(b"")
    files["empty_parquet"] = w / "empty.parquet"
    (w / "folder.parquet").mkdir(exist_ok=True)
    files["folder_parquet"] = w / "folder.parquet"
    table = pq.read_table(run)

    def with_meta(name, value: bytes):
        md = dict(table.schema.metadata or {})
        md[b"vetica"] = value
        files[name] = w / f"{name}.parquet"
        pq.write_table(table.replace_schema_metadata(md), files[name])

    with_meta("meta_list", b"[1, 2, 3]")
    with_meta("meta_params_text", b'{"params": "probe"}')
    with_meta("meta_probe_text", b'{"params": {"probe": 5, "surface": {"k0": "x"}}}')
    with_meta("meta_bad_model", b'{"params": {"surface": {"model": ["sls"]}}}')
    with_meta("meta_k_inf_text", b'{"params": {"surface": {"k_inf": "x", "k0": 1, "cd": 1}}}')
    with_meta("meta_k2_text", b'{"params": {"probe": {"k2": "abc", "f2": 7.5e5, "q2": 1000}}}')
    files["t_text"] = w / "t_text.parquet"
    pq.write_table(pa.table({"t": ["a", "b", "c"], "z_tip": [1e-9, 2e-9, 3e-9], "f_ts": [0.0, 1e-9, 0.0]}),
                   files["t_text"])  # fmt: skip
    # configs
    cfgs = {
        "deep_map": "probe:\n  f1: " + "{a: " * 4000 + "1" + "}" * 4000 + "\n",
        "python_tag": "probe: !!python/object/apply:os.system ['true']\n",
        "tab_indent": "probe:\n\tf1: 5e4\n",
        "hertz_12_arms": "surface:\n  model: hertz\n  arms:\n" + "".join(f"    - {{e: 1.0e9, tau: {10.0 ** -(i % 6 + 3)}}}\n"
                                                                       for i in range(12)),  # fmt: skip
        "hertz_e_inf": "surface: {model: hertz, e_inf: 3.0e16}\n",
        "wiechert_k": "surface:\n  model: wiechert\n  arms: [{k: 2.0e9, cd: 1.0e-4}]\n",
        "sweep_huge_list": "name: big\nsweep:\n  surface.cd: [" + ", ".join(f"{1e-5 * (1 + i * 1e-7):.9e}" for i in range(150000))
        + "]\n",  # ~2.4 MB
        "sweep_bad_value": "name: bad\nsweep:\n  surface.k_inf: [4.0, 4.0e9]\n",
        "sweep_grid": "name: grid\nsweep:\n  surface.cd: {logspace: [-5, 3, 3000]}\n  surface.k0: {linspace: [1, 100, 3000]}\n",
        "scan_1m": "scan: {pixels: [4, 4], size: [0.5, 0.5]}\nsample:\n  background: {height: 0.0}\n",
        "scan_slow": "scan: {pixels: [64, 64], pixel_time: 0.4}\nsample:\n  background: {height: 0.0}\n",
        "scan_stiff": "scan: {pixels: [2, 2]}\nsample:\n  background: {height: 0.0, k0: 5.0e10}\n",
        "utf16": None,
        "binary": None,
    }
    for name, text in cfgs.items():
        files[name] = w / f"{name}.yaml"
        if text is not None:
            files[name].write_text(text)
    files["utf16"].write_bytes("probe: {f1: 5.0e4}\n".encode("utf-16"))
    files["binary"].write_bytes(b"\x89PNG\r\n\x1a\n" + os.urandom(2000))
    return files


def cases(f: dict, w: Path) -> list[tuple[str, str, list[str]]]:
    """``(kind, name, argv)`` of every case; outputs go to ``w/out/`` (checked to stay empty)."""
    o = str(w / "out" / "x.parquet")
    png = str(w / "out" / "x.png")
    ext = lambda rec, *a: ["extract", str(f[rec]), *a]  # noqa: E731
    adv = ["advise", "--k-inf", "4", "--k0", "64", "--cd", "3e-3", "-o", png]
    return [
        # one range per quantity, everywhere it is typed
        ("range", "simulate tip radius 5 mm", ["simulate", "--set", "probe.tip_radius=5e-3", "-o", o]),
        ("range", "simulate k0 1e12 N/m", ["simulate", "--set", "surface.k0=1e12", "-o", o]),
        ("range", "simulate f1 300 Hz", ["simulate", "--set", "probe.f1=300", "-o", o]),
        ("range", "simulate free amplitude 5 cm", ["simulate", "--set", "operation.free_amplitude=0.05", "-o", o]),
        ("range", "simulate temperature 5000 K", ["simulate", "--set", "numerics.temperature=5000", "-o", o]),
        ("range", "simulate dt 1 ms", ["simulate", "--set", "numerics.dt=1e-3", "-o", o]),
        ("range", "simulate hertz e_inf 3e16 Pa", ["simulate", str(f["hertz_e_inf"]), "-o", o]),
        ("range", "simulate wiechert arm k 2e9", ["simulate", str(f["wiechert_k"]), "-o", o]),
        ("range", "bench k_inf 1e20", ["bench", "--set", "surface.k_inf=1e20"]),
        ("range", "sweep with k_inf 4e9 in its list (dry run)", ["sweep", str(f["sweep_bad_value"]), "--dry-run", "-o", o]),
        ("range", "scan 0.5 m x 0.5 m", ["scan", str(f["scan_1m"]), "-o", o]),
        ("range", "scan background k0 5e10", ["scan", str(f["scan_stiff"]), "-o", o]),
        ("range", "extract --k2 1e9 (paddle)", ext("paddle", "--k2", "1e9", "--f2", "750e3", "--q2", "1000", "--a0",
                                                   "0.2e-9", "--vdw-on-surface")),  # fmt: skip
        ("range", "extract --f2 10 Hz", ext("paddle", "--k2", "700", "--f2", "10", "--q2", "1000", "--z1", "1e-9")),
        ("range", "extract --a0 3 nm", ext("record", "--a0", "3e-9", "--vdw-on-surface")),
        ("range", "extract --f1 5 MHz against a 50 kHz record", ext("record", "--f1", "5e6", "--a0", "0.2e-9",
                                                                    "--vdw-on-surface")),  # fmt: skip
        ("range", "extract full --tip-radius 3 m", ext("run", "--method", "full", "--tip-radius", "3")),
        ("range", "extract full --hamaker 1e-10", ext("run", "--method", "full", "--hamaker", "1e-10")),
        ("range", "extract --contact tip_radius=2", ext("run", "--contact", "tip_radius=2")),
        ("range", "extract --contact e_tip=1e20", ext("run", "--contact", "e_tip=1e20")),
        ("range", "observables --q1 1e9", ext("run", "--method", "observables", "--q1", "1e9")),
        ("range", "observables --drive-frequency 5 Hz", ext("run", "--method", "observables", "--drive-frequency", "5")),
        ("range", "observables --k1 5e4", ext("run", "--method", "observables", "--k1", "5e4")),
        ("range", "observables --free-amplitude 20 nm (below A)", ext("run", "--method", "observables",
                                                                      "--free-amplitude", "20e-9")),  # fmt: skip
        ("range", "advise --k0 5e12", ["advise", "--k-inf", "4", "--k0", "5e12", "--cd", "1e-3", "-o", png]),
        ("range", "advise --cd 1e20", ["advise", "--k-inf", "4", "--k0", "64", "--cd", "1e20", "-o", png]),
        ("range", "advise --e-glassy 1e15", ["advise", "--e-glassy", "1e15", "--e-rubbery", "1e9", "--tau-r", "1e-5",
                                             "-o", png]),  # fmt: skip
        ("range", "advise --depth 1 m", ["advise", "--e-glassy", "3e9", "--e-rubbery", "1e8", "--tau-r", "1e-5",
                                         "--depth", "1", "-o", png]),  # fmt: skip
        ("range", "advise --tau-r 1e9 s", ["advise", "--e-glassy", "3e9", "--e-rubbery", "1e8", "--tau-r", "1e9",
                                           "-o", png]),  # fmt: skip
        ("range", "advise --temperature 1e4", [*adv, "--temperature", "1e4"]),
        ("range", "advise --set probe.tip_radius=1e-2", [*adv, "--set", "probe.tip_radius=1e-2"]),
        # record units
        ("units", "extract record with t in ms", ext("t_ms", "--a0", "0.2e-9", "--vdw-on-surface")),
        ("units", "extract record with t in us", ext("t_us", "--a0", "0.2e-9", "--vdw-on-surface")),
        ("units", "extract record with z_tip in nm", ext("z_nm", "--a0", "0.2e-9", "--vdw-on-surface")),
        ("units", "observables on a record with t in ms", ext("t_ms", "--method", "observables", "--free-amplitude",
                                                              "100e-9", "--k1", "10", "--q1", "100", "--f1", "50e3")),  # fmt: skip
        # runaways: bounded before work
        ("runaway", "scan 64x64 at 0.4 s a pixel", ["scan", str(f["scan_slow"]), "-o", o]),
        ("runaway", "advise 25 set points", [*adv, "--setpoint", ",".join(f"{0.3 + 0.02 * i:.2f}" for i in range(25))]),
        ("runaway", "advise 20x20x20x20 settings", [*adv, "--f1", ",".join(str(10e3 + 4e3 * i) for i in range(20)),
                                                   "--setpoint", ",".join(f"{0.3 + 0.025 * i:.3f}" for i in range(20)),
                                                   "--print-step", ",".join(f"{0.5 + 0.35 * i:.2f}e-9" for i in range(20)),
                                                   "--k2", ",".join(str(100 + 50 * i) for i in range(20))]),  # fmt: skip
        ("runaway", "simulate a 300 s transient", ["simulate", "--set", "numerics.steady=transient", "--set",
                                                   "numerics.max_time=300", "-o", o]),  # fmt: skip
        ("runaway", "bench --repeat 50000", ["bench", "--repeat", "50000"]),
        ("runaway", "sweep of 9 million points", ["sweep", str(f["sweep_grid"]), "-o", o]),
        ("runaway", "sweep list of 2.4 MB", ["sweep", str(f["sweep_huge_list"]), "-o", o]),
        ("runaway", "simulate hertz with 12 arms", ["simulate", str(f["hertz_12_arms"]), "-o", o]),
        ("runaway", "config nested 4000 levels", ["simulate", str(f["deep_map"]), "-o", o]),
        ("runaway", "--set value nested 3000 levels", ["simulate", "--set", "probe.f1=" + "[" * 3000 + "]" * 3000,
                                                       "-o", o]),  # fmt: skip
        # readers: one line whatever they raise
        ("reader", "extract semicolon CSV", ext("semicolon")),
        ("reader", "extract random bytes as CSV", ext("garbage")),
        ("reader", "extract CSV with a quoted number", ext("quoted")),
        ("reader", "extract truncated Parquet", ext("truncated")),
        ("reader", "extract empty Parquet", ext("empty_parquet")),
        ("reader", "extract a folder named .parquet", ext("folder_parquet")),
        ("reader", "extract Parquet whose metadata is a list", ext("meta_list")),
        ("reader", "extract Parquet whose params are text", ext("meta_params_text")),
        ("reader", "extract Parquet whose probe is a number", ext("meta_probe_text")),
        ("reader", "extract Parquet whose model is a list", ext("meta_bad_model")),
        ("reader", "extract Parquet whose t is text", ext("t_text")),
        ("reader", "extract Parquet whose k_inf is text", ext("meta_k_inf_text", "--force", "true")),
        ("reader", "extract Parquet whose k2 is text", ext("meta_k2_text")),
        ("reader", "plot Parquet whose metadata is a list", ["plot", str(f["meta_list"]), "-o", str(w / "out")]),
        ("reader", "plot truncated Parquet", ["plot", str(f["truncated"]), "-o", str(w / "out")]),
        ("reader", "simulate config with a python tag", ["simulate", str(f["python_tag"]), "-o", o]),
        ("reader", "simulate config indented by a tab", ["simulate", str(f["tab_indent"]), "-o", o]),
        ("reader", "simulate UTF-16 config", ["simulate", str(f["utf16"]), "-o", o]),
        ("reader", "sweep binary file as config", ["sweep", str(f["binary"]), "-o", o]),
        ("reader", "scan config that is a folder", ["scan", str(w / "out"), "-o", o]),
    ]


def classify(proc: subprocess.CompletedProcess | None, out: Path) -> str:
    if proc is None:
        return "runaway"
    err = proc.stderr.strip()
    if "Traceback" in err:
        return "traceback"
    written = any(out.iterdir())
    if proc.returncode == 0:
        return "accepted"
    if proc.returncode == 2 and len(err.splitlines()) == 1 and not written:
        return "clean"
    return "other"


def run_case(argv: list[str], cwd: Path, timeout: float) -> tuple[subprocess.CompletedProcess | None, float]:
    t0 = time.monotonic()
    p = subprocess.Popen([*vetica(), *argv], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)  # fmt: skip
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        return None, time.monotonic() - t0
    return subprocess.CompletedProcess(argv, p.returncode, out, err), time.monotonic() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, default=Path("/tmp/bad_inputs"), help="folder for the inputs and outputs")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds before a case counts as a runaway")
    ap.add_argument("-k", default="", help="run only the cases whose name contains this")
    ap.add_argument("--command", default="", help="how to run vetica for the cases, e.g. 'env PYTHONPATH=/old "
                    "python -m vetica_cli' to tally another version (the inputs are made with the installed one)")
    a = ap.parse_args()
    a.work.mkdir(parents=True, exist_ok=True)
    files = make_inputs(a.work)
    COMMAND[:] = shlex.split(a.command)
    out = a.work / "out"
    tally: Counter = Counter()
    by_kind: dict = {}
    for kind, name, argv in cases(files, a.work):
        if a.k not in name:
            continue
        shutil.rmtree(out, ignore_errors=True)
        out.mkdir()
        proc, wall = run_case(argv, a.work, a.timeout)
        verdict = classify(proc, out)
        tally[verdict] += 1
        by_kind.setdefault(kind, Counter())[verdict] += 1
        last = "" if proc is None else (proc.stderr.strip().splitlines() or [""])[-1][:150]
        print(f"{verdict:<9} {kind:<7} {wall:5.1f} s  {name}: {last}", flush=True)
    shutil.rmtree(out, ignore_errors=True)
    print("\n" + ", ".join(f"{k}: {dict(v)}" for k, v in by_kind.items()))
    print(f"total {sum(tally.values())}: " + ", ".join(f"{k} {v}" for k, v in tally.most_common()))
    return 0 if set(tally) <= {"clean"} else 1


if __name__ == "__main__":
    sys.exit(main())
