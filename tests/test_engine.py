"""The engine apart (issue 12): its rooms import nothing above them, lost flows are warned of,
the connection table names every signal's producer and readers, and the three solver
backends give the same run (the SciPy path is the per-component Python reference)."""
import ast
import re
import pathlib
import warnings

import numpy as np
import pytest

from hydroline import components as comp
from hydroline.engine import Network, integrate, solve_steady_state
from hydroline.engine.network import UnusedSignalWarning

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "hydroline"


def _imports(path):
    """Modules a file imports, as (level, module) pairs (level 0: absolute)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            out.append((node.level, node.module or ""))
        elif isinstance(node, ast.Import):
            out += [(0, a.name) for a in node.names]
    return out


def _names(path, module, level):
    """Names imported by ``from ..{module} import names`` statements of a file."""
    return [a.name for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.ImportFrom) and node.level == level and (node.module or "") == module
            for a in node.names]


@pytest.mark.parametrize("room,allowed", [
    ("engine", {"compiled", "blas"}),   # the compiled core is a backend below it; blas a
                                        # leaf (one BLAS thread for the small solves)
    ("traces", set()),             # pure trace functions
])
def test_room_imports_nothing_above_it(room, allowed):
    for path in sorted((PACKAGE / room).glob("*.py")):
        for level, module in _imports(path):
            if level == 1:         # its own room
                continue
            if level >= 2:         # ..x: a sibling room of the package
                top = module.split(".")[0] if module else None
                names = {top} if top else {a for a in _names(path, module, level)}
                assert names <= allowed, f"{path.name} imports ..{module} {names - allowed}"
            else:
                assert not module.startswith("hydroline"), f"{path.name} imports {module}"


def test_no_private_name_imported_across_modules():
    """No module imports another's private (``_x``) name; dunder names (``__version__``) are
    public by convention."""
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module != "__future__":
                private = [a.name for a in node.names
                           if a.name.startswith("_") and not a.name.startswith("__")]
                assert not private, f"{path.relative_to(PACKAGE)} imports {private} from {node.module}"


def _vessel(outlet_read: bool):
    """Source -> orifice -> vessel (-> orifice -> tank when ``outlet_read``, else the second
    orifice's flow is read by nobody: fluid lost from the vessel)."""
    src = comp.PressureSource(name="pump", pressure=10e6, connections={"pressure": "p_pump"})
    tank = comp.PressureSource(name="tank", pressure=1e6, connections={"pressure": "p_tank"})
    r_in = comp.LinearResistance(name="r_in", compute="flow", resistance=1e10,
                                 connections={"inlet_pressure": "p_pump", "outlet_pressure": "p_v",
                                              "flow": "q_in"})
    r_out = comp.LinearResistance(name="r_out", compute="flow", resistance=1e10,
                                  connections={"inlet_pressure": "p_v", "outlet_pressure": "p_tank",
                                               "flow": "q_out"})
    terms = {"inflow": 1, "outflow": -1} if outlet_read else {"inflow": 1}
    wires = {"inflow": "q_in", "outflow": "q_out", "pressure": "p_v"}
    vessel = comp.HydraulicVolume(name="vessel", volume=1e-4, bulk_modulus=1.5e9, terms=terms,
                                  nominal_pressure=5e6,
                                  connections={k: v for k, v in wires.items() if k in terms or k == "pressure"})
    return [src, tank, r_in, r_out, vessel]


def test_lost_flow_is_warned_naming_signal_and_port():
    with pytest.warns(UnusedSignalWarning, match=r"'q_out' \(r_out\.flow\)"):
        net = Network(_vessel(outlet_read=False))
    assert "q_out" in net.unused_signals()


def test_flow_into_pressure_boundaries_is_not_lost():
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnusedSignalWarning)
        net = Network(_vessel(outlet_read=True))
    # the vessel pressure settles where the two equal resistances split the drop (hand value)
    ss = solve_steady_state(net)
    assert net.signals_at(0.0, ss.x)["p_v"] == pytest.approx(5.5e6, rel=1e-9)


def test_connection_table_one_producer_and_every_reader():
    net = Network(_vessel(outlet_read=True))
    rows = {r["signal"]: r for r in net.connection_table()}
    assert rows["p_v"]["producer"] == "vessel.pressure"
    assert sorted(rows["p_v"]["consumers"]) == ["r_in.outlet_pressure", "r_out.inlet_pressure"]
    assert rows["q_out"] == {"signal": "q_out", "producer": "r_out.flow",
                             "consumers": ["vessel.outflow"], "quantity": "flow", "unit": "m^3/s"}


