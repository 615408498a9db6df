"""Worked example: the 2005 paper's hose-layout question, then a sweep of the hose bore.

Run it from anywhere (about 10 s on a laptop):

    python examples/layout_study.py [OUT_DIR]

1. The layout study (the paper's Figs. 13-14): the hoses between the manifold and the
   servovalve (sections II) at 10, 7.5, 5 and 2.46 ft and removed (manifold close-coupled
   to the valve), the 50 mA open-loop step each time. Shorter hoses ring faster and
   weaker; without them the port pressures no longer oscillate.
2. A full-factorial sweep over two design parameters of the same hoses, their bore and
   length, on local worker processes, written to OUT_DIR/bore_sweep/ (sweep.csv and the
   resumable record sweep.jsonl).

The same from the command line:

    hydroline layout --out OUT_DIR/layout
    hydroline sweep --set 'supply.section2.diameter+return.section2.diameter=12.7 mm,15.9 mm,19.05 mm' \\
                    --set 'supply.section2.length+return.section2.length=0.7512 m,3.048 m' \\
                    --out OUT_DIR/bore_sweep
"""
from __future__ import annotations

import sys
from pathlib import Path

from hydroline.studies import layout, sweep


def main(out="layout-example"):
    out = Path(out)

    # 1. the layout study: lengths in metres (or strings with units, "10 ft")
    study = layout(lengths=[3.048, 2.286, 1.524, 0.7512, 0.0])
    print("Section II layout study (open-loop 50 mA step, default rig):")
    table = study.table()
    print(table.drop(columns=["warnings", "supply_settling_note", "return_settling_note",
                              "settling_band"])
          .to_string(index=False, float_format="%.4g"))
    # settling within +-2 % of the final absolute pressure (table["settling_band"]);
    # settling_method: "measured" within the window (step to piston stop), "estimated" from
    # the decay of the ringing at the stop, "" none -- the note says why
    for L, s in zip(study.lengths, study.summaries):
        for side in ("supply", "return"):
            if s[side]["settling_method"] != "measured":
                print(f"  {L:g} m, {side} settling: {s[side]['settling_note']}")
    files = study.save(out / "layout")
    print(f"figure: {files['figure']}   metrics: {files['csv']}")

    # 2. a sweep: bore and length of both sections II together ("a+b" sets both paths)
    result = sweep({
        "supply.section2.diameter+return.section2.diameter": "12.7 mm,15.9 mm,19.05 mm",
        "supply.section2.length+return.section2.length": "0.7512 m,3.048 m",
    }, workers=2, out=out / "bore_sweep", resume=True)   # resume=True: rerunning skips done rows
    cols = ["supply.section2.diameter", "supply.section2.length", "supply_frequency_hz",
            "supply_amplitude_mpa", "return_frequency_hz", "return_amplitude_mpa", "error"]
    print("\nSections II bore x length (full factorial):")
    print(result.table[cols].to_string(index=False, float_format="%.4g"))
    print(f"table: {result.files['csv']}")


if __name__ == "__main__":
    main(*sys.argv[1:2])
