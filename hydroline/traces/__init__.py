"""Pure functions of sampled traces: oscillation and settling metrics, a long trace's envelope
over time, and the few filters and peak finders they need (NumPy only).

Nothing here knows a rig, a network or a scenario: each function takes times ``t`` [s] and a
signal ``p`` (usually a pressure, [Pa]) and returns numbers. Scenarios, studies and the CLI call
these; this package imports nothing else of hydroline, so it sits at the bottom of the package
and can be used on measured traces as well as simulated ones.
"""
from .binned import BinnedEnvelope
from .metrics import (SettlingBand, first_excursion, oscillation_amplitude, oscillation_baseline,
                      oscillation_frequency, overshoot, peak_to_peak, port_settling,
                      pressure_metrics, settling_time)

__all__ = ["BinnedEnvelope", "first_excursion", "oscillation_amplitude", "oscillation_baseline",
           "oscillation_frequency", "overshoot", "peak_to_peak", "port_settling",
           "pressure_metrics", "settling_time", "SettlingBand"]