@pytest.mark.parametrize("solver", ["compiled", "cvodes"])
def test_backends_agree_with_the_exact_vessel_charge(solver):
    """Vessel charged through R from a pressure step: p_v(t) relaxes exponentially with
    tau = R C / 2 (two equal resistances, C = V / beta), exact solution by hand."""
    from hydroline import compiled

    if solver == "compiled" and not compiled.available():
        pytest.skip("no C compiler")
    parts = _vessel(outlet_read=True)
    net = Network(parts)
    x0 = np.array([1e6])                       # vessel at tank pressure at t = 0
    res = integrate(net, x0, 0.05, dt_out=1e-3, solver=solver, rtol=1e-9, atol_scale=1e-10)
    tau = 1e10 * (1e-4 / 1.5e9) / 2
    exact = 5.5e6 + (1e6 - 5.5e6) * np.exp(-res.t / tau)
    assert np.max(np.abs(res["p_v"] - exact)) < 1e-6 * 4.5e6
    ref = integrate(net, x0, 0.05, dt_out=1e-3, solver="scipy", rtol=1e-9, atol_scale=1e-10)
    assert np.max(np.abs(res["p_v"] - ref["p_v"])) < 1e-6 * 4.5e6


def test_the_cvodes_path_cuts_the_network_open_where_the_compiled_core_does():
    """The CVODES path integrates the default rig (hose-end cavities on) cut open at its
    interface signals (engine.backends.CUT_OPEN): its DAE's Jacobian in (z, v) holds fewer
    nonzeros than the ODE's d(dz/dt)/dz (where every path through a connection, and a hose
    end's cavity lift read by every state of its section, fills a block), and the cut values
    and rates it starts a segment from are the components' own Python equations'
    (Network.evaluate, Network.rhs) at a moving state, within the rounding bound."""
    import casadi as ca
    from rounding_bound import rounding_bound

    from hydroline.engine.backends import CvodesBackend
    from hydroline.rigs import load_rig
    from hydroline.scenarios import build_scenario
    from hydroline.system import build_network

    rig = load_rig()
    sc = build_scenario(rig, "open-loop-step")
    net = build_network(rig, sc.commands, sc.position_guess)
    backend = CvodesBackend(net, 1e-6, 1e-7)
    dae = backend.dae
    assert backend.consistent is not None and dae["z"].numel() > 0
    model = net.compile()
    ode_nnz = ca.jacobian(model.dx, model.x).nnz()
    both = ca.vertcat(dae["x"], dae["z"])
    assert ca.jacobian(ca.vertcat(dae["ode"], dae["alg"]), both).nnz() < 0.5 * ode_nnz
    ss = solve_steady_state(net)
    x = ss.x * (1.0 + 1e-3)
    x[net.state_names.index("actuator.velocity")] = 0.05
    v, rates = backend.consistent(0.02, x / backend.scales, ss.p)
    np.testing.assert_array_less(np.abs(np.asarray(rates) * backend.scales - net.rhs(0.02, x, ss.p)),
                                 rounding_bound(net, 0.02, x, ss.p) + 1e-300)
    residual = ca.Function("alg", [dae["t"], dae["x"], dae["z"], dae["p"]], [dae["alg"]])
    assert np.abs(np.asarray(residual(0.02, x / backend.scales, v, ss.p))).max() < 1e-12


