"""hydroline: electrohydraulic servo systems with the dynamics of their supply and return hoses.

The public names below load on first use (PEP 562), so ``import hydroline`` is quick and a
command pays only for what it uses (``hydroline.studies`` pulls in the sweep machinery,
``hydroline.analysis`` SciPy's signal and optimisation modules, ``simulate`` CasADi).
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: Public name -> (module, attribute or None for the module itself).
_LAZY = {
    "Fluid": ("hydroline.fluid", "Fluid"),
    "MINERAL_OIL": ("hydroline.fluid", "MINERAL_OIL"),
    "effective_bulk_modulus": ("hydroline.fluid", "effective_bulk_modulus"),
    "Rig": ("hydroline.rigs", "Rig"),
    "load_rig": ("hydroline.rigs", "load_rig"),
    "simulate": ("hydroline.scenarios.running", "simulate"),
    "summarize": ("hydroline.scenarios.summaries", "summarize"),
    "scenarios": ("hydroline.scenarios", None),  # experiments: hydroline.scenarios.OpenLoopStep
    "analysis": ("hydroline.analysis", None),   # hydroline.analysis.linearize(...)
    "studies": ("hydroline.studies", None),     # hydroline.studies.layout(...)
    # the linear model and what is read from it (python-control, SciPy: loaded on first use)
    "linearize": ("hydroline.analysis", "linearize"),
    "bode_analysis": ("hydroline.analysis", "bode_analysis"),
    "bode_data": ("hydroline.analysis", "bode_data"),
    "frequency_response_data": ("hydroline.analysis", "frequency_response_data"),
    "stability_margins": ("hydroline.analysis", "stability_margins"),
    "layout": ("hydroline.studies", "layout"),
    "sweep": ("hydroline.studies", "sweep"),
    "optimize": ("hydroline.studies", "optimize"),
}

__all__ = ["Fluid", "MINERAL_OIL", "effective_bulk_modulus", "Rig", "load_rig", "simulate",
           "summarize", "scenarios", "analysis", "studies", "linearize", "bode_analysis",
           "bode_data", "frequency_response_data", "stability_margins", "layout", "sweep",
           "optimize", "__version__"]


def __getattr__(name):
    try:
        module, attr = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'hydroline' has no attribute {name!r}") from None
    value = importlib.import_module(module)
    if attr is not None:
        value = getattr(value, attr)
    globals()[name] = value   # later look-ups skip this function
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
