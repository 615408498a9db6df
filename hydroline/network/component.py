"""The component interface: ports (signals with causality), states and equations.

A component declares

* ``inputs`` / ``outputs``: local port names -> :class:`Port` (quantity and unit);
* ``states``: :class:`State` entries (local name, unit, typical magnitude);
* ``outputs_of(t, x, u, p)``: the outputs from states x, inputs u and runtime parameters p
  (dicts keyed by local names);
* ``derivatives(t, x, u, p)``: the time derivatives of the states.

Both receive numbers (reference path) or CasADi symbols (compiled path) and must only use
:mod:`hydroline.network.ops` and arithmetic. A component whose outputs do not depend on its
inputs sets ``feedthrough = False``; the network uses it to order the evaluation and to find
algebraic loops.
"""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Port", "State", "Component", "QUANTITY_UNITS"]

#: Physical quantity kinds of signals and their SI units.
QUANTITY_UNITS = {
    "pressure": "Pa",
    "flow": "m^3/s",
    "current": "A",
    "position": "m",
    "velocity": "m/s",
    "force": "N",
    "volume": "m^3",
    "dimensionless": "-",
}


@dataclass(frozen=True)
class Port:
    """One input or output signal of a component.

    Parameters
    ----------
    quantity : str      Kind of signal (a key of QUANTITY_UNITS); connecting ports of
                        different kinds is a causality/quantity mismatch
    description : str   What the signal is, with its sign convention
    """

    quantity: str
    description: str = ""

    @property
    def unit(self) -> str:
        return QUANTITY_UNITS[self.quantity]


@dataclass(frozen=True)
class State:
    """One state of a component: local name, SI unit, typical magnitude (for tolerances)."""

    name: str
    unit: str
    scale: float = 1.0
    description: str = ""


@dataclass
class Component:
    """Base class. Subclasses set ``inputs``, ``outputs``, ``states`` and the equations.

    Parameters
    ----------
    name : str          Unique name in the network (dots allowed: ``supply.section2``)
    connections : dict  Local port name -> network signal name. Unlisted ports connect to
                        a signal of the same name prefixed by nothing (the port name itself)
    """

    name: str
    connections: dict = field(default_factory=dict)

    inputs = {}
    outputs = {}
    feedthrough = True

    # ---- to be provided by subclasses --------------------------------------------------
    @property
    def states(self) -> list[State]:
        return []

    def outputs_of(self, t, x, u, p):
        raise NotImplementedError

    def derivatives(self, t, x, u, p):
        return {}

    # ---- optional hooks ------------------------------------------------------------------
    def runtime_parameters(self) -> dict:
        """Parameters that may change without rebuilding the compiled model, name -> value."""
        return {}

    def initial_guess(self) -> dict:
        """Guess of every state for the steady-state solver, local name -> value [SI]."""
        return {s.name: 0.0 for s in self.states}

    def settle(self, x: dict, u: dict, p: dict):
        """Called with the solved steady state; may return ``(new_x, new_p)`` dicts to adopt
        (e.g. an accumulator takes its pre-charge reference from the steady pressure)."""
        return None

    def breakpoints(self, t_end: float) -> list[float]:
        """Times in (0, t_end) where the component's inputs to the ODE jump, [s]."""
        return []

    def signal(self, port: str) -> str:
        """Network signal connected to a local port."""
        return self.connections.get(port, port)
