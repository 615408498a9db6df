"""Four-way two-stage servovalve: spool dynamics and orifice flows (docs/model.md 4, M19-M21)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..engine import ops
from ..engine.component import Component, HydraulicEnd, Port, State, parameter

__all__ = ["Servovalve", "valve_coefficient"]


def valve_coefficient(rated_flow, rated_pressure_drop, max_opening):
    """K_v from rated data (M21): ``Q_N / (x_max sqrt(dp_N/2))``, [m^2/s/sqrt(Pa)].

    Parameters
    ----------
    rated_flow : float
        Q_N, [m^3/s]
    rated_pressure_drop : float
        Valve drop at rated flow, over two orifices, [Pa]
    max_opening : float
        Spool opening at rated current, [m]

    Returns
    -------
    float
        Valve coefficient K_v, [m^2/(s sqrt(Pa))]

    Examples
    --------
    The default rig's valve, 19 L/min at 1000 psi over 0.4 mm:
    ``3.1667e-4 / (4e-4 sqrt(3.447e6)) = 3.1667e-4 / 0.74267``:

    >>> print(f"{valve_coefficient(19e-3 / 60, 6.894757e6, 0.4e-3):.4e}")
    4.2638e-04
    """
    return rated_flow / (max_opening * ops.sqrt(rated_pressure_drop / 2.0))


@dataclass(kw_only=True)
class Servovalve(Component):
    """Spool position from coil current (M19) and sharp-edged orifice flows (M20).

    Spool: ``x_v'' = w_v^2 (G_v i_sat - x_v) - 2 zeta_v w_v x_v'`` with ``i_sat`` the current
    saturated at +-rated_current and ``G_v = max_opening/rated_current``; the opening used in
    (M20) is clipped to +-max_opening. Each orifice: ``K_v sg(+-x_v + u_k) phi(dp)`` with
    ``phi(dp) = dp/(dp^2 + p_lam^2)^(1/4)``, the square-root law with a laminar region
    below ``laminar_pressure`` (:func:`hydroline.engine.ops.smooth_sqrt`).

    Parameters
    ----------
    rated_current : float
        [A]
    rated_flow : float
        Q_N at rated drop, [m^3/s]
    rated_pressure_drop : float
        dp_N over the valve (two orifices), [Pa]
    max_opening : float
        Spool opening at rated current, [m]
    natural_frequency : float
        w_v/2pi, [Hz]
    damping_ratio : float
        zeta_v, [-]
    laps : tuple
        (u1, u2, u3, u4), negative overlap, positive underlap, [m]
    laminar_pressure : float
        p_lam, [Pa]

    Other Parameters
    ----------------
    name, connections
        As for every component (:class:`~hydroline.engine.component.Component`):
        its unique name in the network and its port -> signal map.

    Notes
    -----
    Ports: inputs ``current`` [A], ``supply_pressure``, ``return_pressure``,
    ``bottom_pressure``, ``top_pressure`` [Pa]; outputs ``supply_flow`` (into the valve from
    the supply port), ``return_flow`` (out of the valve into the return port), ``bottom_flow``
    (into the bottom chamber, q_b), ``top_flow`` (out of the top chamber, q_t) [m^3/s].
    States ``spool_position`` [m], ``spool_velocity`` [m/s].
    """

    rated_current: float = parameter(0.05, "A", "rated coil current (saturation)", positive=True,
                                     plausible=(0.0001, 5.0))
    rated_flow: float = parameter(3.15e-4, "m^3/s", "Q_N at the rated drop (M21)", positive=True,
                                  plausible=(1e-06, 0.1))
    rated_pressure_drop: float = parameter(6.895e6, "Pa", "dp_N over two orifices (M21)", positive=True,
                                           plausible=(1e5, 5e7))
    max_opening: float = parameter(4e-4, "m", "spool opening at rated current (M19)", positive=True,
                                   plausible=(1e-05, 0.01))
    natural_frequency: float = parameter(140.0, "Hz", "w_v/2pi of the spool (M19)", positive=True,
                                         plausible=(1.0, 2000.0))
    damping_ratio: float = parameter(1.0, "-", "zeta_v of the spool (M19)", positive=True,
                                     plausible=(0.05, 5.0))
    laps: tuple = parameter((0.0, 0.0, 0.0, 0.0), "list:m",
                            "u1..u4: negative overlap, positive underlap (M20)",
                                plausible=(-0.001, 0.001))
    laminar_pressure: float = parameter(1e5, "Pa", "p_lam, laminar region of (M20)", positive=True,
                                        plausible=(100.0, 1e7))

    inputs = {
        "current": Port("current", "coil current"),
        "supply_pressure": Port("pressure", "pressure at the supply port P"),
        "return_pressure": Port("pressure", "pressure at the return port T"),
        "bottom_pressure": Port("pressure", "pressure at control port to the bottom chamber"),
        "top_pressure": Port("pressure", "pressure at control port to the top chamber"),
    }
    outputs = {
        "supply_flow": Port("flow", "flow into the valve at the supply port"),
        "return_flow": Port("flow", "flow out of the valve at the return port"),
        "bottom_flow": Port("flow", "flow into the bottom chamber (q_b)"),
        "top_flow": Port("flow", "flow out of the top chamber (q_t)"),
    }
    #: P must reach the supply, T the tank (M20 meters P -> B, A -> T, ...)
    pressure_order = (("supply", "return"),)

    def __post_init__(self):
        self.check_parameters()
        if len(self.laps) != 4:
            raise ValueError(f"{self.name}: laps must be four lengths (u1..u4) [m]")
        if any(not abs(u) < self.max_opening for u in self.laps):
            raise ValueError(f"{self.name}: laps must each be shorter than max_opening "
                             f"({self.max_opening:g} m) [m], got {tuple(self.laps)!r}")

    def hydraulic_ends(self):
        """Ports P (supply), T (return) and the control ports to the chambers.

        Returns
        -------
        dict
            End name -> :class:`~hydroline.engine.component.HydraulicEnd`.
        """
        return {end: HydraulicEnd(f"{end}_pressure", (f"{end}_flow",))
                for end in ("supply", "return", "bottom", "top")}

    @property
    def coefficient(self) -> float:
        """K_v (M21), [m^2/s/sqrt(Pa)]."""
        return valve_coefficient(self.rated_flow, self.rated_pressure_drop, self.max_opening)

    @property
    def states(self):
        """The states: ``spool_position`` [m] and ``spool_velocity`` [m/s] of (M19)."""
        return [State("spool_position", "m", self.max_opening),
                State("spool_velocity", "m/s", self.max_opening * self.natural_frequency * 6.3)]

    def orifice(self, opening, dp):
        """Flow through one metering edge (M20), [m^3/s]; opening >= 0 [m], dp [Pa].

        Parameters
        ----------
        opening : float
            Spool opening beyond the lap, >= 0 (number or CasADi symbol), [m]
        dp : float
            Pressure drop across the edge, [Pa]

        Returns
        -------
        float
            Flow through the edge, with the sign of dp, [m^3/s]
        """
        return self.coefficient * opening * ops.smooth_sqrt(dp, self.laminar_pressure)

    def outputs_of(self, t, x, u, p):
        xm = self.max_opening
        xv = ops.fmin(ops.fmax(x["spool_position"], -xm), xm)
        u1, u2, u3, u4 = self.laps
        pS, pR, pb, pt = (u["supply_pressure"], u["return_pressure"],
                          u["bottom_pressure"], u["top_pressure"])
        s_b = self.orifice(ops.fmax(xv + u1, 0.0), pS - pb)     # P -> B
        b_r = self.orifice(ops.fmax(-xv + u2, 0.0), pb - pR)    # B -> T
        t_r = self.orifice(ops.fmax(xv + u3, 0.0), pt - pR)     # A(top) -> T
        s_t = self.orifice(ops.fmax(-xv + u4, 0.0), pS - pt)    # P -> A(top)
        return {"bottom_flow": s_b - b_r,                       # (M20)
                "top_flow": t_r - s_t,
                "supply_flow": s_b + s_t,
                "return_flow": b_r + t_r}

    def derivatives(self, t, x, u, p):
        w = 2.0 * np.pi * self.natural_frequency
        i_sat = ops.fmin(ops.fmax(u["current"], -self.rated_current), self.rated_current)
        gain = self.max_opening / self.rated_current
        return {"spool_position": x["spool_velocity"],                                   # (M19)
                "spool_velocity": w * w * (gain * i_sat - x["spool_position"])
                - 2.0 * self.damping_ratio * w * x["spool_velocity"]}
