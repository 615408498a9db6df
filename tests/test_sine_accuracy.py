"""The closed-loop sine at the default tolerances against a tight reference (issue 26 item 2:
the 10-minute run keeps its defaults; benchmarks/bench_longrun.py, benchmarks/README.md).

The reference is a different integrator, CVODES through CasADi at rtol 1e-9 (it agrees with
the compiled core at rtol 1e-10 to ~3e-7 % on these metrics). Three command cycles (1.5 s):
the response is periodic after the first (the start from rest), so a long run's per-cycle
errors are those of these cycles (20 s measured: the same errors to a few 1e-3 %), and its
largest ripple is the first cycle's.
"""
from __future__ import annotations

import numpy as np
import pytest

import hydroline
from hydroline.scenarios import summarize

TRACES = ("supply_port_pressure", "return_port_pressure", "piston_position", "piston_velocity")
T_END = 1.5   # three periods of the rig's 2 Hz command, [s]


@pytest.fixture(scope="module")
def runs():
    ref = hydroline.simulate(None, "closed-loop-sine", T_END, solver="cvodes", rtol=1e-9,
                             atol_scale=1e-10)
    return ref, hydroline.simulate(None, "closed-loop-sine", T_END)


def test_default_tolerances_keep_the_sine_metrics_within_0_05_percent(runs):
    ref, res = runs
    want, got = summarize(ref), summarize(res)
    errors = {k: abs(got[k] / want[k] - 1) * 100
              for k in ("tracking_error_rms_mm", "tracking_error_max_mm")}
    for side in ("supply", "return"):
        assert len(got[side]["ripple_pp_mpa_per_cycle"]) == 3
        errors[f"{side}.ripple_pp_mpa"] = abs(got[side]["ripple_pp_mpa"]
                                              / want[side]["ripple_pp_mpa"] - 1) * 100
    worst = max(errors, key=errors.get)
    assert errors[worst] <= 0.05, (worst, errors[worst])


def test_default_tolerances_keep_the_sine_traces_within_0_5_percent(runs):
    ref, res = runs
    assert np.array_equal(res.t, ref.t)
    for k in TRACES:
        assert np.max(np.abs(res[k] - ref[k])) <= 0.005 * np.ptp(ref[k]), k


def test_each_cycles_ripple_within_0_2_percent(runs):
    """The ripple of each later cycle (0.378 / 0.155 MPa, a peak of the lines' ringing after a
    valve reversal) is stepped at NDF order 2 past the order-3 stability limit of the lines'
    fast modes (158 us): its phase error moves the peak by up to 0.08 % at rtol 1e-6 (0.24 %
    at 3e-6, 0.64 % at 1e-5, measured over 20 s); the bound is that miss with a 2x margin."""
    ref, res = runs
    want, got = summarize(ref), summarize(res)
    for side in ("supply", "return"):
        np.testing.assert_allclose(got[side]["ripple_pp_mpa_per_cycle"],
                                   want[side]["ripple_pp_mpa_per_cycle"], rtol=2e-3)
