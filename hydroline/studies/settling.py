"""The design studies' port metrics: the same definitions as ``hydroline simulate``.

Kept as a module for its names: :func:`port_settling` is
:func:`hydroline.traces.metrics.port_settling` (settling time in a band of +-2 % of the final
absolute pressure by default, :class:`SettlingBand`; measured within the metrics window or
estimated from the decay of the oscillation), and :func:`port_summary` is
:func:`hydroline.scenarios.summarize`, which takes every port metric -- frequency, two-sided
amplitude, first excursion, steady change, peak-to-peak, settling time -- with one definition
for simulate, layout and sweep.
"""
from __future__ import annotations

from ..traces.metrics import (MAX_FIT_SCATTER, MIN_CRESTS, SETTLING_BAND as BAND, SettlingBand,
                              port_settling)
from ..scenarios.summaries import summarize as port_summary

__all__ = ["port_settling", "port_summary", "MIN_CRESTS", "MAX_FIT_SCATTER", "BAND",
           "SettlingBand"]
