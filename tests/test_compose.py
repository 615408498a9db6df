"""Rigs that extend rigs and sub-circuits (issue 27 items 2, 3; hydroline.circuit.compose).

* the rewritten ``two_axis`` (a shared supply plus two instances of one axis) gives the traces
  of the file with every component written out (tests/data/two_axis_written_out.toml), and is
  at most 60 % of its length;
* two identical axes (``base = "two_axis"``, both stepped alike) give identical traces;
* the paper's circuit with a filter element and its housing before the valve (``base =
  "ayalew2005_circuit"``, a short file) passes the axis's flow: the element's mean drop is
  R A v at the piston's mean velocity (continuity);
* ``base =`` a shipped rig's name, a path relative to the file or absolute, chains of bases;
* every bad edit is refused in one line (unknown component, dangling port, base cycle, base
  not found, type change, sub-circuit ports and members).

The runs use one mode per hose section and short windows: a few seconds each.
"""
from pathlib import Path

import numpy as np
import pytest

import hydroline
from hydroline.cli import main
from hydroline.rigs import RigError, load_rig
from hydroline.system import build_circuit

DATA = Path(__file__).parent / "data"
SHIPPED = Path(hydroline.__file__).parent / "rigs"
#: Lines of two_axis.toml with every component written out (before sub-circuits).
WRITTEN_OUT_LINES = 253


def _file(folder: Path, text: str, name: str = "rig.toml") -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def _one_line(capsys, path, *needles):
    """``hydroline circuit PATH --json``: exit 2, one line on stderr naming every needle."""
    rc = main(["circuit", str(path), "--json"])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


# ---------------------------------------------------------------- sub-circuits: two_axis

def test_rewritten_two_axis_gives_the_written_out_traces():
    """The same components, values and wiring in the same order: the same network, so the
    same arithmetic (the run of one is the other's to the last bit; 1e-12 of each trace's
    excursion leaves room for nothing but rounding)."""
    new, old = load_rig("two_axis"), load_rig(DATA / "two_axis_written_out.toml")
    a, b = build_circuit(new), build_circuit(old)
    assert [c.name for c in a.components] == [c.name for c in b.components]
    for x, y in zip(a.components, b.components):
        assert type(x) is type(y) and x.connections == y.connections, x.name
    ra, rb = hydroline.simulate(new), hydroline.simulate(old)
    assert list(ra.data.columns) == list(rb.data.columns)
    for k in ra.data.columns:
        assert np.max(np.abs(ra[k] - rb[k])) <= 1e-12 * max(np.ptp(rb[k]), 1e-300), k
    lines = (SHIPPED / "two_axis.toml").read_text().count("\n")
    assert lines <= 0.6 * WRITTEN_OUT_LINES, lines


def test_instances_name_their_components_and_signals_under_their_prefix():
    rig = load_rig("two_axis")
    v = rig.values
    # a member's own signal under the prefix, a group port joined to the outside signal
    assert v["circuit.axis2.servovalve.ports.current"] == "axis2.valve_current"
    assert v["circuit.axis2.supply_hose.ports.upstream_pressure"] == "supply.manifold_pressure"
    assert v["circuit.axis1.supply_hose.ports.upstream_flow"] == "axis1.supply_hose_inflow"
    # the instance's override, and the group's value elsewhere
    assert v["circuit.axis1.actuator.initial_position"] == pytest.approx(-0.020)
    assert v["circuit.axis2.actuator.initial_position"] == 0.0
    assert "subcircuit.axis.ports" not in rig.raw and "circuit.axis1.subcircuit" not in rig.raw
    # a swept path reaches one instance's member (what `hydroline sweep --set` does)
    rig.set("circuit.axis2.supply_hose.length", "1.5 m")
    assert rig["circuit.axis2.supply_hose.length"] == 1.5
    assert rig["circuit.axis1.supply_hose.length"] == pytest.approx(3.048)


IDENTICAL_AXES = """
[rig]
base = "two_axis"
modes_per_section = 1            # one mode per hose: a short compile
scenario = "both-step"

[circuit."axis1.actuator"]
initial_position = "0 mm"        # where axis 2 starts: the two axes are now alike

[scenario.both-step]
type = "axis-commands"
t_end = "40 ms"
""" + "".join(f"""
[scenario.both-step.{ax}]
quantity = "position"
waveform = "step"
initial = "0 mm"
final = "10 mm"
time = "5 ms"
""" for ax in ("axis1", "axis2"))


