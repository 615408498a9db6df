"""Model-level analysis: linearisation, frequency response, parameter and friction fits.

The trace metrics (oscillation amplitude, settling, ...) live in :mod:`hydroline.traces`; their
names are also reachable here for convenience.

The names below load on first use (PEP 562): the metrics need SciPy's peak finder, the
linearisation python-control, the fits SciPy's optimisers; a run that uses none pays for none.
"""
from __future__ import annotations

import importlib
import sys
import types

#: Public name -> submodule that defines it.
_LAZY = {
    "oscillation_frequency": "..traces.metrics", "oscillation_amplitude": "..traces.metrics",
    "oscillation_baseline": "..traces.metrics", "overshoot": "..traces.metrics",
    "first_excursion": "..traces.metrics", "peak_to_peak": "..traces.metrics",
    "pressure_metrics": "..traces.metrics", "port_settling": "..traces.metrics",
    "settling_time": "..traces.metrics", "SettlingBand": "..traces.metrics",
    "OperatingPoint": "linearize", "OperatingPointError": "linearize", "linearize": "linearize",
    "solve_operating_point": "linearize",
    "bandwidth": "frequency", "passband": "frequency", "bode_analysis": "frequency",
    "line_coupled_model": "frequency",
    "resonances": "frequency",
    "DataError": "fit", "fit_parameters": "fit", "read_measurements": "fit",
    "fit_stribeck": "friction_id", "identify_friction": "friction_id",
    "bode_data": "loop", "frequency_response_data": "loop", "stability_margins": "loop",
    "closed_loop_bandwidth": "loop", "closed_loop_position_response": "loop",
    "position_bandwidth": "loop",
}

__all__ = list(_LAZY)


def __getattr__(name):
    if name not in _LAZY:
        raise AttributeError(f"module 'hydroline.analysis' has no attribute {name!r}")
    module = _LAZY[name]
    if module.startswith(".."):   # the trace metrics live in hydroline.traces (pure functions)
        value = getattr(importlib.import_module(module[1:], "hydroline"), name)
    else:
        value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))


class _Package(types.ModuleType):
    """When a submodule of the same name as a public function is imported (``linearize``),
    the import system binds the submodule on the package; keep the function there instead
    (as the eager imports of this package used to)."""

    def __setattr__(self, name, value):
        if name in _LAZY and isinstance(value, types.ModuleType) and hasattr(value, name):
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
