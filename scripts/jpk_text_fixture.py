"""Write the JPK text-export fixture of the tests: afmformats' spot3 force-distance curve
(tests/data/afmformats/fmt-jpk-fd_spot3-0192.jpk-force, MIT) as JPK's data-processing software
exports a force curve to text (the header keys vetica_cli/curves/jpktxt.py documents), every
4th sample, the deflection in V (so reading it needs the sensitivity and spring constant the
header carries), the measured and the piezo height in m, series and segment time in s.

    python scripts/jpk_text_fixture.py   # writes tests/data/jpktext/spot3-0192-export.txt
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vetica_cli.curves.read import load_file

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "tests" / "data" / "afmformats" / "fmt-jpk-fd_spot3-0192.jpk-force"
TARGET = ROOT / "tests" / "data" / "jpktext" / "spot3-0192-export.txt"
EVERY = 4


def main() -> None:
    d = load_file(SOURCE)[0]
    k, sens = d.metadata["spring constant"], d.metadata["sensitivity"]
    lines = ["# TEXT EXPORT", "# data-description.comment: written by scripts/jpk_text_fixture.py from "
             + SOURCE.name, "# data-description.instrument: A0042-CellHesion", "# index: 0",
             f"# xPosition: {d.metadata['position x']!r}", f"# yPosition: {d.metadata['position y']!r}",
             "# feedbackMode: contact", "#"]  # fmt: skip
    for i, (kind, seg) in enumerate((("extend", d.appr), ("retract", d.retr))):
        t = np.asarray(seg["time"])[::EVERY]
        volts = np.asarray(seg["force"])[::EVERY] / k / sens
        hm = np.asarray(seg["height (measured)"])[::EVERY]
        hp = np.asarray(seg["height (piezo)"])[::EVERY]
        lines += [f"# segmentIndex: {i}", f"# recorded-num-points: {t.size}", f"# segment: {kind}",
                  "# columns: vDeflection strainGaugeHeight height seriesTime time",
                  '# fancyNames: "Vertical Deflection" "Height (measured)" "Height" "Series Time" "Segment Time"',
                  f"# sensitivity: {sens!r}", f"# springConstant: {k!r}",
                  "# calibrationSlots: volts distance distance elapsed elapsed", "# units: V m m s s", "#"]  # fmt: skip
        lines += [f"{v:.7g} {a:.8g} {b:.8g} {tt:.7g} {tt - t[0]:.7g}" for v, a, b, tt in zip(volts, hm, hp, t)]
        lines.append("")
    TARGET.parent.mkdir(parents=True, exist_ok=True)
    TARGET.write_text("\n".join(lines) + "\n")
    print(f"wrote {TARGET} ({TARGET.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
