"""Virtual friction experiments: the paper's friction tests run on the model itself.

:func:`virtual_friction_tests` makes the records that
:func:`hydroline.analysis.friction_id.identify_friction` reads from a real rig: open-loop
steady-velocity runs (the piston held by its holding current, then a current step) and the
closed-loop sine, so that the identification can be checked against the friction the model
was given (M24). CLI: ``hydroline friction-id --virtual``.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from .. import components as comp
from ..analysis.fit import Measurements
from ..analysis.friction_id import axis_mechanics
from ..analysis.linearize import (VALVE_COMMAND, OperatingPoint, axis_network, axis_signal, select_axis,
                                  solve_operating_point, transfer_state)
from ..rigs import Rig, load_rig
from ..scenarios.experiments import experiment
from ..scenarios.running import simulate
from ..engine import integrate
from ..system import build_circuit

__all__ = ["virtual_friction_tests", "RECORD_COLUMNS"]

#: The columns a virtual run records, as a rig's data acquisition would (SI units).
RECORD_COLUMNS = ("valve_current", "supply_port_pressure", "return_port_pressure",
                  "bottom_chamber_pressure", "top_chamber_pressure", "piston_position")


def _record(res, axis, columns=RECORD_COLUMNS, load_cell=False, load_force=None):
    """The record of a run as the axis's data acquisition writes it (generic column names)."""
    data = {"time": res.t}
    data.update({c: res[axis_signal(axis, c)] for c in columns
                 if axis_signal(axis, c) in res.data})
    if load_cell:   # the load force as a load cell on the rod measures it (positive down)
        data["external_force"] = res[load_force]
    return pd.DataFrame(data)


def _open_loop_run(rig, axis, di, t_run, dt, label, load_cell=False):
    """Piston held at -+40 mm, then the current steps by di at 5 ms (one steady run)."""
    x0 = -0.04 if di > 0 else 0.04
    hold = solve_operating_point(rig, OperatingPoint(piston_position=x0), axis=axis)
    ax = hold.axis
    half = ax.stroke / 2
    i0 = hold.valve_current
    cmd = comp.StepCommand(name=VALVE_COMMAND, initial=i0, final=i0 + di, time=5e-3,
                           connections={"command": ax.current})
    net = axis_network(rig, [cmd], ax.name, x0)
    x, p = transfer_state(hold, net)
    p[net.parameter_names.index(f"{VALVE_COMMAND}.initial")] = i0
    p[net.parameter_names.index(f"{VALVE_COMMAND}.final")] = i0 + di
    res = integrate(net, x, t_run, dt_out=dt, p=p)
    df = _record(res, ax, load_cell=load_cell,
                 load_force=net.component(ax.actuator).signal("load_force"))
    near = np.flatnonzero(np.abs(df["piston_position"].to_numpy()) > half - 2e-3)
    if near.size:
        df = df.iloc[:max(int(near[0]), 10)]
    return Measurements(df, label)


def virtual_friction_tests(rig: Rig | str | None = None, currents=None, t_run: float = 0.12,
                           sine: bool = True, dt: float = 1e-4, slow_currents=None,
                           damper: float = 1e4, axis: str | None = None):
    """The paper's friction experiments run on the model itself (to check the identification).

    Open-loop runs: the piston held at -40 mm (up runs) or +40 mm (down runs) by its holding
    current, then the current steps by each value of ``currents`` at 5 ms and the run lasts
    ``t_run`` or until the piston nears its stop. Closed-loop sine: the rig's
    ``closed-loop-sine`` scenario (the paper's 2 Hz, 35 mm under P control).

    Slow runs (``slow_currents``, a few mm/s, around the Stribeck velocity): there the friction
    force falls with speed (M24) -- for the default rig by up to ~5 kN s/m, more than the
    viscous term and the valve's pressure-flow slope damp -- so an open-loop run (and a P
    position loop) at these speeds stick-slips instead of reaching a steady velocity (the
    default rig hunts with a ~0.2 s period at 0.1-0.2 mA). These runs are therefore made against
    a viscous damper specimen of ``damper`` N s/m added to the rig's load, which makes the
    steady motion stable; its force is recorded as the ``external_force`` column (a load
    cell), so Newton's law (M23) removes it exactly and the friction point is unbiased.

    Parameters
    ----------
    rig : Rig, str or None
        The rig (None: the embedded default).
    currents : list[float]
        Current steps [A]; +-(1, 3, 10, 25) % of rated when None
    t_run : float
        Longest run, [s]
    sine : bool
        Also run the closed-loop sine
    dt : float
        Sampling interval, [s]
    slow_currents : list
        Current steps of the slow runs against the damper [A];
        +-(0.1, 0.14, 0.2, 0.3, 0.4) % of rated when None (about 2-9 mm/s
        on the default rig); () for none
    damper : float
        Damping of the slow runs' specimen, [N s/m]
    axis : str
        The axis tested (None: the first); the others hold. Its load
        takes the damper; the sine is the rig's ``closed-loop-sine`` on it

    Returns
    -------
    steady, sine : list of Measurements
        The open-loop runs (slow runs included) and the closed-loop sine records.
    """
    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    ax = select_axis(rig, axis)
    i_r = build_circuit(rig).component(ax.valve).rated_current
    if currents is None:
        currents = [s * f * i_r for f in (0.01, 0.03, 0.1, 0.25) for s in (1, -1)]
    if slow_currents is None:
        slow_currents = [s * f * i_r for f in (0.001, 0.0014, 0.002, 0.003, 0.004) for s in (1, -1)]
    steady = [_open_loop_run(rig, ax.name, di, t_run, dt,
                             f"virtual open-loop run, {di * 1e3:+.3g} mA") for di in currents]
    if len(slow_currents):
        load = axis_mechanics(rig, ax.name).load
        if load is None:
            raise ValueError(f"axis '{ax.name}': no load component to add the slow runs' "
                             f"damper to (slow_currents=() runs none)")
        path = (f"circuit.{load.name}.damping" if f"circuit.{load.name}.type" in rig.raw
                else "load.damping")
        damped = rig.copy()
        damped.set(path, f"{load.damping + damper!r} N*s/m")
        steady += [_open_loop_run(damped, ax.name, di, t_run, dt, f"virtual slow run against a "
                                  f"{damper:g} N s/m damper, {di * 1e3:+.3g} mA", load_cell=True)
                   for di in slow_currents]
    sines = []
    if sine:
        res = simulate(rig, replace(experiment(rig, "closed-loop-sine"), axis=ax.name), dt_out=dt)
        sines.append(Measurements(_record(res, ax), "virtual closed-loop sine"))
    return steady, sines
