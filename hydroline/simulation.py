"""Compatibility names: steady state, integration and the result now live in
:mod:`hydroline.engine` (``steady_state``, ``integrate``, ``backends``, ``result``).
``from hydroline.simulation import integrate, solve_steady_state`` keeps working; new code
imports from :mod:`hydroline.engine`."""
from .engine.backends import SOLVERS
from .engine.integrate import integrate
from .engine.result import SimulationResult, column_units, write_csv_rows
from .engine.steady_state import SteadyState, SteadyStateError, solve_steady_state

__all__ = ["SteadyState", "solve_steady_state", "integrate", "SimulationResult",
           "SteadyStateError", "SOLVERS", "column_units", "write_csv_rows"]
