"""The compiled core (hydroline.compiled) against independent truth: the exact solution of a
damped oscillator, NumPy's dense linear algebra, the reference Python right-hand side, and the
reference SciPy integration of the full default rig."""
from dataclasses import dataclass

import numpy as np
import pytest

from hydroline import compiled
from hydroline.compiled.codegen import generate, lu_plan
from hydroline.network import Network, ops
from hydroline.network.component import Component, Port, State
from hydroline.rigs import load_rig
from hydroline.scenarios import build_scenario
from hydroline.simulation import integrate, solve_steady_state
from hydroline.system import build_network

pytestmark = pytest.mark.skipif(not compiled.available(), reason="no C compiler")


@dataclass(kw_only=True)
class Oscillator(Component):
    """x'' + 2 zeta w x' + w^2 x = w^2 u: mass-spring-damper driven by a position input."""

    omega: float = 2 * np.pi * 50.0
    zeta: float = 0.05
    inputs = {"u": Port("position")}
    outputs = {"x": Port("position")}
    feedthrough = False

    @property
    def states(self):
        return [State("x", "m", 1e-3), State("v", "m/s", 1e-1)]

    def outputs_of(self, t, x, u, p):
        return {"x": x["x"]}

    def derivatives(self, t, x, u, p):
        w, z = self.omega, self.zeta
        return {"x": x["v"], "v": w * w * (u["u"] - x["x"]) - 2 * z * w * x["v"]}


@dataclass(kw_only=True)
class Hold(Component):
    """A constant position source (runtime parameter ``value``)."""

    value: float = 1e-3
    outputs = {"u": Port("position")}
    feedthrough = False

    def outputs_of(self, t, x, u, p):
        return {"u": p["value"] * ops.sqrt(1.0 + 0.0 * t)}

    def runtime_parameters(self):
        return {"value": self.value}


def oscillator_network(omega=2 * np.pi * 50.0, zeta=0.05):
    return Network([Hold(name="source"), Oscillator(name="osc", omega=omega, zeta=zeta)])


def test_oscillator_step_matches_exact_solution():
    # Underdamped step response: x(t) = u (1 - e^{-z w t} (cos(wd t) + z/sqrt(1-z^2) sin(wd t)))
    w, z, u = 2 * np.pi * 50.0, 0.05, 1e-3
    net = oscillator_network(w, z)
    res = integrate(net, np.zeros(2), 0.2, dt_out=1e-4, solver="compiled", rtol=1e-8,
                    atol_scale=1e-9)
    t = res.t
    wd = w * np.sqrt(1 - z * z)
    exact = u * (1 - np.exp(-z * w * t) * (np.cos(wd * t) + z / np.sqrt(1 - z * z) * np.sin(wd * t)))
    assert res.metadata["solver"] == "compiled"
    # global error of a tolerance-controlled BDF: a few hundred rtol of the amplitude
    assert np.max(np.abs(res["osc.x"] - exact)) < 2e-5 * u
    assert res["x"] == pytest.approx(res["osc.x"])   # the signal equals the state


def test_runtime_parameters_and_constants_need_no_recompile():
    # two stiffnesses = same structure: one library, different constants (values that make
    # a product exactly 1 or 0 would let CasADi simplify the graph: another structure)
    a = compiled.native_model(oscillator_network(omega=123.4))
    b = compiled.native_model(oscillator_network(omega=234.5))
    assert a.generated.key == b.generated.key
    assert not np.array_equal(a.generated.constants, b.generated.constants)


def test_sparse_lu_solves_like_dense_numpy():
    rng = np.random.default_rng(1)
    n = 30
    dense_pattern = rng.random((n, n)) < 0.15
    rows, cols = np.nonzero(dense_pattern.T)   # column-major order (as CasADi stores it)
    rows, cols = cols, rows
    plan = lu_plan(n, rows.tolist(), cols.tolist())
    # fill-reducing order: a permutation, and never more slots than a dense matrix
    assert sorted(plan.order) == list(range(n)) and len(plan.slots) <= n * n
    # emulate the generated factor/solve in Python on random values
    J = np.zeros((n, n))
    J[rows, cols] = rng.normal(size=len(rows))
    g = 0.3
    W = np.eye(n) - g * J
    pos = {s: k for k, s in enumerate(plan.order)}
    a = {ij: 0.0 for ij in plan.slots}
    for r, c in zip(rows, cols):
        a[(pos[r], pos[c])] = -g * J[r, c]
    for k in range(n):
        a[(k, k)] += 1.0
    for k in range(n):
        a[(k, k)] = 1.0 / a[(k, k)]
        for i in plan.lower[k]:
            a[(i, k)] *= a[(k, k)]
            for j in plan.upper[k]:
                a[(i, j)] -= a[(i, k)] * a[(k, j)]
    b = rng.normal(size=n)
    v = b[plan.order].copy()
    for k in range(n):
        for i in plan.lower[k]:
            v[i] -= a[(i, k)] * v[k]
    for k in reversed(range(n)):
        v[k] = (v[k] - sum(a[(k, j)] * v[j] for j in plan.upper[k])) * a[(k, k)]
    x = np.empty(n)
    x[plan.order] = v
    assert x == pytest.approx(np.linalg.solve(W, b), rel=1e-9, abs=1e-12)


