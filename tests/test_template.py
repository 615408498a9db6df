"""The template rig (hydroline/rigs/ayalew2005.toml) is built by the circuit builder: its run
equals the run of the hand-wired template build it replaced (numbers recorded from that build),
and its expansion into circuit tables is the circuit file of the same rig
(tests/data/ayalew2005_circuit.toml), component by component."""
from pathlib import Path

import numpy as np
import pytest

import hydroline

DATA = Path(__file__).parent / "data"

#: The default rig's states, component by component, in the order of the hand-wired template
#: build (the circuit builder keeps it: equal state order gives bit-identical runs).
STATE_GROUPS = [("supply.section1", 32), ("supply.accumulator", 2), ("supply.section2", 32),
                ("return.section1", 32), ("return.accumulator", 2), ("return.section2", 32),
                ("servovalve", 2), ("actuator", 4)]

#: The result's signal columns (CSV columns, summaries), in the hand-wired build's order.
SIGNALS = ["pump_pressure", "supply.manifold_inlet_pressure", "pump_flow",
           "supply.accumulator_flow", "supply_port_pressure", "supply.section2_inflow",
           "supply.manifold_flow", "supply.manifold_pressure", "tank_pressure",
           "return.section1_inlet_pressure", "tank_flow", "return.accumulator_flow",
           "return_port_pressure", "return.section2_outflow", "return.manifold_flow",
           "return.check_valve_pressure", "return.manifold_pressure", "bottom_chamber_pressure",
           "top_chamber_pressure", "piston_position", "piston_velocity", "valve_current",
           "supply_port_flow", "return_port_flow", "bottom_chamber_flow", "top_chamber_flow",
           "friction_force", "load_force"]

#: The 50 mA open-loop step of the default rig as the hand-wired template build
#: (system._build, before the circuit builder took over) ran it, time [s] -> signal -> SI.
#: At rest (t = 0) the piston sits on its bottom stop (-51 mm) and, the valve's four laps
#: equal and the areas equal, both chambers hold the mean of the port pressures:
#: (20.6845547 + 1.51342801) / 2 = 11.0989914 MPa.
REFERENCE = {
    0.0: {"supply_port_pressure": 20684554.7, "return_port_pressure": 1513428.01,
          "bottom_chamber_pressure": 11098991.3, "top_chamber_pressure": 11098991.3,
          "piston_position": -0.051000078, "piston_velocity": 0.0},
    0.02: {"supply_port_pressure": 19180920.8, "return_port_pressure": 2725020.72,
           "bottom_chamber_pressure": 11854334.7, "top_chamber_pressure": 9981717.85,
           "piston_position": -0.0438216171, "piston_velocity": 0.963804631},
    0.05: {"supply_port_pressure": 19695465.2, "return_port_pressure": 2312589.22,
           "bottom_chamber_pressure": 11818745.2, "top_chamber_pressure": 9834451.37,
           "piston_position": -0.0133639167, "piston_velocity": 0.987959466},
    0.1: {"supply_port_pressure": 19859396.8, "return_port_pressure": 1489842.18,
          "bottom_chamber_pressure": 11646100.7, "top_chamber_pressure": 9633048.55,
          "piston_position": 0.0371318422, "piston_velocity": 1.01868928},
}
#: Each trace's excursion over the run in that build, [SI]: the scale of the tolerance.
SPAN = {"supply_port_pressure": 2.861188e6, "return_port_pressure": 2.746367e6,
        "bottom_chamber_pressure": 2.9e6, "top_chamber_pressure": 2.9e6,
        "piston_position": 0.102, "piston_velocity": 1.1955}


def test_default_rig_run_equals_the_hand_wired_template_build():
    """Same states in the same order, same signal columns, and the traces of the recorded
    build within 1e-4 of each trace's excursion (the solver's rtol 1e-6 is 6e-3 % of the
    excursion, README; the recorded numbers carry 9 digits)."""
    res = hydroline.simulate(None, "open-loop-step")
    states = [c for c in res.columns if c not in SIGNALS]
    groups = []
    for s in states:
        owner = next(n for n, _ in STATE_GROUPS if s.startswith(n + "."))
        if groups and groups[-1][0] == owner:
            groups[-1][1] += 1
        else:
            groups.append([owner, 1])
    assert [tuple(g) for g in groups] == STATE_GROUPS
    assert res.columns[:len(SIGNALS)] == SIGNALS
    for t, row in REFERENCE.items():
        i = int(np.argmin(np.abs(res.t - t)))
        assert res.t[i] == pytest.approx(t, abs=1e-9)
        for k, v in row.items():
            assert abs(res[k][i] - v) < 1e-4 * SPAN[k], (t, k, res[k][i], v)