def test_two_identical_axes_give_identical_traces(tmp_path):
    """Two instances with the same values, stepped alike, on one symmetric supply: the same
    equations from the same rest state, so the same traces (only the order in which the
    junctions add their two flows differs: rounding, ~1e-13 of the excursion)."""
    res = hydroline.simulate(load_rig(_file(tmp_path, IDENTICAL_AXES)))
    a2 = [c for c in res.data.columns if c.startswith("axis2.")]
    assert len(a2) > 20
    assert np.ptp(res["axis2.piston_position"]) > 5e-3           # it moved: not vacuous
    for c in a2:
        twin = "axis1." + c[len("axis2."):]
        assert np.max(np.abs(res[c] - res[twin])) <= 1e-9 * max(np.ptp(res[c]), 1e-300), c


def test_an_extending_file_places_the_base_groups_again(tmp_path):
    """A third axis from two_axis's own [subcircuit.axis]; the junctions take its flows."""
    path = _file(tmp_path, """
[rig]
base = "two_axis"
[circuit.axis3]
subcircuit = "axis"
ports = { supply_pressure = "supply.manifold_pressure", supply_flow = "axis3.supply_hose_inflow", return_pressure = "return.manifold_pressure", return_flow = "axis3.return_hose_outflow" }
actuator = { moving_mass = "20 kg" }
[circuit."supply.junction"]
terms = { axis3 = 1 }
ports = { axis3 = "axis3.supply_hose_inflow" }
[circuit."return.junction"]
terms = { axis3 = 1 }
ports = { axis3 = "axis3.return_hose_outflow" }
""")
    circuit = build_circuit(load_rig(path))
    assert list(circuit.axes) == ["axis1", "axis2", "axis3"]
    assert circuit.component("axis3.actuator").moving_mass == 20.0
    assert circuit.component("supply.junction").terms == {"axis1": 1, "axis2": 1,
                                                          "accumulator": 1, "axis3": 1}


def test_an_instance_and_its_terms_removed_leave_one_axis(tmp_path):
    path = _file(tmp_path, """
[rig]
base = "two_axis"
[remove]
components = ["axis2"]                 # every component of the instance
terms = ["supply.junction.axis2", "return.junction.axis2"]
""")
    circuit = build_circuit(load_rig(path))
    assert list(circuit.axes) == ["axis1"]
    assert not [c for c in circuit.components if c.name.startswith("axis2.")]


def test_a_rig_written_back_reads_back(tmp_path):
    """Rig.to_toml writes dotted names as nested tables ([circuit.axis1.supply_hose]): read
    as the same components, and an edit may name them either way."""
    rig = load_rig("two_axis")
    again = load_rig(_file(tmp_path, rig.to_toml(), "written.toml"))
    assert again.values == rig.values and list(again.values) == list(rig.values)
    edited = load_rig(_file(tmp_path, '[rig]\nbase = "written.toml"\n'
                                      '[circuit.axis2.actuator]\nmoving_mass = "20 kg"\n'))
    assert edited["circuit.axis2.actuator.moving_mass"] == 20.0


def test_the_bases_connections_of_a_removed_component_go_with_it(tmp_path):
    _file(tmp_path, '[rig]\nbase = "two_axis"\n[connections]\n'
                    '"axis2.servovalve.supply_pressure" = "pump_pressure"\n', "ideal.toml")
    path = _file(tmp_path, '[rig]\nbase = "ideal.toml"\n[remove]\ncomponents = ["axis2"]\n'
                           'terms = ["supply.junction.axis2", "return.junction.axis2"]\n')
    rig = load_rig(path)
    assert not [k for k in rig.values if k.startswith("connections.")]
    assert list(build_circuit(rig).axes) == ["axis1"]


def test_nested_sub_circuits(tmp_path):
    """A group placing a group: names nest (pair.left.r), ports pass through both."""
    path = _file(tmp_path, """
[fluid]
density = "870 kg/m^3"
kinematic_viscosity = "32 cSt"
bulk_modulus = "1.5 GPa"
[circuit.pump]
type = "pressure_source"
pressure = "10 MPa"
ports = { pressure = "p_pump" }
[circuit.tank]
type = "pressure_source"
pressure = "1 MPa"
ports = { pressure = "p_tank" }
[circuit.pair]
subcircuit = "two_branches"
ports = { high = "p_pump", low = "p_tank" }
[subcircuit.branch]
ports = ["inlet", "outlet"]
[subcircuit.branch.r]
type = "resistance"
resistance = "1e10 Pa*s/m^3"
compute = "flow"
ports = { inlet_pressure = "inlet", outlet_pressure = "outlet", flow = "flow" }
[subcircuit.two_branches]
ports = ["high", "low"]
left = { subcircuit = "branch", ports = { inlet = "high", outlet = "low" } }
right = { subcircuit = "branch", ports = { inlet = "high", outlet = "low" }, r = { resistance = "2e10 Pa*s/m^3" } }
""")
    rig = load_rig(path)
    assert rig["circuit.pair.left.r.ports.flow"] == "pair.left.flow"
    assert rig["circuit.pair.right.r.ports.inlet_pressure"] == "p_pump"
    assert rig["circuit.pair.right.r.resistance"] == 2e10


