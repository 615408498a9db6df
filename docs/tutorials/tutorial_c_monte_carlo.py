"""
(c) A Monte-Carlo sweep, locally and on a Dask cluster
======================================================

How uncertain are the port oscillations if the hoses' effective bulk modulus is only known to
about +-6 % (one standard deviation)? :func:`hydroline.studies.sweep` draws random variants of
any rig parameters (by their path in the rig file), runs them in parallel and appends every
finished row to a results file, so an interrupted sweep resumes where it stopped.

The same run goes to a Dask cluster by naming its scheduler: ``scheduler="tcp://host:8786"``
(hydroline installed on the workers), or ``scheduler="local"`` for a local Dask cluster as
below. Run time: about 15-30 s on two cores (16 samples in processes, then 4 on a Dask cluster).

Command-line equivalent::

    hydroline sweep --samples 16 --seed 1 \\
        --set 'supply.section1.bulk_modulus+supply.section2.bulk_modulus=normal(194.5 MPa, 11.67 MPa)' \\
        --out tutorial-out/mc --resume [--scheduler tcp://host:8786]
"""

# %%
# The design: one normal distribution per hose side
# -------------------------------------------------
# ``a+b`` sets both paths to the same draw (sections I and II of one side are the same hose
# type). The means are read from the rig.
from pathlib import Path

import hydroline
from hydroline.studies import sweep

OUT = Path("tutorial-out")
rig = hydroline.load_rig()
spec = {}
for side in ("supply", "return"):
    mean = rig[f"{side}.section2.bulk_modulus"] / 1e6          # [MPa]
    spec[f"{side}.section1.bulk_modulus+{side}.section2.bulk_modulus"] = \
        f"normal({mean:.6g} MPa, {0.06 * mean:.4g} MPa)"
for paths, dist in spec.items():
    print(f"{paths}: {dist}")

# %%
# Local worker processes, then a Dask cluster
# -------------------------------------------
# ``resume=True``: run the script again and finished variants are read back, not rerun.
# The worker processes re-import this script, so the parallel runs sit under a
# ``__main__`` guard (as in any script that starts processes); what is above it is cheap.
if __name__ == "__main__":
    result = sweep(spec, rig, samples=16, seed=1, workers=2, out=OUT / "mc", resume=True)
    metrics = ["supply_frequency_hz", "supply_amplitude_mpa", "return_frequency_hz",
               "return_amplitude_mpa"]
    q = result.table[metrics].quantile([0.05, 0.5, 0.95])
    q.index = ["5 %", "median", "95 %"]
    print(q.to_string(float_format="%.4g"))
    print(f"{result.n_failed} failed; table: {result.files['csv']}")


    # A first-order check: if the hose alone set the port frequency it would scale with the
    # wave speed c = sqrt(beta_e/rho) (M2), f ~ beta_e^(1/2). The fitted exponent is lower:
    # the manifold and its accumulator, which do not change, also take part in the mode.
    import numpy as np

    slope = np.polyfit(np.log(result.table["supply.section2.bulk_modulus"]),
                       np.log(result.table["supply_frequency_hz"]), 1)[0]
    print(f"supply frequency ~ (bulk modulus)^{slope:.2f}  (a lone quarter-wave hose: ^0.5)")


    # The same on a Dask cluster. Variant i is drawn from its own random stream, so the
    # first four Dask variants equal the first four local ones. A dask.distributed Client
    # can be passed as the scheduler; here an in-process cluster (threads) stands in for a
    # real one, which you reach with scheduler="tcp://host:8786" (hydroline installed on
    # its workers), or start locally with scheduler="local".
    import logging

    from dask.distributed import Client, LocalCluster

    # an in-process cluster closing may log a closed comm, with its traceback, at INFO level
    logging.getLogger("distributed").setLevel(logging.WARNING)

    with LocalCluster(n_workers=2, processes=False, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        dask_result = sweep(spec, rig, samples=4, seed=1, scheduler=client, out=OUT / "mc_dask")
    same = (dask_result.table["supply_frequency_hz"].to_numpy()
            - result.table["supply_frequency_hz"].to_numpy()[:4])
    print(f"Dask vs local, first 4 variants: max difference {abs(same).max():.3g} Hz")
