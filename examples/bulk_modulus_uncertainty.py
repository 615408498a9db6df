"""Worked example: how uncertain are the port oscillations if the hoses' effective bulk
modulus is only known to +-10 %?

    python examples/bulk_modulus_uncertainty.py [N_SAMPLES] [OUT_DIR]

A random design (Monte Carlo) over the effective bulk modulus of the hose sections: the
supply sections' (both take the same draw) from a normal distribution about the rig's value
with a standard deviation of 6 %, the return sections' likewise, independently; the means
are read from the rig (203.8 MPa supply, 140.8 MPa return on the default rig). On local worker
processes. Prints the 5/50/95 % points of each metric and writes OUT_DIR/sweep.csv. Stop it
at any time (Ctrl-C) and run it again: it resumes from OUT_DIR/sweep.jsonl; run it with a
larger N and the first variants are kept (variant i is drawn from its own random stream).

The same from the command line:

    hydroline sweep --samples 64 --seed 1 \\
        --set 'supply.section1.bulk_modulus+supply.section2.bulk_modulus=normal(203.8 MPa, 12.23 MPa)' \\
        --set 'return.section1.bulk_modulus+return.section2.bulk_modulus=normal(140.8 MPa, 8.45 MPa)' \\
        --out bulk-modulus-mc --resume

(add ``--scheduler tcp://host:8786`` to run it on a Dask cluster instead).
"""
from __future__ import annotations

import sys

from hydroline.rigs import load_rig
from hydroline.studies import sweep


RELATIVE_STD = 0.06     # standard deviation of the bulk moduli, relative to the rig's, [-]


def main(n_samples=64, out="bulk-modulus-mc"):
    rig = load_rig()
    spec = {}
    for side in ("supply", "return"):
        mean = rig[f"{side}.section2.bulk_modulus"] / 1e6     # the rig's value [MPa]
        dist = f"normal({mean:.6g} MPa, {RELATIVE_STD * mean:.4g} MPa)"
        spec[f"{side}.section1.bulk_modulus+{side}.section2.bulk_modulus"] = dist
        print(f"{side} hoses (sections I and II): effective bulk modulus {dist}")
    result = sweep(spec, rig, samples=int(n_samples), seed=1, out=out, resume=True,
        progress=lambda done, total, failed: print(f"\r{done}/{total} ({failed} failed)", end=""))
    print()
    metrics = ["supply_frequency_hz", "supply_amplitude_mpa", "return_frequency_hz",
               "return_amplitude_mpa"]
    q = result.table[metrics].quantile([0.05, 0.5, 0.95])
    q.index = ["5 %", "median", "95 %"]
    print(q.to_string(float_format="%.4g"))
    print(f"{result.n_failed} failed; table: {result.files['csv']}")
    for note in result.notes:
        print("note:", note)


if __name__ == "__main__":
    main(*sys.argv[1:3])
