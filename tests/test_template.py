"""The template rig (hydroline/rigs/ayalew2005.toml) is built by the circuit builder: its run
equals the run of the hand-wired template build it replaced (numbers recorded from that build),
and its expansion into circuit tables is the circuit file of the same rig
(tests/data/ayalew2005_circuit.toml), component by component."""
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import hydroline
from hydroline.engine.component import Component, HydraulicEnd, Port, parameter

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


@dataclass(kw_only=True)
class Capillary(Component):
    """Laminar flow through a long thin bore (Hagen-Poiseuille): q = dp pi d^4 / (128 mu L),
    mu = rho nu of the rig's oil, which the component takes from its context."""

    length: float = parameter(1.0, "m", "bore length", positive=True, plausible=(1e-3, 100.0))
    diameter: float = parameter(1e-3, "m", "bore", positive=True, plausible=(1e-5, 0.1))
    fluid: object = None

    context = ("fluid",)
    conducts = True
    inputs = {"inlet_pressure": Port("pressure"), "outlet_pressure": Port("pressure")}
    outputs = {"flow": Port("flow")}

    def hydraulic_ends(self):
        return {"inlet": HydraulicEnd("inlet_pressure", ("flow",)),
                "outlet": HydraulicEnd("outlet_pressure", ("flow",))}

    def outputs_of(self, t, x, u, p):
        mu = self.fluid.density * self.fluid.kinematic_viscosity
        return {"flow": (u["inlet_pressure"] - u["outlet_pressure"]) * np.pi
                * self.diameter ** 4 / (128 * mu * self.length)}


CAPILLARY_RIG = """
[fluid]
density = "870 kg/m^3"
kinematic_viscosity = "32 cSt"
bulk_modulus = "1.5 GPa"

[circuit.pump]
type = "pressure_source"
pressure = "10 MPa"
ports = { pressure = "p_pump" }

[circuit.inlet]
type = "capillary"
length = "2 m"
diameter = "1 mm"
ports = { inlet_pressure = "p_pump", outlet_pressure = "p_node", flow = "q_in" }

[circuit.node]
type = "volume"
volume = "0.1 L"
terms = { inflow = 1, outflow = -1 }
ports = { inflow = "q_in", outflow = "q_out", pressure = "p_node" }

[circuit.outlet]
type = "capillary"
length = "2 m"
diameter = "1 mm"
ports = { inlet_pressure = "p_node", outlet_pressure = "p_tank", flow = "q_out" }

[circuit.tank]
type = "pressure_source"
pressure = "1 MPa"
ports = { pressure = "p_tank" }
"""


def test_a_new_component_type_takes_the_fluid_without_touching_the_builder(monkeypatch, tmp_path):
    """A component declaring ``context = ("fluid",)`` is handed the rig's oil by the builder
    (registered as a type, nothing else), as is a volume given no bulk modulus. Two equal
    capillaries in series hold the node between them at the mean of 10 and 1 MPa, and carry
    q = 4.5 MPa pi (1 mm)^4 / (128 * 870 kg/m^3 * 32 cSt * 2 m) = 0.1190 L/min."""
    from hydroline.circuit import COMPONENT_TYPES, ComponentType
    from hydroline.engine import solve_steady_state
    from hydroline.rigs import load_rig
    from hydroline.system import build_circuit

    monkeypatch.setitem(COMPONENT_TYPES, "capillary",
                        ComponentType("capillary", Capillary, "laminar capillary"))
    f = tmp_path / "capillary.toml"
    f.write_text(CAPILLARY_RIG)
    circuit = build_circuit(load_rig(f))
    cap, node = circuit.component("inlet"), circuit.component("node")
    assert cap.fluid.density == 870.0 and cap.fluid.kinematic_viscosity == pytest.approx(32e-6)
    assert node.bulk_modulus == 1.5e9
    net = circuit.network()
    ss = solve_steady_state(net)
    s = net.signals_at(0.0, ss.x, ss.p)
    q = 4.5e6 * np.pi * 1e-3 ** 4 / (128 * 870 * 32e-6 * 2)
    assert q * 6e4 == pytest.approx(0.1190, abs=1e-4)            # [L/min], the hand value
    assert s["p_node"] == pytest.approx(5.5e6, rel=1e-9)
    assert s["q_in"] == pytest.approx(q, rel=1e-9) and s["q_out"] == pytest.approx(q, rel=1e-9)


