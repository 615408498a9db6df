"""A hose section: a linear line model (modal or lumped) as a network component (docs/model.md 2)."""
from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from ..lines.modal import StateSpaceLine
from ..engine import ops
from ..engine.component import Component, HydraulicEnd, Port, State
from ..fluid import Fluid, oil_numbers

__all__ = ["HoseSection", "COEFFICIENT_MATRICES"]

_QUANTITY = {"pressure": "pressure", "flow": "flow"}
#: The internal signal of a section with an end cavity (M45): ``|k| w``, what the cavity holds
#: the end's pressure above the line's own, [Pa]
CAVITY_LIFT = "cavity_lift"
#: Runtime parameters ``<GAIN><row>`` of a section with an end cavity: ``[C b]_row``, the rate
#: of each output per unit end flow (M45)
GAIN = "cavity_gain"

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
    fluid : Fluid or None
        The rig's oil; with ``cavity_pressure`` set, each end whose pressure the line puts out
        holds a gas/vapour cavity (M45); None or no cavity model: the plain line

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

    End cavity (M45): at the end whose pressure the line puts out (PQ: downstream, QP:
    upstream) the line and the port meet in a node that may hold a gas/vapour cavity of
    volume ``w``, so that the line's end flow is ``q_line = q_port - s dw/dt`` (``s = +1``
    downstream, where the port flow leaves the line, ``-1`` upstream). The states are then
    the line's states shifted by the cavity, ``z = x + s w b`` (``b`` the column of B of the
    end flow, ``k = [C b]`` the end pressure's rate per unit end flow, ``s k < 0``), which obey
    the cavity-free line driven by the port's flow, ``dz/dt = A x + B u``. Their end pressure
    ``p~ = [C z]`` is what the end would read without the cavity, and::

        w = softplus(p_cav - p~, delta) / |k|,    p_end = [C x] = p~ + |k| w >= p_cav

    (``softplus`` the smooth positive part of width ``delta = fluid.cavity_pressure_drop``,
    :func:`hydroline.engine.ops.softplus`): the ideal cavity of the discrete vapour cavity
    model at the line's end, smoothed. The cavity closes when the oil it misses has come
    back; the collapse peak is the line's own water hammer. Without a cavity model the
    states are the line's own. ``|k| w`` (the end's pressure above ``p~``) is the section's
    internal signal ``cavity_lift``
    (:attr:`~hydroline.engine.component.Component.internal_signals`), computed once per
    evaluation: every state reads it, so the compiled core's bordered Jacobian takes it as
    one row and column (the rank-one term ``-s (A b) (dw/dp~) c^T`` of ``d(dz/dt)/dz``) and
    the section's block stays as sparse as the line's A.
    """

    model: StateSpaceLine = None
    nominal_pressure: float = 0.0
    fluid: Fluid | None = None

    conducts = True
    #: The model reference's equation of its end cavities (named in the run's cavity warnings).
    cavity_equation = "M45"

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
        #: (end, output row, input column, s) of each end that holds a cavity (M45)
        self.cavity_ends = self._cavity_ends()

    def _cavity_ends(self):
        if self.fluid is None or self.fluid.cavity_pressure is None:
            return ()
        m = self.model
        gain = np.asarray(m.C, dtype=float) @ np.asarray(m.B, dtype=float)
        ends = []
        for end, sign in (("upstream", -1.0), ("downstream", 1.0)):
            out, inp = f"{end}_pressure", f"{end}_flow"
            if out not in m.output_names or inp not in m.input_names:
                continue
            i, j = m.output_names.index(out), m.input_names.index(inp)
            if np.any(np.asarray(m.D, dtype=float)[i] != 0) or not sign * gain[i, j] < 0:
                raise ValueError(f"{self.name}: an end cavity (fluid.cavity_pressure, M45) needs "
                                 f"a line whose {out} has no feedthrough and falls as oil "
                                 f"leaves that end; the {m.form} line's does not")
            ends.append((end, i, j, sign))
        if len(ends) > 1:
            raise ValueError(f"{self.name}: an end cavity (fluid.cavity_pressure, M45) is "
                             f"modelled at one end of a line; form {m.form} puts out both "
                             f"ends' pressures: use PQ or QP")
        return tuple(ends)

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

    @property
    def internal_signals(self):
        """``("cavity_lift",)`` with an end cavity (M45: ``|k| w``, what the cavity holds the
        end's pressure above the line's own ``p~``), else none."""
        return (CAVITY_LIFT,) if self.cavity_ends else ()

    def internal_values(self, t, x, p):
        """The end cavity's lift ``|k| w = softplus(p_cav - p~, delta)`` with an end cavity
        (M45), [Pa].

        Parameters
        ----------
        t : float
            Time, [s]
        x : dict
            States (the shifted ``z``), local name -> value [SI]
        p : dict
            Runtime parameters, name -> value [SI]

        Returns
        -------
        dict
            ``{"cavity_lift": |k| w}``, [Pa]; empty without an end cavity.
        """
        if not self.cavity_ends:
            return {}
        xv, _ = self._vectors(x, {})
        return {CAVITY_LIFT: self._lift(xv, {}, p)}

    def _vectors(self, x, u):
        xv = ops.vertcat([x[s.name] for s in self._states])
        names = self.model.input_names
        uv = ops.vertcat([u[n] for n in names]) if names and names[0] in u else None
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
        out = {f"{name}{i}_{j}": float(getattr(self.model, name)[i, j])
               for name, i, j in self.coefficient_pattern}
        if self.cavity_ends:
            out.update((f"{GAIN}{r}", g) for r, g in enumerate(self._gains(None)))
        return out

    def parameters_for(self, model):
        """The runtime parameters this section takes for a line model of the same pattern
        (another length, bore or bulk modulus: a study's variant, without making a section
        for it), in :meth:`runtime_parameters`' order: the matrices' nonzero entries, then,
        with an end cavity (M45), the end flow's gains ``C b`` (the rate of each output per
        unit end flow, of the matrices alone: a product per run, not per evaluation).

        Parameters
        ----------
        model : StateSpaceLine
            The line model (e.g. a variant's ``ModalLine`` of the same modes and form)

        Returns
        -------
        list[float] or None
            Values, [SI units of the state-space model]; None where the section does not
            carry its matrices in the parameters, or the model's pattern differs
        """
        if self.coefficient_pattern is None:
            return None
        values = []
        for name in _MATRICES:
            a = np.asarray(getattr(model, name), dtype=float)
            rows, cols = np.nonzero(a)
            mine = [(i, j) for m, i, j in self.coefficient_pattern if m == name]
            if mine != list(zip(rows.tolist(), cols.tolist())):
                return None
            values += a[rows, cols].tolist()
        if self.cavity_ends:
            values += self._gains(None, model)
        return values

    def compiled_numbers(self) -> dict:
        """As :meth:`Component.compiled_numbers`, with the cavity model's numbers
        (:func:`~hydroline.fluid.oil_numbers`) where an end holds a cavity (M45).

        Returns
        -------
        dict
            Name -> float or tuple of floats, [SI].
        """
        numbers = super().compiled_numbers()
        if self.cavity_ends:
            numbers.update(oil_numbers(self.fluid, air=False))
        return numbers

    def structure_attributes(self, attributes: dict) -> dict:
        """As :meth:`Component.structure_attributes`; where the line's matrix entries are
        runtime parameters, the line model stands as its kind, form, port and state names
        (its matrices' pattern is :attr:`coefficient_pattern`): their values are not
        structure. The oil stands as whether it has a cavity model (M45): the cavity's
        numbers are runtime numbers (:meth:`compiled_numbers`), and its density, viscosity
        and bulk modulus reach the hose through the line's matrices.

        Parameters
        ----------
        attributes : dict
            The hose's attributes, name -> value.

        Returns
        -------
        dict
            Name -> value or mark.
        """
        out = super().structure_attributes(attributes)
        m = attributes.get("model")
        pattern = attributes.get("coefficient_pattern")
        if pattern is not None and m is not None:
            out["model"] = (type(m).__qualname__, m.form, tuple(m.input_names),
                            tuple(m.output_names), tuple(m.state_names))
            # (the pattern by its digest, the states by their names (above: their units
            # follow from them, their scales are numbers): hundreds of entries, described
            # once per run)
            out["coefficient_pattern"] = hashlib.sha256(repr(pattern).encode()).hexdigest()
            out["_states"] = len(attributes.get("_states", ()))
        fluid = out.get("fluid")
        if fluid is not None:
            out["fluid"] = ("end cavity", fluid.cavity_pressure is not None)
        return out

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
        if self.cavity_ends:                   # y = C x = C z + (lift / k) C b (M45)
            (_, i, j, _), = self.cavity_ends
            lift = self._lift(xv, u, p)
            gains = self._gains(p)
            per_k = lift / gains[i]
            y = ops.vertcat([y[r] + lift if r == i else y[r] + gains[r] * per_k
                             for r in range(rows)])
        if self.feedthrough:
            y = y + self._product("D", uv, p, rows)
        return {n: y[i] for i, n in enumerate(self.model.output_names)}

    def derivatives(self, t, x, u, p):
        xv, uv = self._vectors(x, u)
        if self.cavity_ends:                   # dz/dt = A x + B u (M45)
            xv = self._line_states(xv, u, p)
        rows = len(self._states)
        dx = self._product("A", xv, p, rows) + self._product("B", uv, p, rows)
        return {s.name: dx[i] for i, s in enumerate(self._states)}

    def _free_pressure(self, z, p):
        """p~ = [C z], the cavity end's pressure without the cavity (M45), [Pa]."""
        (_, i, _, _), = self.cavity_ends
        return self._product("C", z, p, len(self.model.output_names))[i]

    def _lift(self, z, u, p):
        """``|k| w = softplus(p_cav - p~, delta)``: what the end cavity holds the end's
        pressure above the line's own (M45), [Pa]; given in u (the network's, computed once
        per evaluation, or the bordered Jacobian's cut), else from z."""
        if CAVITY_LIFT in u:
            return u[CAVITY_LIFT]
        return ops.softplus(self.fluid.cavity_pressure - self._free_pressure(z, p),
                            self.fluid.cavity_pressure_drop)

    def _column(self, name, j, p, rows):
        """Column j of matrix ``name`` (from p where its entries are parameters)."""
        if self.coefficient_pattern is None:
            return ops.vertcat([float(v) for v in np.asarray(getattr(self.model, name))[:, j]])
        column = [0.0] * rows
        for m, r, c in self.coefficient_pattern:
            if m == name and c == j:
                column[r] = p[f"{m}{r}_{c}"]
        return ops.vertcat(column)

    def _line_states(self, z, u, p):
        """The line's states ``x = z - s w b = z + (|k| w / k) b`` from the shifted states z
        (M45; ``s k < 0``)."""
        (_, i, j, _), = self.cavity_ends
        b = self._column("B", j, p, len(self._states))
        return z + b * (self._lift(z, u, p) / self._gains(p)[i])

    def _gains(self, p, model=None):
        """``C b``: each output's rate per unit end flow (M45; ``k`` its end pressure's), from
        the runtime parameters p where the matrices are there, else from ``model`` (this
        section's by default)."""
        if p is not None and self.coefficient_pattern is not None:
            return [p[f"{GAIN}{r}"] for r in range(len(self.model.output_names))]
        m = self.model if model is None else model
        (_, _, j, _), = self.cavity_ends
        return (np.asarray(m.C, dtype=float) @ np.asarray(m.B, dtype=float)[:, j]).tolist()

    def cavity_volumes(self, x, outputs=None):
        """Gas/vapour cavity volume at the end that holds one (M45), [m^3].

        Parameters
        ----------
        x : dict
            States (arrays of a run allowed), local name -> value [SI]
        outputs : dict, optional
            Its outputs there, local port name -> value [SI]: where the end's pressure
            stays ``38 delta`` above ``p_cav``, so does ``p~`` (``p_end - p_cav =
            softplus(p~ - p_cav, delta)``), and the states are not read

        Returns
        -------
        dict
            ``{"upstream end": w}`` or ``{"downstream end": w}``, [m^3]; empty without an
            end cavity. Zero where ``p~`` lies more than ``37 delta`` above ``p_cav``: the
            lift ``|k| w < 1e-16 delta`` is then below the rounding of ``p~`` (no pressure of
            the model moves)
        """
        if not self.cavity_ends:
            return {}
        (end, i, j, s), = self.cavity_ends
        C, B = np.asarray(self.model.C, dtype=float), np.asarray(self.model.B, dtype=float)
        delta = self.fluid.cavity_pressure_drop
        p_end = (outputs or {}).get(f"{end}_pressure")
        if p_end is not None and np.min(p_end) > self.fluid.cavity_pressure + 38.0 * delta:
            return {f"{end} end": np.zeros_like(np.asarray(p_end, dtype=float))}
        free = sum(C[i, r] * np.asarray(x[self._states[r].name], dtype=float)
                   for r in np.flatnonzero(C[i]))
        y = self.fluid.cavity_pressure - free
        lifted = y > -37.0 * delta
        w = np.where(lifted, ops.softplus(y, delta), 0.0) if np.any(lifted) else np.zeros_like(y)
        return {f"{end} end": w / (-s * float(C[i] @ B[:, j]))}

    def initial_guess(self):
        ins = self.model.input_names
        u0 = [self.nominal_pressure if n.endswith("pressure") else 0.0 for n in ins]
        if self.model.form == "QQ":
            x0 = self.model.initial_state(u0, mean_pressure=self.nominal_pressure)
        else:
            x0 = self.model.initial_state(u0)
        return {s.name: float(v) for s, v in zip(self._states, x0)}