# ---------------------------------------------------------------- extending the paper's rig

FILTERED = """
[rig]
base = "ayalew2005_circuit"      # the paper's rig, as a circuit
modes_per_section = 1            # one mode per hose: a short compile

[circuit.filter]                 # the element: dp = R q, from the hose's end into the housing
type = "resistance"
resistance = "1e9 Pa*s/m^3"
compute = "flow"
ports = { inlet_pressure = "supply_port_pressure", outlet_pressure = "filter_pressure", flow = "filter_flow" }

[circuit.filter_housing]         # the oil in the bowl, which the valve draws from
type = "volume"
volume = "0.2 L"
nominal_pressure = "20 MPa"
terms = { element = 1, valve = -1 }
ports = { element = "filter_flow", valve = "supply_port_flow", pressure = "filter_pressure" }

[circuit."supply.section2"]      # the hose now delivers what the element passes
ports = { downstream_flow = "filter_flow" }

[circuit.servovalve]             # and the valve's P port sits on the housing
ports = { supply_pressure = "filter_pressure" }
"""


def test_paper_rig_with_a_filter_before_the_valve(tmp_path):
    """50 mA step: the piston rises at about constant speed; the element passes what the
    bottom chamber takes, A v (continuity), so its mean drop over whole supply-line periods is
    R A v at the mean velocity. What the housing (0.2 L) and the chamber (35 cm^3) store or
    give back as their pressures swing by ~1 MPa is V dp / beta over 50 ms: below 1 % of A v."""
    path = _file(tmp_path, FILTERED)
    assert len(FILTERED.strip().splitlines()) < 30           # "a short file"
    rig = load_rig(path)
    assert rig["circuit.servovalve.ports.supply_pressure"] == "filter_pressure"
    assert rig["circuit.servovalve.ports.supply_flow"] == "supply_port_flow"   # the others stay
    res = hydroline.simulate(rig, "open-loop-step", t_end=0.07)
    t = res.t
    dp = res["supply_port_pressure"] - res["filter_pressure"]
    m = (t >= 0.02) & (t <= 0.07)
    area = 4.83e-4                                           # [paper] A_b, m^2
    q_hand = area * np.mean(res["piston_velocity"][m])
    assert q_hand > 2e-4                                     # ~29 L/min: the valve wide open
    assert np.mean(dp[m]) == pytest.approx(1e9 * q_hand, rel=0.02)
    rest = t < 0.01                                          # before the step: null leakage
    assert dp[rest][-1] == pytest.approx(1e9 * res["filter_flow"][rest][-1], rel=1e-9)


def test_the_shipped_paper_circuit_is_the_tested_one_with_the_templates_experiments():
    """hydroline/rigs/ayalew2005_circuit.toml: the components and values of
    tests/data/ayalew2005_circuit.toml (whose run tests/test_circuit.py checks against the
    template's), plus what the template's experiments and controller need, as the template."""
    shipped, tested = load_rig("ayalew2005_circuit"), load_rig(DATA / "ayalew2005_circuit.toml")
    template = load_rig()
    mine = {k: v for k, v in shipped.values.items() if k.startswith("circuit.")}
    theirs = {k: v for k, v in tested.values.items() if k.startswith("circuit.")}
    extra = set(mine) - set(theirs)
    assert set(theirs) <= set(mine) and all(mine[k] == theirs[k] for k in theirs)
    assert all(mine[k] == 0.0 for k in extra), extra          # zeros the defaults give too
    for k, v in template.values.items():
        if k.split(".")[0] in ("scenario", "controller", "fluid"):
            assert shipped[k] == v, k
    assert shipped["rig.line_method"] == template["rig.line_method"]


# ---------------------------------------------------------------- bases by name and path