def test_template_expands_into_the_paper_rigs_circuit_file():
    """The template's expansion is tests/data/ayalew2005_circuit.toml component by component:
    same names, types, ports and flow terms, and every declared parameter equal (a value the
    file leaves out taken at its declared default, as the builder does): e.g. each chamber's
    volume at mid-stroke 10 cm^3 + 4.83 cm^2 * 51 mm = 34.633 cm^3, written out in the file."""
    from hydroline.circuit import COMPONENT_TYPES, circuit_specs
    from hydroline.rigs import load_rig
    from hydroline.rigs.template import expand

    default, circuit = load_rig(), load_rig(DATA / "ayalew2005_circuit.toml")
    # the calibrated values follow the default rig's (recalibrated now and then)
    for sec in ("supply.section1", "supply.section2", "return.section1", "return.section2"):
        for k in ("length", "diameter", "bulk_modulus"):
            circuit.set(f"circuit.{sec}.{k}", default.raw[f"{sec}.{k}"])
    for side in ("supply", "return"):
        circuit.set(f"circuit.{side}.manifold.resistance", default.raw[f"{side}.manifold.resistance"])
    circuit.set("circuit.supply.pump.pressure", default.raw["supply.pressure"])
    circuit.set("circuit.return.tank.pressure", default.raw["return.pressure"])
    circuit.set("circuit.actuator.moving_mass", default.raw["actuator.moving_mass"])
    circuit.set("circuit.actuator.bulk_modulus", default.raw["actuator.bulk_modulus"])
    template = {s.name: s for s in expand(default)}
    written = {s.name: s for s in circuit_specs(circuit)}
    assert sorted(template) == sorted(written)
    assert template["actuator"].params["bottom_volume"] == pytest.approx(34.633e-6, rel=1e-12)
    for name, t in template.items():
        w = written[name]
        assert (t.type, t.ports, t.terms) == (w.type, w.ports, w.terms), name
        for key, decl in COMPONENT_TYPES[t.type].declarations().items():
            a, b = t.params.get(key, decl.default), w.params.get(key, decl.default)
            if isinstance(a, str) or a is None:
                assert a == b, (name, key)
            else:
                assert np.allclose(a, b, rtol=1e-12, atol=0), (name, key, a, b)


def test_template_values_reaching_the_builder_are_named_by_their_template_paths():
    """A template value the builder checks (its component's declaration) is named as the rig
    file wrote it, not as a circuit path: a bore of 0 allowed past its plausible range is
    refused by the hose's bound; a supply pressure allowed above its range passes on to the
    pump, the hoses and the actuator whose values derive from it."""
    from hydroline.rigs import RigError, load_rig
    from hydroline.system import build_circuit

    rig = load_rig()
    rig.set("rig.allow_implausible", ["supply.section1.diameter"])
    rig.set("supply.section1.diameter", "0 mm")
    with pytest.raises(RigError, match=r"^supply\.section1\.diameter: must be > 0 \[m\], got "
                                       r"'0 mm' \(component 'supply\.section1', hose\)$"):
        build_circuit(rig)
    rig = load_rig()
    rig.set("rig.allow_implausible", ["supply.pressure"])
    rig.set("supply.pressure", "150 MPa")
    circuit = build_circuit(rig)
    assert circuit.component("supply.pump").pressure == 150e6
    assert circuit.component("supply.section2").nominal_pressure == 150e6
    assert circuit.component("actuator").nominal_pressure == pytest.approx(0.5 * (150e6 + 1.5e6))