@pytest.fixture(scope="module")
def default_rig_network():
    rig = load_rig(None)
    sc = build_scenario(rig, "open-loop-step")
    net = build_network(rig, sc.commands, sc.position_guess)
    return net, solve_steady_state(net)


def test_compiled_rhs_equals_reference_python_rhs(default_rig_network):
    net, ss = default_rig_network
    solver = compiled.native_model(net).solver(ss.p)
    rng = np.random.default_rng(2)
    for t in (0.0, 0.02):
        x = ss.x + 0.05 * rng.normal(size=len(ss.x)) * net.state_scales
        ref = net.rhs(t, x, ss.p)
        assert solver.rhs(t, x) == pytest.approx(ref, rel=1e-9, abs=1e-12 * np.max(np.abs(ref)))


def test_compiled_matches_reference_scipy_on_the_default_rig(default_rig_network):
    # 30 ms around the 50 mA step at 10 ms: both within their tolerance of the truth, so they
    # agree to a small multiple of rtol relative to each signal's excursion
    net, ss = default_rig_network
    rtol = 1e-6
    kw = dict(dt_out=1e-4, p=ss.p, rtol=rtol, atol_scale=1e-7)
    ref = integrate(net, ss.x, 0.03, solver="scipy", **kw)
    res = integrate(net, ss.x, 0.03, solver="compiled", **kw)
    assert res.metadata["solver"] == "compiled"
    for k in ("supply_port_pressure", "return_port_pressure", "bottom_chamber_pressure",
              "piston_velocity", "actuator.position"):
        span = np.ptp(ref[k])
        assert np.max(np.abs(res[k] - ref[k])) < 300 * rtol * span, k


def test_streaming_writes_every_row_and_keeps_statistics(tmp_path):
    import pandas as pd

    net = oscillator_network()
    full = integrate(net, np.zeros(2), 0.05, dt_out=1e-4, solver="compiled")
    path = tmp_path / "run.csv"
    res = integrate(net, np.zeros(2), 0.05, dt_out=1e-4, solver="compiled", stream_to=path,
                    chunk_rows=64)
    back = pd.read_csv(path, index_col="time")
    assert len(back) == len(full.data) == res.metadata["stream_rows"]
    assert back["osc.x"].to_numpy() == pytest.approx(full["osc.x"], rel=1e-8, abs=1e-15)
    stats = res.metadata["stream_stats"]
    assert stats.loc["osc.x", "max"] == pytest.approx(full["osc.x"].max())
    assert stats.loc["osc.x", "mean"] == pytest.approx(full["osc.x"].mean())
    assert len(res.data) == 1 and res.data.index[0] == pytest.approx(0.05)


def test_without_compiler_auto_falls_back_to_cvodes(monkeypatch, tmp_path):
    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiled, "_compiler", lambda: None)
    net = oscillator_network(omega=123.0)   # a fresh network object: nothing built yet
    res = integrate(net, np.zeros(2), 0.01, solver="auto")
    assert res.metadata["solver"] == "cvodes"
    assert any("compiled core unavailable" in w for w in res.warnings)
    with pytest.raises(compiled.CompilerUnavailable):
        integrate(oscillator_network(omega=124.0), np.zeros(2), 0.01, solver="compiled")


def test_generated_code_has_no_numbers_of_the_model():
    # the structure-only source: no physical value (here 2*pi*50) written into it
    gen = generate(oscillator_network(omega=314.159).compile())
    assert "314.159" not in gen.source
    assert 314.159**2 in gen.constants or 314.159 in gen.constants


# ---- lumped segmented line (benchmarks/bench_lines) -------------------------------------
def _lumped(n):
    from hydroline.fluid import MINERAL_OIL
    from hydroline.lines import Line
    from hydroline.lines.lumped import LumpedLine

    line = Line(3.048, 0.0127, MINERAL_OIL)
    return line, LumpedLine(line, n)


@pytest.mark.parametrize("n", [1, 4, 25])
def test_lumped_line_dc_gain_is_laminar_steady_state(n):
    # (M12): P_d = P_u - R Q_d, Q_u = Q_d, for any number of segments
    line, m = _lumped(n)
    H0 = m.transfer(np.array([1e-9j]))[0].real
    assert H0 == pytest.approx(np.array([[1.0, -line.resistance], [0.0, 1.0]]), rel=1e-6, abs=1e-9)


def test_lumped_line_first_resonance_converges_to_quarter_wave():
    # lossless ladder, short at the source, open (blocked) end: hand-derived
    # f_1 = (4N/pi) sin(pi/(2(2N+1))) c/(4L) -> c/(4L), error O(1/N)
    errors = []
    for n in (2, 8, 32, 128):
        line, m = _lumped(n)
        A = m.A.copy()
        A[np.arange(0, 2 * n, 2), np.arange(0, 2 * n, 2)] = 0.0     # drop the friction R
        f1 = np.min(np.abs(np.linalg.eigvals(A).imag)) / (2 * np.pi)
        quarter = line.wave_speed / (4 * line.length)
        assert f1 == pytest.approx(4 * n / np.pi * np.sin(np.pi / (2 * (2 * n + 1))) * quarter,
                                   rel=1e-9)
        errors.append(abs(f1 / quarter - 1))
    assert errors[-1] < 0.01
    assert all(b < a / 3 for a, b in zip(errors, errors[1:]))   # ~1/N: x4 segments, /4 error
