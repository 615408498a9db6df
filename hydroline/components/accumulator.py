"""Gas-charged piston accumulator with its connection line (docs/model.md 3, M16-M18)."""
from __future__ import annotations

from dataclasses import dataclass

from ..lines.modal import StateSpaceLine
from ..engine import ops
from ..engine.component import Component, HydraulicEnd, Port, State, parameter

__all__ = ["PistonAccumulator"]


@dataclass(kw_only=True)
class PistonAccumulator(Component):
    """Massless, frictionless piston accumulator, polytropic gas (M16-M17).

    Gas: ``p_g V_g^m = K`` with ``K = p_ref (V_0 p_0/p_ref)^m``: a slow isothermal charge from
    the pre-charge ``p_0`` at capacity ``V_0`` to the steady node pressure ``p_ref``, then
    polytropic (M16). State ``gas_volume`` V_g with ``dV_g/dt = -q_a`` (so (M17) holds).
    Piston travel limits: V_g <= V_0 (oil side empty: the piston rests on its stop, the gas
    stays at p(V_0) and the oil side stiffens like a small oil volume, ``stop_stiffness``
    [Pa/m^3]); V_g is kept above 0.1 % of V_0.

    Connection line from the node to the oil side: "version II" (default, M18)
    ``I_a dq_a/dt = p_node - p_oil - R_a q_a`` (state ``flow``), or a full line model
    (``connection_model``, PP form: inputs node and oil pressures; states ``line.*``).

    Parameters
    ----------
    capacity : float
        V_0, gas volume at pre-charge, [m^3]
    precharge_pressure : float
        p_0, absolute, [Pa]
    polytropic_exponent : float
        m, 1 (isothermal) ... 1.4 (adiabatic N2), [-]
    resistance : float
        R_a of the connection (version II), [Pa s/m^3]
    inertance : float
        I_a of the connection (version II), [kg/m^4]
    connection_model : StateSpaceLine
        PP line model replacing (R_a, I_a); None for version II
    nominal_pressure : float
        Guess of the node pressure for the steady-state solver, [Pa]
    stop_stiffness : float
        Stiffness of the oil side once it is empty (piston on its
        stop, V_g > V_0), None: that of a 1 % oil film, [Pa/m^3]

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Ports: input ``pressure`` (node) [Pa]; output ``flow`` into the accumulator branch [m^3/s];
    signal ``gas_pressure`` is not a port (see :meth:`gas_pressure`).
    """

    capacity: float = parameter(1e-3, "m^3", "V_0, gas volume at pre-charge (M16)", positive=True,
                                plausible=(1e-05, 0.1))
    precharge_pressure: float = parameter(1e7, "Pa", "p_0, absolute (M16)", positive=True,
                                          plausible=(1e4, 1e8))
    polytropic_exponent: float = parameter(1.4, "-", "m: 1 isothermal ... 5/3 adiabatic (M16)",
                                           minimum=1.0, maximum=5.0 / 3.0, plausible=(1.0, 5 / 3))
    resistance: float = parameter(0.0, "Pa*s/m^3", "R_a of the connection, version II (M18)", minimum=0.0)
    inertance: float = parameter(1.0, "kg/m^4", "I_a of the connection, version II (M18)", positive=True)
    connection_model: StateSpaceLine | None = None
    nominal_pressure: float = parameter(2e7, "Pa", "guess of the node pressure", positive=True,
                                        plausible=(1e3, 1e8))
    stop_stiffness: float | None = parameter(None, "Pa/m^3", "oil side emptied (None: 1 % film)",
                                             positive=True, optional=True, plausible=(1e8, 1e18))

    inputs = {"pressure": Port("pressure", "pressure at the node the accumulator hangs on")}
    outputs = {"flow": Port("flow", "flow from the node into the accumulator branch")}
    feedthrough = False
    conducts = True

    def __post_init__(self):
        self.check_parameters()
        if self.stop_stiffness is None:
            # oil side emptied: stiffness of an oil film of 1 % of V0 (beta = 1.5 GPa)
            self.stop_stiffness = 1.5e9 / (0.01 * self.capacity)
        if self.connection_model is not None and self.connection_model.form != "PP":
            raise ValueError(f"{self.name}: connection_model must be a PP-form line")

    @property
    def states(self):
        """The states: ``gas_volume`` V_g [m^3], and the connection line's: ``flow`` [m^3/s]
        (version II, (M18)) or the modal line's states."""
        st = [State("gas_volume", "m^3", self.capacity, "gas volume V_g")]
        if self.connection_model is None:
            st.append(State("flow", "m^3/s", 1e-4, "flow in the connection line, into the accumulator"))
        else:
            st += [State(f"line.{n}", "-", 1e-4) for n in self.connection_model.state_names]
        return st

    def hydraulic_ends(self):
        """Its connection to the node, holding oil.

        Returns
        -------
        dict
            End name -> :class:`~hydroline.engine.component.HydraulicEnd`.
        """
        return {"node": HydraulicEnd("pressure", ("flow",), compliant=True)}

    def runtime_parameters(self):
        return {"reference_pressure": self.nominal_pressure}

    def gas_pressure(self, gas_volume, reference_pressure):
        """Gas pressure from (M16), with the piston's stops, [Pa] (oil-side pressure).

        Parameters
        ----------
        gas_volume : float
            Gas volume (number or CasADi symbol), [m^3]
        reference_pressure : float
            Pressure at the end of the isothermal charge (section 3),
            [Pa]

        Returns
        -------
        float
            Gas pressure minus the stop's push beyond the capacity, [Pa]
        """
        m, V0, p0 = self.polytropic_exponent, self.capacity, self.precharge_pressure
        K = reference_pressure * (V0 * p0 / reference_pressure) ** m
        V = ops.fmax(ops.fmin(gas_volume, V0), 1e-3 * V0)
        p_gas = K / V**m
        return p_gas - self.stop_stiffness * ops.fmax(gas_volume - V0, 0.0)

    def _line_vectors(self, x):
        return ops.vertcat([x[f"line.{n}"] for n in self.connection_model.state_names])

    def outputs_of(self, t, x, u, p):
        if self.connection_model is None:
            return {"flow": x["flow"]}
        y = ops.matvec(self.connection_model.C, self._line_vectors(x))
        return {"flow": y[0]}

    def derivatives(self, t, x, u, p):
        p_oil = self.gas_pressure(x["gas_volume"], p["reference_pressure"])
        if self.connection_model is None:
            q = x["flow"]
            return {"flow": (u["pressure"] - p_oil - self.resistance * q) / self.inertance,   # (M18)
                    "gas_volume": -q}                                                      # (M16)
        cm = self.connection_model
        xv = self._line_vectors(x)
        uv = ops.vertcat([u["pressure"], p_oil])
        dx = ops.matvec(cm.A, xv) + ops.matvec(cm.B, uv)
        q_in = ops.matvec(cm.C, xv)[1]
        out = {f"line.{n}": dx[i] for i, n in enumerate(cm.state_names)}
        out["gas_volume"] = -q_in
        return out

    def initial_guess(self):
        g = {"gas_volume": min(self.capacity,
                               self.capacity * self.precharge_pressure / self.nominal_pressure)}
        if self.connection_model is None:
            g["flow"] = 0.0
        else:
            x0 = self.connection_model.initial_state([self.nominal_pressure] * 2)
            g.update({f"line.{n}": float(v) for n, v in zip(self.connection_model.state_names, x0)})
        return g

    def settle(self, x, u, p):
        """Adopt the steady node pressure as the end of the isothermal charge (section 3).

        Parameters
        ----------
        x : dict
            States at the steady state, local name -> value [SI]
        u : dict
            Inputs there, local port name -> value [SI]
        p : dict
            Runtime parameters, name -> value [SI]

        Returns
        -------
        tuple or None
            ``(new_x, new_p)``: the gas volume [m^3] and the reference pressure [Pa]
            to adopt; None when the accumulator is empty (piston on its stop)
        """
        p_g = float(self.gas_pressure(x["gas_volume"], p["reference_pressure"]))
        if p_g <= self.precharge_pressure:       # empty: piston on its stop, nothing to adopt
            return None
        return ({"gas_volume": self.capacity * self.precharge_pressure / p_g},
                {"reference_pressure": p_g})