def test_base_by_relative_and_absolute_path_and_chains(tmp_path):
    """top.toml -> sub/middle.toml (relative to top) -> two_axis (shipped): each level's
    values; the same chain through an absolute path."""
    _file(tmp_path, '[rig]\nbase = "two_axis"\nname = "middle"\n'
                    '[circuit.pump]\npressure = "18 MPa"\n', "sub/middle.toml")
    top = _file(tmp_path, '[rig]\nbase = "sub/middle.toml"\n'
                          '[circuit."axis2.actuator"]\nmoving_mass = "20 kg"\n', "top.toml")
    rig = load_rig(top)
    assert rig["rig.name"] == "middle" and rig["circuit.pump.pressure"] == 18e6
    assert rig["circuit.axis2.actuator.moving_mass"] == 20.0
    assert rig["circuit.axis1.actuator.moving_mass"] == pytest.approx(16.15)
    assert rig["rig.scenario"] == "position-step" and rig.source == str(top)
    absolute = _file(tmp_path / "elsewhere", f'[rig]\nbase = "{tmp_path / "top.toml"}"\n')
    assert load_rig(absolute)["circuit.pump.pressure"] == 18e6


def test_a_base_files_table_file_is_read_beside_it(tmp_path):
    """A relative ``file`` of the base names a file beside the base, not beside the file
    that extends it."""
    (tmp_path / "base").mkdir()
    (tmp_path / "base" / "cmd.csv").write_text("time [s],current [mA]\n0,0\n1,5\n")
    _file(tmp_path, (SHIPPED / "ayalew2005_circuit.toml").read_text()
          + '[circuit.command]\ntype = "table_command"\nfile = "cmd.csv"\n'
            'ports = { command = "spare_current" }\n', "base/base.toml")
    rig = load_rig(_file(tmp_path, '[rig]\nbase = "base/base.toml"\n', "top.toml"))
    assert rig["circuit.command.file"] == str(tmp_path / "base" / "cmd.csv")


def test_template_bases_and_template_values_still_work(tmp_path):
    """``base = "default"`` (and the shipped template's name) with template values."""
    for base in ("default", "ayalew2005", "ayalew2005_yang_tobler"):
        rig = load_rig(_file(tmp_path, f'[rig]\nbase = "{base}"\n[supply]\npressure = "18 MPa"\n'))
        assert rig["supply.pressure"] == 18e6 and "rig.base" not in rig.raw
    assert rig["rig.line_method"] == "yang-tobler"     # the chain's middle file


# ---------------------------------------------------------------- bad edits: one line each

BAD_EDITS = [
    # an edit of no component (a misspelt name would change nothing)
    ('[circuit.servovalv]\nrated_flow = "38 L/min"\n',
     ("circuit.servovalv: no component 'servovalv' to change", "did you mean 'servovalve'?",
      "a new component needs type")),
    # a removal leaving a port with nothing at its other end
    ('[remove]\ncomponents = ["return.check_valve"]\n',
     ("taking out 'return.check_valve' leaves port", "re-point it")),
    ('[remove]\ncomponents = ["actuator"]\n', ("taking out 'actuator' leaves port",)),
    ('[remove]\ncomponents = ["supply.section2"]\n', ("'supply.section2'", "nothing at its other end")),
    ('[remove]\ncomponents = ["supply.accumulator"]\n',
     ("leaves port 'accumulator' of 'supply.junction'",
      'drop the term ([remove] terms = ["supply.junction.accumulator"])')),
    ('[remove]\ncomponents = ["filter"]\n', ("remove.components: no component 'filter' in the base rig",)),
    ('[remove]\nterms = ["supply.junction.axis9"]\n', ("no flow term 'axis9'", "section2, accumulator")),
    ('[remove]\nparts = ["load"]\n', ("remove.parts: [remove] takes components = [...]",)),
    ('[remove]\ncomponents = "load"\n', ("remove.components: expected a list",)),
    ('[circuit.servovalve]\ntype = "hose"\n', ("circuit.servovalve.type: 'hose' would change the type",
                                               "remove it first")),
    ('[remove]\ncomponents = ["servovalve"]\n[connections]\n"servovalve.supply_pressure" = "pump_pressure"\n',
     ("connections.servovalve.supply_pressure: component 'servovalve' is removed",)),
    # sub-circuits
    ('[circuit.axis2]\nsubcircuit = "axle"\n', ("circuit.axis2.subcircuit: no sub-circuit 'axle'",)),
    ('[subcircuit.g]\nports = ["a"]\n[subcircuit.g.r]\ntype = "resistance"\n'
     'ports = { inlet_pressure = "a", flow = "q", outlet_pressure = "b" }\n'
     '[circuit.x]\nsubcircuit = "g"\nports = { a = "pump_pressure", z = "y" }\n',
     ("circuit.x.ports.z: sub-circuit 'g' has no port 'z' (ports: a)",)),
    ('[subcircuit.g]\nports = ["a"]\n[subcircuit.g.r]\ntype = "resistance"\n'
     'ports = { inlet_pressure = "a", flow = "q", outlet_pressure = "b" }\n'
     '[circuit.x]\nsubcircuit = "g"\n', ("circuit.x.ports: port 'a' of sub-circuit 'g' is not joined",)),
    ('[subcircuit.g]\nports = ["a"]\n[subcircuit.g.r]\ntype = "resistance"\n'
     'ports = { inlet_pressure = "a", flow = "q", outlet_pressure = "b" }\n'
     '[circuit.x]\nsubcircuit = "g"\nports = { a = "pump_pressure" }\nq = { resistance = "1 Pa*s/m^3" }\n',
     ("circuit.x.q: sub-circuit 'g' has no component 'q'",)),
    ('[subcircuit.g]\nports = ["a", "unused"]\n[subcircuit.g.r]\ntype = "resistance"\n'
     'ports = { inlet_pressure = "a", flow = "q", outlet_pressure = "b" }\n'
     '[circuit.x]\nsubcircuit = "g"\nports = { a = "pump_pressure", unused = "u" }\n',
     ("subcircuit.g.ports: port 'unused' is joined to none of its components",)),
    ('[subcircuit.g]\nports = []\nme = { subcircuit = "g" }\n[circuit.x]\nsubcircuit = "g"\n',
     ("sub-circuit 'g' places itself (g -> g)",)),
]