def test_cli_says_lost_flow_once_in_one_line(tmp_path, capsys):
    """two_axis with axis 2's supply hose left off the manifold node: the CLI names the flow
    and the port in one warning line (and still runs: the circuit is legal, only leaky)."""
    from hydroline.cli import main
    from hydroline.rigs import shipped_rig

    text = (PACKAGE / "rigs" / shipped_rig("two_axis")).read_text()
    node = 'terms = { axis1 = 1, axis2 = 1, accumulator = 1 }\nports = { axis1 = "axis1.supply_hose_inflow", axis2 = "axis2.supply_hose_inflow",'
    assert node in text
    text = text.replace(node, 'terms = { axis1 = 1, accumulator = 1 }\nports = { axis1 = "axis1.supply_hose_inflow",')
    rig = tmp_path / "leaky.toml"
    rig.write_text(text)
    assert main(["simulate", str(rig), "--json", "--t-end", "30 ms"]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(err) == 1
    assert "'axis2.supply_hose_inflow' (axis2.supply_hose.upstream_flow)" in err[0]


# ---- parameters declared once (issue 12 item 2) ------------------------------------------------
def test_template_table_repeats_no_component_declaration():
    """A template-rig parameter that a component declares takes unit, description and
    plausible range from that declaration: the table holds no second copy."""
    from hydroline.rigs.parameters import PARAMETERS, Declared

    from hydroline.rigs import declarations
    for path, entry in PARAMETERS.entries.items():
        section, key = path.rsplit(".", 1)
        decl = declarations(section).get(key)
        if decl is not None:
            assert isinstance(entry, Declared), f"{path}: unit/range repeated in the rig table"
            assert PARAMETERS[path].unit == decl.unit.replace("list:", "")
            assert (PARAMETERS[path].low, PARAMETERS[path].high) == decl.plausible


def test_circuit_value_outside_plausible_range_refused_and_overridable(tmp_path):
    from hydroline.rigs import load_rig, shipped_rig
    from hydroline.system import build_circuit

    text = (PACKAGE / "rigs" / shipped_rig("two_axis")).read_text()
    bad = text + '\n[circuit."axis1.actuator"]\nstroke = "100 m"   # a slip of unit\n'   # axis 1's
    rig_file = tmp_path / "slip.toml"
    rig_file.write_text(bad)
    with pytest.raises(ValueError, match=r"^circuit\.axis1\.actuator\.stroke: '100 m' is outside "
                                         r"its plausible range, within 0\.001 \.\.\. 10 \[m\].*"
                                         r"allow_implausible"):
        build_circuit(load_rig(str(rig_file)))
    allowed = bad.replace("[rig]\n", '[rig]\nallow_implausible = ["circuit.axis1.actuator.stroke"]\n', 1)
    rig_file.write_text(allowed)
    circuit = build_circuit(load_rig(str(rig_file)))
    assert circuit.component("axis1.actuator").stroke == pytest.approx(100.0)


def test_engine_page_example_runs():
    """docs/engine.md's worked example (a component written once, wired, solved, integrated)
    runs, and its hand values hold (two equal orifices split the drop evenly)."""
    text = (PACKAGE.parent / "docs" / "engine.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) == 1
    exec(compile(blocks[0], "docs/engine.md", "exec"), {"__name__": "engine_page"})


@pytest.mark.parametrize("chunk_rows", [20000, 7])
def test_rows_written_in_place_follow_the_exact_charge_across_an_off_grid_step(chunk_rows):
    """The compiled core writes its rows straight into the run's table (no copy, no stacking
    of parts): a pump step at t_s = 12.34 ms, between two 1 ms output times, ends a segment
    off the grid (its extra row is overwritten by the next segment's first). Exact by hand:
    p_v = 5.5 MPa until t_s, then 7.5 + (5.5 - 7.5) exp(-(t - t_s) / tau) MPa."""
    from hydroline import compiled

    if not compiled.available():
        pytest.skip("no C compiler")
    parts = _vessel(outlet_read=True)
    parts[0] = comp.PressureSource(name="pump", pressure=10e6, step_time=12.34e-3, step_to=14e6,
                                   connections={"pressure": "p_pump"})
    net = Network(parts)
    res = integrate(net, np.array([5.5e6]), 0.05, dt_out=1e-3, solver="compiled", rtol=1e-9,
                    atol_scale=1e-10, chunk_rows=chunk_rows)
    assert res.t.shape == (51,) and np.array_equal(res.t, np.arange(51) * 1e-3)
    tau = 1e10 * (1e-4 / 1.5e9) / 2
    ts = 12.34e-3
    exact = np.where(res.t < ts, 5.5e6, 7.5e6 - 2e6 * np.exp(-np.clip(res.t - ts, 0, None) / tau))
    assert np.max(np.abs(res["p_v"] - exact)) < 1e-6 * 2e6


def test_compiled_advance_refuses_an_output_array_of_another_shape():
    from hydroline import compiled

    if not compiled.available():
        pytest.skip("no C compiler")
    net = Network(_vessel(outlet_read=True))
    solver = compiled.native_model(net).solver()
    solver.start(0.0, np.array([1e6]), 0.01)
    with pytest.raises(ValueError, match="out must be"):
        solver.advance(np.array([0.005, 0.01]), table=True, out=np.empty((3, 2)))
    rows = np.full((2, len(net.signal_names) + 1), np.nan)
    table = solver.advance(np.array([0.005, 0.01]), table=True, out=rows)
    assert table is rows and np.all(np.isfinite(rows))
