"""A hose section: a linear line model (modal or lumped) as a network component (docs/model.md 2)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lines.modal import StateSpaceLine
from ..engine import ops
from ..engine.component import Component, HydraulicEnd, Port, State

__all__ = ["HoseSection", "COEFFICIENT_MATRICES"]

_QUANTITY = {"pressure": "pressure", "flow": "flow"}

#: Hose sections made while this is True read their line's matrix entries (the nonzeros of A,
#: B, C, D, M8-M14) from the runtime parameters ``p`` instead of the graph's constants, so
#: that variants that differ only in hose numbers (length, bore, bulk modulus: the layout
#: study, a fit, a rig file that changes one hose's bulk modulus) share one compiled model and
#: swap ``p``. On by default: the exact-pole (residue) line's graph, folded as constants, took
#: another C build (~5 s) for every new number (CasADi folds equal and zero constants, so its
#: program changed with the numbers), against ~0.1 s with the entries in ``p``; a run costs
#: the same either way (default rig: 20 ms in-process).
COEFFICIENTS_AS_PARAMETERS = True
#: The line matrices whose nonzero entries become runtime parameters, in their order.
COEFFICIENT_MATRICES = ("A", "B", "C", "D")
_MATRICES = COEFFICIENT_MATRICES


class coefficients_as_parameters:
    """Context manager: hose sections made inside it carry their line's matrix entries in
    the runtime parameters (see :data:`COEFFICIENTS_AS_PARAMETERS`)."""

    def __enter__(self):
        global COEFFICIENTS_AS_PARAMETERS
        self._saved, COEFFICIENTS_AS_PARAMETERS = COEFFICIENTS_AS_PARAMETERS, True
        return self

    def __exit__(self, *exc):
        global COEFFICIENTS_AS_PARAMETERS
        COEFFICIENTS_AS_PARAMETERS = self._saved
        return False


@dataclass(kw_only=True)
class HoseSection(Component):
    """A line in one causal form, ``x' = A x + B u``, ``y = C x + D u`` (M8-M14).

    Parameters
    ----------
    model : StateSpaceLine
        The line model (e.g. ``ModalLine(line, 6, "PQ")``)
    nominal_pressure : float
        Pressure level used for the steady-state solver's guess, [Pa]

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Ports: the form's inputs and outputs, named as in
    :data:`hydroline.lines.FORM_PORTS` (e.g. PQ: inputs ``upstream_pressure``,
    ``downstream_flow``; outputs ``downstream_pressure``, ``upstream_flow``).
    States: the model's, e.g. ``mode3.flow``.
    """

    model: StateSpaceLine = None
    nominal_pressure: float = 0.0

    conducts = True

    def __post_init__(self):
        m = self.model
        self.inputs = {n: Port(n.split("_")[1], f"{n.replace('_', ' ')} of the line")
                       for n in m.input_names}
        self.outputs = {n: Port(n.split("_")[1], f"{n.replace('_', ' ')} of the line")
                        for n in m.output_names}
        self.feedthrough = bool(np.any(m.D != 0))
        #: (matrix, row, column) of each nonzero entry, when they are runtime parameters
        self.coefficient_pattern = None
        if COEFFICIENTS_AS_PARAMETERS:
            pattern = []
            for name in _MATRICES:
                rows, cols = np.nonzero(np.asarray(getattr(m, name), dtype=float))
                pattern += zip([name] * len(rows), rows.tolist(), cols.tolist())
            self.coefficient_pattern = tuple(pattern)
        scale_p, scale_q = max(self.nominal_pressure, 1e5), 1e-4
        self._states = []
        for name in m.state_names:
            unit, scale = {"pressure": ("Pa", scale_p), "flow": ("m^3/s", scale_q),
                           "volume": ("m^3", 1e-6), "pressure_integral": ("Pa s", scale_p * 1e-3)
                           }.get(name.split(".")[1].rstrip("0123456789"), ("m^3/s", scale_q))
            self._states.append(State(name, unit, scale))

    @property
    def states(self):
        """The states of the line model (its modes, or its segments), [SI]."""
        return self._states

    def hydraulic_ends(self):
        """Its two ends, each holding oil (the line's compliance).

        Returns
        -------
        dict
            End name -> :class:`~hydroline.engine.component.HydraulicEnd`.
        """
        return {end: HydraulicEnd(f"{end}_pressure", (f"{end}_flow",), compliant=True)
                for end in ("upstream", "downstream")}

    def _vectors(self, x, u):
        xv = ops.vertcat([x[s.name] for s in self._states])
        uv = ops.vertcat([u[n] for n in self.model.input_names]) if u else None
        return xv, uv

    def runtime_parameters(self):
        """The line's matrix entries where they are runtime parameters, else none.

        Returns
        -------
        dict
            ``"<M><row>_<col>"`` -> entry, [SI units of the state-space model], when the
            section was made under :class:`coefficients_as_parameters`; else empty.
        """
        if self.coefficient_pattern is None:
            return {}
        return {f"{name}{i}_{j}": float(getattr(self.model, name)[i, j])
                for name, i, j in self.coefficient_pattern}

    def _product(self, name, v, p, rows):
        """Matrix ``name`` (from p where its entries are parameters) times vector v."""
        if self.coefficient_pattern is None:
            return ops.matvec(getattr(self.model, name), v)
        terms = [[] for _ in range(rows)]
        for m, i, j in self.coefficient_pattern:
            if m == name:
                terms[i].append(p[f"{m}{i}_{j}"] * v[j])
        return ops.vertcat([ops.pairwise_sum(row) for row in terms])

    def outputs_of(self, t, x, u, p):
        xv, uv = self._vectors(x, u)
        rows = len(self.model.output_names)
        y = self._product("C", xv, p, rows)
        if self.feedthrough:
            y = y + self._product("D", uv, p, rows)
        return {n: y[i] for i, n in enumerate(self.model.output_names)}

    def derivatives(self, t, x, u, p):
        xv, uv = self._vectors(x, u)
        rows = len(self._states)
        dx = self._product("A", xv, p, rows) + self._product("B", uv, p, rows)
        return {s.name: dx[i] for i, s in enumerate(self._states)}

    def initial_guess(self):
        ins = self.model.input_names
        u0 = [self.nominal_pressure if n.endswith("pressure") else 0.0 for n in ins]
        if self.model.form == "QQ":
            x0 = self.model.initial_state(u0, mean_pressure=self.nominal_pressure)
        else:
            x0 = self.model.initial_state(u0)
        return {s.name: float(v) for s, v in zip(self._states, x0)}