@pytest.mark.parametrize("edit, needles", BAD_EDITS, ids=[n[0][:40] for _, n in BAD_EDITS])
def test_a_bad_edit_of_the_paper_circuit_is_one_line(tmp_path, capsys, edit, needles):
    path = _file(tmp_path, '[rig]\nbase = "ayalew2005_circuit"\n' + edit)
    _one_line(capsys, path, *needles)


def test_removing_the_controller_leaves_the_current_to_the_experiment(tmp_path):
    """A valve current that a removal leaves unread by... nothing: an experiment drives it."""
    path = _file(tmp_path, '[rig]\nbase = "two_axis"\n[remove]\ncomponents = ["axis2.controller"]\n')
    circuit = build_circuit(load_rig(path))
    assert circuit.axes["axis2"].controller is None and circuit.axes["axis1"].controller


def test_a_removal_re_pointed_is_fine(tmp_path):
    """The check valve out, the manifold re-pointed onto the return hose's inlet."""
    path = _file(tmp_path, '[rig]\nbase = "ayalew2005_circuit"\n[remove]\n'
                           'components = ["return.check_valve"]\n[circuit."return.manifold"]\n'
                           'ports = { outlet_pressure = "return.section1_inlet_pressure" }\n')
    manifold = build_circuit(load_rig(path)).component("return.manifold")
    assert manifold.connections["outlet_pressure"] == "return.section1_inlet_pressure"
    assert manifold.connections["flow"] == "return.manifold_flow"


def test_base_cycles_and_missing_bases_are_one_line(tmp_path, capsys):
    a = _file(tmp_path, '[rig]\nbase = "b.toml"\n', "a.toml")
    _file(tmp_path, '[rig]\nbase = "a.toml"\n', "b.toml")
    _one_line(capsys, a, "rig.base: a cycle of bases:", "a.toml -> ", "b.toml -> ")
    _one_line(capsys, _file(tmp_path, '[rig]\nbase = "self.toml"\n', "self.toml"),
              "a cycle of bases")
    _one_line(capsys, _file(tmp_path, '[rig]\nbase = "nowhere/x.toml"\n'),
              "rig.base: rig file not found:", "x.toml")
    _one_line(capsys, _file(tmp_path, '[rig]\nbase = "two_axis.toml"\n'),
              "rig file not found", "the shipped rig of that name is 'two_axis', without .toml")
    _one_line(capsys, _file(tmp_path, '[remove]\ncomponents = ["pump"]\n'),
              "remove: there is nothing to remove from")
    with pytest.raises(RigError, match=r"^rig\.base: 'ayalew' is no shipped rig"):
        load_rig(_file(tmp_path, '[rig]\nbase = "ayalew"\n'))
