"""Analysis of simulated and measured traces.

The names below load on first use (PEP 562): the metrics need SciPy's peak finder, the
linearisation python-control, the fits SciPy's optimisers; a run that uses none pays for none.
"""
from __future__ import annotations

import importlib

#: Public name -> submodule that defines it.
_LAZY = {
    "oscillation_frequency": "metrics", "oscillation_amplitude": "metrics",
    "settling_time": "metrics",
    "OperatingPoint": "linearize", "OperatingPointError": "linearize", "linearize": "linearize",
    "solve_operating_point": "linearize",
    "bandwidth": "frequency", "bode_analysis": "frequency", "line_coupled_model": "frequency",
    "resonances": "frequency",
    "DataError": "fit", "fit_parameters": "fit", "read_measurements": "fit",
    "fit_stribeck": "friction_id", "identify_friction": "friction_id",
}

__all__ = list(_LAZY)


def __getattr__(name):
    if name not in _LAZY:
        raise AttributeError(f"module 'hydroline.analysis' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
