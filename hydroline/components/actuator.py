"""Double-ended actuator with chamber compressibility and end stops (docs/model.md 4, M22-M23)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..engine import ops
from ..engine.component import HydraulicEnd, Port, State, parameter
from ..fluid import Fluid, cavity_volume_fraction, chamber_pressure_scale, oil_compliance
from .volume import OilChamber

__all__ = ["Actuator"]


@dataclass(kw_only=True)
class Actuator(OilChamber):
    """Chamber pressures (M22) and piston motion (M23), vertical, upward positive.

    ``x_p`` is measured from mid-stroke; the stops are at +-stroke/2, modelled as a stiff
    spring-damper acting on the penetration (M27). Chamber volumes ``V_b + A_b x_p`` and
    ``V_t - A_t x_p`` are kept above ``min_volume_fraction`` of their centre values (M37).

    Parameters
    ----------
    bottom_area, top_area : float
        A_b, A_t, [m^2]
    bottom_volume, top_volume : float
        V_b, V_t at centre incl. valve/manifold passages, [m^3]
    bulk_modulus : float
        beta_c of the oil in the chambers, [Pa]
    moving_mass : float
        Piston, rod and rigidly attached load, [kg]
    stroke : float
        Full stroke, [m]
    internal_leakage : float
        C_i, [m^3/s/Pa]
    external_leakage : float
        C_e (each chamber), [m^3/s/Pa]
    gravity : float
        g along the axis (0 for a horizontal actuator), [m/s^2]
    stop_stiffness : float
        End-stop contact stiffness, [N/m]
    stop_damping : float
        End-stop contact damping (None: critical), [N s/m]
    min_volume_fraction : float
        Floor of the chamber volumes, a fraction of their
        centre values, [-]
    initial_position : float
        Guess of x_p for the steady-state solver, [m]
    nominal_pressure : float
        Guess of the chamber pressures, [Pa]
    fluid : Fluid or None
        The rig's oil: its entrained air (M40) and cavity model (M42) enter the
        chamber compliances (M41); None or air-free oil without a cavity model: (M22)

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Ports: inputs ``bottom_flow`` (q_b, into the bottom chamber), ``top_flow`` (q_t, out of
    the top chamber) [m^3/s], ``friction_force``, ``load_force`` [N] (both opposing upward
    motion when positive); outputs ``bottom_pressure``, ``top_pressure`` [Pa],
    ``position`` [m], ``velocity`` [m/s].
    """

    bottom_area: float = parameter(1e-3, "m^2", "A_b, bottom piston area (M22)", positive=True,
                                   plausible=(1e-06, 1.0))
    top_area: float = parameter(1e-3, "m^2", "A_t, top (rod-side) piston area (M22)", positive=True,
                                plausible=(1e-06, 1.0))
    bottom_volume: float = parameter(1e-4, "m^3", "V_b at mid-stroke incl. passages (M22)", positive=True,
                                     plausible=(1e-8, 10.0))
    top_volume: float = parameter(1e-4, "m^3", "V_t at mid-stroke incl. passages (M22)", positive=True,
                                  plausible=(1e-8, 10.0))
    bulk_modulus: float = parameter(1.4e9, "Pa", "beta_c of the oil in the chambers (M22)", positive=True,
                                    plausible=(1e8, 5e9))
    moving_mass: float = parameter(10.0, "kg", "piston, rod and attached load (M23)", positive=True,
                                   plausible=(0.01, 1e5))
    stroke: float = parameter(0.1, "m", "full stroke; stops at +-stroke/2 (M23)", positive=True,
                              plausible=(0.001, 10.0))
    internal_leakage: float = parameter(0.0, "m^3/s/Pa", "C_i across the piston (M22)", minimum=0.0,
                                        plausible=(0.0, 1e-10))
    external_leakage: float = parameter(0.0, "m^3/s/Pa", "C_e of each chamber (M22)", minimum=0.0,
                                        plausible=(0.0, 1e-10))
    gravity: float = parameter(9.81, "m/s^2", "g along the axis, 0 horizontal (M23)",
                               plausible=(-15.0, 15.0))
    stop_stiffness: float = parameter(1e9, "N/m", "end-stop contact stiffness", positive=True,
                                      plausible=(1e5, 1e13))
    stop_damping: float | None = parameter(None, "N*s/m", "end-stop contact damping (None: critical)",
                                           minimum=0.0, optional=True, plausible=(0.0, 1e9))
    min_volume_fraction: float = parameter(0.02, "-", "floor of the chamber volumes", positive=True,
                                           maximum=1.0, plausible=(1e-4, 0.5))
    initial_position: float = parameter(0.0, "m", "guess of x_p for the steady state",
                                        plausible=(-5.0, 5.0))
    nominal_pressure: float = parameter(1e7, "Pa", "chamber pressure scale and guess", positive=True,
                                        plausible=(1e3, 1e8))
    fluid: Fluid | None = None

    context = ("fluid",)
    inputs = {"bottom_flow": Port("flow", "q_b into the bottom chamber"),
              "top_flow": Port("flow", "q_t out of the top chamber"),
              "friction_force": Port("force", "friction on the piston, opposing +x when > 0"),
              "load_force": Port("force", "load/specimen force, opposing +x when > 0")}
    outputs = {"bottom_pressure": Port("pressure", "bottom chamber pressure p_b"),
               "top_pressure": Port("pressure", "top chamber pressure p_t"),
               "position": Port("position", "piston position from mid-stroke, up +"),
               "velocity": Port("velocity", "piston velocity, up +")}
    feedthrough = False

    def __post_init__(self):
        self.check_parameters()
        if self.stop_damping is None:   # critically damped contact
            self.stop_damping = 2.0 * np.sqrt(self.stop_stiffness * self.moving_mass)

    def hydraulic_ends(self):
        """The two chambers, each holding oil (M22).

        Returns
        -------
        dict
            End name -> :class:`~hydroline.engine.component.HydraulicEnd`.
        """
        return {end: HydraulicEnd(f"{end}_pressure", (f"{end}_flow",), compliant=True)
                for end in ("bottom", "top")}

    @property
    def states(self):
        """The states: ``bottom_pressure``, ``top_pressure`` [Pa] (their scale
        :func:`~hydroline.fluid.chamber_pressure_scale`), ``position`` [m], ``velocity``
        [m/s]."""
        ps = chamber_pressure_scale(self.nominal_pressure, self.fluid)
        return [State("bottom_pressure", "Pa", ps),
                State("top_pressure", "Pa", ps),
                State("position", "m", self.stroke / 2),
                State("velocity", "m/s", 1.0)]

    def hydraulic_natural_frequency(self, position: float = 0.0, bottom_pressure: float | None = None,
                                    top_pressure: float | None = None) -> float:
        """``w_h = sqrt((A_b^2 K_b/V_b + A_t^2 K_t/V_t)/m)`` at a position, [Hz].

        ``K`` is ``beta_c`` for air-free oil (M22); with the fluid's entrained air (and
        cavity) it is each chamber's effective modulus ``V/C(p, V)`` at its pressure (M40,
        M41): the chamber compliance the pressure equations use.

        Parameters
        ----------
        position : float
            Piston position from mid-stroke, positive up, [m]
        bottom_pressure : float or None
            Bottom chamber's mean absolute pressure, [Pa]; None: ``nominal_pressure``
        top_pressure : float or None
            Top chamber's mean absolute pressure, [Pa]; None: ``nominal_pressure``

        Returns
        -------
        float
            Hydraulic natural frequency ``w_h / (2 pi)``, [Hz]
        """
        Vb = self.bottom_volume + self.bottom_area * position
        Vt = self.top_volume - self.top_area * position
        if self.fluid is None or self.fluid.plain:
            w2 = self.bulk_modulus * (self.bottom_area**2 / Vb + self.top_area**2 / Vt) / self.moving_mass
        else:                                           # (M41): K = V/C at the mean pressure
            pb = self.nominal_pressure if bottom_pressure is None else bottom_pressure
            pt = self.nominal_pressure if top_pressure is None else top_pressure
            w2 = (self.bottom_area**2 / float(oil_compliance(Vb, pb, self.bulk_modulus, self.fluid))
                  + self.top_area**2 / float(oil_compliance(Vt, pt, self.bulk_modulus, self.fluid))
                  ) / self.moving_mass
        return float(np.sqrt(w2) / (2 * np.pi))

    def output_states(self):
        """Every output is the state of its name.

        Returns
        -------
        dict
            Output port -> state name.
        """
        return {k: k for k in self.outputs}

    def outputs_of(self, t, x, u, p):
        return {k: x[k] for k in ("bottom_pressure", "top_pressure", "position", "velocity")}

    def stop_force(self, x, v):
        """Force of the end stops on the piston (M27), positive up, [N].

        Parameters
        ----------
        x : float
            Piston position from mid-stroke, positive up (number or CasADi symbol), [m]
        v : float
            Piston velocity, positive up, [m/s]

        Returns
        -------
        float
            Stop force (stiffness beyond +-stroke/2, damping while in contact), [N]
        """
        half = self.stroke / 2
        over_top = ops.fmax(x - half, 0.0)
        over_bottom = ops.fmax(-half - x, 0.0)
        ramp = 1e-5  # [m] penetration over which the contact damping engages
        return (-self.stop_stiffness * over_top + self.stop_stiffness * over_bottom
                - self.stop_damping * v * ops.fmin((over_top + over_bottom) / ramp, 1.0))

    def derivatives(self, t, x, u, p):
        pb, pt, xp, vp = x["bottom_pressure"], x["top_pressure"], x["position"], x["velocity"]
        Ab, At = self.bottom_area, self.top_area
        Vb = ops.fmax(self.bottom_volume + Ab * xp, self.min_volume_fraction * self.bottom_volume)
        Vt = ops.fmax(self.top_volume - At * xp, self.min_volume_fraction * self.top_volume)
        qi = self.internal_leakage * (pt - pb)
        net_b = u["bottom_flow"] - Ab * vp + qi - self.external_leakage * pb
        net_t = -u["top_flow"] + At * vp - qi - self.external_leakage * pt
        if self.fluid is None or self.fluid.plain:
            beta = self.bulk_modulus
            dpb, dpt = beta / Vb * net_b, beta / Vt * net_t                         # (M22)
        else:                                                                      # (M41)
            dpb = net_b / oil_compliance(Vb, pb, self.bulk_modulus, self.fluid)
            dpt = net_t / oil_compliance(Vt, pt, self.bulk_modulus, self.fluid)
        return {
            "bottom_pressure": dpb,
            "top_pressure": dpt,
            "position": vp,                                                          # (M23)
            "velocity": (Ab * pb - At * pt - u["load_force"] - u["friction_force"]
                         - self.moving_mass * self.gravity + self.stop_force(xp, vp))
            / self.moving_mass,
        }

    def cavity_volumes(self, x, outputs=None):
        """Gas/vapour cavity volume in each chamber (M42), [m^3].

        Parameters
        ----------
        x : dict
            States (arrays of a run allowed), local name -> value [SI]
        outputs : dict, optional
            Its outputs there, local port name -> value [SI] (not needed: the pressures
            are states)

        Returns
        -------
        dict
            ``{"bottom chamber": V_cav, "top chamber": V_cav}``, [m^3]; empty without a
            cavity model
        """
        if self.fluid is None or self.fluid.cavity_pressure is None:
            return {}
        pc, d = self.fluid.cavity_pressure, self.fluid.cavity_pressure_drop
        xp = np.asarray(x["position"], dtype=float)
        Vb = np.maximum(self.bottom_volume + self.bottom_area * xp,
                        self.min_volume_fraction * self.bottom_volume)
        Vt = np.maximum(self.top_volume - self.top_area * xp,
                        self.min_volume_fraction * self.top_volume)
        return {"bottom chamber": Vb * cavity_volume_fraction(np.asarray(x["bottom_pressure"]), pc, d),
                "top chamber": Vt * cavity_volume_fraction(np.asarray(x["top_pressure"]), pc, d)}

    def initial_guess(self):
        return {"bottom_pressure": self.nominal_pressure, "top_pressure": self.nominal_pressure,
                "position": self.initial_position, "velocity": 0.0}
