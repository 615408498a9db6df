"""The engine: what turns components into a run, and what a newcomer never has to edit.

* :mod:`~hydroline.engine.component` — the component contract: ports (signals with
  causality), states, equations, declared parameters (unit, bounds, description, default),
  and the optional hooks (steady-state guess and settling, breakpoints, sampling);
* :mod:`~hydroline.engine.ops` — the operations component equations are written with, so they
  evaluate on numbers and compile to C;
* :mod:`~hydroline.engine.network` — components wired by named signals into one explicit ODE
  ``dx/dt = f(t, x, p)`` (connection checks, evaluation order, algebraic loops, the connection
  table, unused-signal warnings);
* :mod:`~hydroline.engine.fingerprint` — what the network's compiled graph is a function of,
  hashed before the graph is built (the key of its compiled model's record);
* :mod:`~hydroline.engine.steady_state` — the rest state before the disturbance;
* :mod:`~hydroline.engine.backends` — one class per solver (compiled C core, CVODES, SciPy);
* :mod:`~hydroline.engine.integrate` — the run over breakpoints and sampling instants;
* :mod:`~hydroline.engine.result` — :class:`SimulationResult` and the output sink (memory, CSV
  streaming in constant memory, preview).

Data flows one way: components -> network -> compiled function -> backend -> result. Nothing
here imports the rigs, circuits, scenarios, studies or the CLI.
"""
from .backends import SOLVERS
from .component import QUANTITY_UNITS, Component, HydraulicEnd, Parameter, Port, State, parameter
from .integrate import integrate
from .network import CompiledModel, Network, NetworkError
from .result import SimulationResult, column_units, write_csv_rows
from .steady_state import SteadyState, SteadyStateError, solve_steady_state

__all__ = ["Component", "HydraulicEnd", "Port", "State", "Parameter", "parameter", "QUANTITY_UNITS",
           "Network", "NetworkError", "CompiledModel", "SteadyState", "SteadyStateError",
           "solve_steady_state", "integrate", "SimulationResult", "column_units",
           "write_csv_rows", "SOLVERS"]
