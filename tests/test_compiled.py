"""The compiled core (hydroline.compiled) against independent truth: the exact solution of a
damped oscillator, NumPy's dense linear algebra, the reference Python right-hand side, and the
reference SciPy integration of the full default rig."""
import hashlib
import os
import subprocess
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from hydroline import compiled
from hydroline.compiled.codegen import generate, lu_plan
from hydroline.engine import Network, ops
from hydroline.engine.component import Component, Port, State
from hydroline.rigs import load_rig
from hydroline.scenarios import build_scenario
from hydroline.engine import integrate, solve_steady_state
from hydroline.system import build_network
from rounding_bound import rounding_bound

#: Tests that build a library; the fallback, code-generation and lumped-line tests need no compiler.
needs_cc = pytest.mark.skipif(not compiled.available(), reason="no C compiler")


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


@dataclass(kw_only=True)
class StepSource(Component):
    """A position that steps from ``initial`` to ``final`` at ``time`` (``t >= time``, as
    :class:`hydroline.components.StepCommand`), declared as a breakpoint."""

    initial: float = 1e-3
    final: float = 2e-3
    time: float = 0.01
    outputs = {"u": Port("position")}
    feedthrough = False

    def outputs_of(self, t, x, u, p):
        return {"u": ops.if_else(t >= self.time, self.final, self.initial)}

    def breakpoints(self, t_end):
        return [self.time] if 0 < self.time < t_end else []


def oscillator_network(omega=2 * np.pi * 50.0, zeta=0.05):
    return Network([Hold(name="source"), Oscillator(name="osc", omega=omega, zeta=zeta)])


@needs_cc
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


@needs_cc
@pytest.mark.parametrize("solver", ["compiled", "radau"])
def test_step_control_keeps_the_error_on_a_ringing_mode_with_few_rejected_steps(solver):
    # a hose-like mode (300 Hz, damping ratio 1 %) ringing for 75 periods after a step, at
    # simulate()'s tolerances and two decades tighter: the error against the exact response
    # stays within a few hundred rtol of the step and falls with the tolerance; the step-size
    # choice (safety 0.8, bdf.c) rejects few steps (SciPy's 0.9 rejected 7 % here); Radau IIA
    # (order 5, bdf.c's second method) the same, in fewer steps
    w, z, u = 2 * np.pi * 300.0, 0.01, 1e-3
    net = oscillator_network(w, z)
    wd = w * np.sqrt(1 - z * z)
    err = {}
    for rtol in (1e-6, 1e-8):
        res = integrate(net, np.zeros(2), 0.25, dt_out=1e-4, solver=solver, rtol=rtol,
                        atol_scale=rtol / 10)
        assert res.metadata["solver"] == solver
        t = res.t
        exact = u * (1 - np.exp(-z * w * t) * (np.cos(wd * t)
                                               + z / np.sqrt(1 - z * z) * np.sin(wd * t)))
        err[rtol] = np.max(np.abs(res["osc.x"] - exact)) / u
        assert res.stats["nrejected"] < 0.05 * res.stats["nsteps"]
    assert err[1e-6] < 300 * 1e-6
    assert err[1e-8] < 0.05 * err[1e-6]



@dataclass(kw_only=True)
class ModalBlock(Component):
    """Lightly damped modes driven by one input, as a hose's modal states (M10): per mode
    q'' + 2 zeta w q' + w^2 q = w^2 g u; output the sum of the q."""

    omegas: tuple = ()
    zetas: tuple = ()
    gains: tuple = ()
    inputs = {"u": Port("position")}
    outputs = {"y": Port("position")}
    feedthrough = False

    @property
    def states(self):
        return [s for i in range(len(self.omegas))
                for s in (State(f"q{i}", "m", 1e-3), State(f"r{i}", "m/s", 1e-3 * self.omegas[i]))]

    def outputs_of(self, t, x, u, p):
        return {"y": sum(x[f"q{i}"] for i in range(len(self.omegas)))}

    def derivatives(self, t, x, u, p):
        out = {}
        for i, (w, z, g) in enumerate(zip(self.omegas, self.zetas, self.gains)):
            out[f"q{i}"] = x[f"r{i}"]
            out[f"r{i}"] = w * w * (g * u["u"] - x[f"q{i}"]) - 2 * z * w * x[f"r{i}"]
        return out


def modal_block_system(omegas, zetas, gains, u):
    """A held input u [-] into a ModalBlock, and its exact x' = A x + b: each mode's
    oscillator q'' = -w^2 q - 2 zeta w q' + w^2 g u."""
    net = Network([Hold(name="source", value=u),
                   ModalBlock(name="m", omegas=omegas, zetas=zetas, gains=gains)])
    n = 2 * len(omegas)
    A, b = np.zeros((n, n)), np.zeros(n)
    for i, (w, z, g) in enumerate(zip(omegas, zetas, gains)):
        A[2 * i, 2 * i + 1] = 1.0
        A[2 * i + 1, 2 * i], A[2 * i + 1, 2 * i + 1] = -w * w, -2 * z * w
        b[2 * i + 1] = w * w * g * u
    return net, A, b


@needs_cc
@pytest.mark.parametrize("solver", ["compiled", "radau"])
def test_stiff_modal_block_matches_the_matrix_exponential(solver):
    # modes from 40 Hz to 16 kHz (damping 1 % to 30 %): eigenvalues from -2.5 to -3e4 1/s in
    # real part, the stiffness of a hose's modal line (M10) next to its slow first mode; the
    # exact solution of x' = A x + b u (u constant) is x(t) = e^{At} x0 + A^-1 (e^{At} - I) b u
    from scipy.linalg import expm

    omegas = tuple(2 * np.pi * f for f in (40.0, 400.0, 2500.0, 16000.0))
    zetas, gains, u = (0.01, 0.02, 0.05, 0.3), (1.0, -0.5, 0.25, 0.1), 1e-3
    net, A, b = modal_block_system(omegas, zetas, gains, u)
    n = len(b)
    x0 = np.zeros(n)
    x0[0], x0[3] = 2e-3, -1.0                # start away from rest in the slow and a fast mode
    res = integrate(net, x0, 0.05, dt_out=2e-4, solver=solver, rtol=1e-8, atol_scale=1e-9)
    assert res.metadata["solver"] == solver
    names = net.state_names
    worst = 0.0
    for k in (10, 50, 125, 250):            # 2, 10, 25, 50 ms
        E = expm(A * res.t[k])
        exact = E @ x0 + np.linalg.solve(A, (E - np.eye(n)) @ b)
        got = np.array([res[name][k] for name in names])
        for i in range(len(omegas)):       # error of each mode's position, of its swing
            q = 2 * i
            swing = max(abs(x0[q]), abs(gains[i] * u), 1e-3 * abs(x0[q + 1]) / omegas[i])
            worst = max(worst, abs(got[q] - exact[q]) / swing)
    # a tolerance-controlled integrator's global error: some hundred rtol of the swing
    assert worst < 1e-5

@needs_cc
def test_auto_takes_radau_only_where_the_modes_cap_the_ndf_orders():
    # solver="auto" (the default): Radau IIA at 100x the tolerances where the NDF order 3 is
    # unstable above NativeSolver.RADAU_BELOW on the model's modes, the BDF elsewhere. The
    # limits from the exact eigenvalues -zeta w +- i w sqrt(1 - zeta^2) of each block: a
    # 10 kHz mode at 2 % damping holds order 3 to a few us (Radau), a 300 Hz one at 1 % to
    # hundreds (BDF); Radau's answer meets the matrix exponential's within some hundred of its
    # own (100x) tolerance
    from scipy.linalg import expm
    from hydroline.compiled.stability import order_step_limits

    below = compiled.NativeSolver.RADAU_BELOW
    factor = compiled.NativeSolver.RADAU_TOLERANCE_FACTOR
    slow = oscillator_network(2 * np.pi * 300.0, 0.01)
    w_s = 2 * np.pi * 300.0
    assert order_step_limits(np.array([complex(-0.01 * w_s, w_s * np.sqrt(1 - 1e-4))]))[2] > below
    res = integrate(slow, np.zeros(2), 0.02, dt_out=1e-4, solver="auto", rtol=1e-6,
                    atol_scale=1e-7)
    assert res.metadata["solver"] == "compiled"

    omegas, zetas, gains, u = (2 * np.pi * 40.0, 2 * np.pi * 1e4), (0.01, 0.02), (1.0, 0.5), 1e-3
    w, z = omegas[1], zetas[1]
    assert order_step_limits(np.array([complex(-z * w, w * np.sqrt(1 - z * z))]))[2] < below
    net, A, b = modal_block_system(omegas, zetas, gains, u)
    n = len(b)
    x0 = np.zeros(n)
    x0[0] = 2e-3
    rtol = 1e-8
    res = integrate(net, x0, 0.02, dt_out=2e-4, solver="auto", rtol=rtol, atol_scale=rtol / 10)
    assert res.metadata["solver"] == "radau"
    assert res.metadata["rtol"] == rtol          # the user's; Radau steps at factor x it
    k = 50                                       # 10 ms
    E = expm(A * res.t[k])
    exact = E @ x0 + np.linalg.solve(A, (E - np.eye(n)) @ b)
    got = np.array([res[name][k] for name in net.state_names])
    assert abs(got[0] - exact[0]) / 2e-3 < 300 * factor * rtol


@needs_cc
@pytest.mark.parametrize("solver", ["compiled", "radau"])
def test_a_segment_at_rest_ends_on_its_breakpoint_in_few_steps(solver):
    # at rest up to a step at 10 ms: the exact solution is constant there, so the steps grow
    # by the largest factor (10) from the first one (~1 us) and the segment takes a handful;
    # f evaluated at the breakpoint itself saw the stepped input (t >= time) and every try to
    # land there failed: 40-50 steps shrinking toward it. After it, the step response.
    u0, u1, w, z = 1e-3, 2e-3, 2 * np.pi * 50.0, 0.05
    net = Network([StepSource(name="source", initial=u0, final=u1),
                   Oscillator(name="osc", omega=w, zeta=z)])
    rest = integrate(net, np.array([u0, 0.0]), 0.01, dt_out=1e-3, solver=solver, rtol=1e-6,
                     atol_scale=1e-7)
    assert rest.stats["nsteps"] <= 15
    assert np.allclose(rest["osc.x"], u0, rtol=0, atol=1e-12)
    res = integrate(net, np.array([u0, 0.0]), 0.05, dt_out=1e-4, solver=solver, rtol=1e-8,
                    atol_scale=1e-9)
    t = res.t - 0.01
    wd = w * np.sqrt(1 - z * z)
    exact = np.where(t < 0, u0, u0 + (u1 - u0) * (1 - np.exp(-z * w * t) * (
        np.cos(wd * t) + z / np.sqrt(1 - z * z) * np.sin(wd * t))))
    assert np.max(np.abs(res["osc.x"] - exact)) < 2e-5 * (u1 - u0)


@needs_cc
def test_runtime_parameters_and_constants_need_no_recompile():
    # two stiffnesses = same structure: one library, different constants (values that make
    # a product exactly 1 or 0 would let CasADi simplify the graph: another structure)
    a = compiled.native_model(oscillator_network(omega=123.4))
    b = compiled.native_model(oscillator_network(omega=234.5))
    assert a.generated.key == b.generated.key
    assert not np.array_equal(a.generated.constants, b.generated.constants)


@needs_cc
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
def built_networks():
    """The default rig's network per build kind, made once per module."""
    return {}


@pytest.fixture(params=["native", "portable"])
def default_rig_network(request, monkeypatch, built_networks):
    """The default rig's network and rest state, its library built for this CPU
    (``-march=native``, fused multiply-adds where the CPU has them) or portably (no
    CPU-specific flags): the suite covers both, whatever machine it runs on."""
    if request.param == "portable":
        monkeypatch.setenv(compiled.PORTABLE_ENV, "1")
    if request.param not in built_networks:
        rig = load_rig(None)
        sc = build_scenario(rig, "open-loop-step")
        net = build_network(rig, sc.commands, sc.position_guess)
        built_networks[request.param] = (net, solve_steady_state(net))
    return built_networks[request.param]


def test_a_portable_build_has_no_cpu_specific_flags(monkeypatch):
    monkeypatch.setenv(compiled.PORTABLE_ENV, "1")
    assert compiled.native_flags() == []
    monkeypatch.setenv(compiled.PORTABLE_ENV, "0")
    assert compiled.native_flags() == compiled.NATIVE_FLAGS


@needs_cc
def test_compiled_rhs_equals_reference_python_rhs(default_rig_network):
    """The C library's derivatives against the components' own Python equations, within the
    rounding bound of the evaluation (tests/rounding_bound.py): fused multiply-adds and
    another operation order may move a near-cancelling dp/dt far beyond 1e-9 of itself, never
    beyond a few roundings of its terms."""
    net, ss = default_rig_network
    solver = compiled.native_model(net).solver(ss.p)
    rng = np.random.default_rng(2)
    for t in (0.0, 0.02):
        x = ss.x + 0.05 * rng.normal(size=len(ss.x)) * net.state_scales
        ref = net.rhs(t, x, ss.p)
        assert np.all(np.abs(solver.rhs(t, x) - ref) <= rounding_bound(net, t, x, ss.p))


@needs_cc
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


@needs_cc
def test_streaming_writes_every_row_and_keeps_statistics(tmp_path):
    import pandas as pd

    net = oscillator_network()
    full = integrate(net, np.zeros(2), 0.05, dt_out=1e-4, solver="compiled")
    path = tmp_path / "run.csv"
    res = integrate(net, np.zeros(2), 0.05, dt_out=1e-4, solver="compiled", stream_to=path,
                    chunk_rows=64)
    back = pd.read_csv(path, index_col="time [s]")
    assert len(back) == len(full.data) == res.metadata["stream_rows"]
    assert back["osc.x [m]"].to_numpy() == pytest.approx(full["osc.x"], rel=1e-8, abs=1e-15)
    stats = res.metadata["stream_stats"]
    assert stats.loc["osc.x", "max"] == pytest.approx(full["osc.x"].max())
    assert stats.loc["osc.x", "mean"] == pytest.approx(full["osc.x"].mean())
    assert len(res.data) == 1 and res.data.index[0] == pytest.approx(0.05)


def test_without_compiler_auto_falls_back_to_cvodes(monkeypatch, tmp_path):
    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiled.toolchain, "compiler", lambda: None)
    net = oscillator_network(omega=123.0)   # a fresh network object: nothing built yet
    with pytest.warns(RuntimeWarning, match="compiled core unavailable"):
        res = integrate(net, np.zeros(2), 0.01, solver="auto")
    assert res.metadata["solver"] == "cvodes"
    assert "compiled core unavailable" in res.metadata["solver_note"]
    assert not res.warnings     # validity warnings only: the fallback is no physics warning
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


# ---- robustness of the cache and the C integrator ---------------------------------------
def _oscillator_peak(zeta=0.05):
    """Peak of the 1 mm step response of the oscillator: 1 + exp(-pi z / sqrt(1 - z^2)) mm."""
    return 1e-3 * (1 + np.exp(-np.pi * zeta / np.sqrt(1 - zeta**2)))


def _fresh_process_cache(monkeypatch):
    """Forget the libraries and models this process has loaded, as a new process would."""
    monkeypatch.setattr(compiled.toolchain, "_LIBS", {})
    monkeypatch.setattr(compiled.records, "_MODELS", {})


@needs_cc
@pytest.mark.parametrize("damage", ["garbage", "random-bytes", "other-library", "other-record",
                                    "damaged-record", "unrecorded", "record-without-key"])
def test_damaged_cached_library_is_rebuilt(monkeypatch, tmp_path, damage):
    """A cached library that is not the file its build recorded (size, SHA-256 and the key it
    was built for) is rebuilt before anything loads it, with one warning naming it: text,
    random bytes, another model's valid library, another library's record, a damaged record.
    A library without a record, or with a record of the format before keys (size and hash
    only), is rebuilt quietly (a cache of an older hydroline)."""
    from hydroline.cache import CacheWarning

    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    net = oscillator_network(omega=211.0)
    path = compiled.native_model(net).library_path
    record = path.with_suffix(".sha256")
    size, digest, key = record.read_text().split()
    assert size == str(path.stat().st_size) and key.startswith(path.stem[3:]) and len(key) == 64
    if damage == "garbage":
        _replace(path, b"not a shared library")   # e.g. a build killed mid-write elsewhere
    elif damage == "random-bytes":
        _replace(path, np.random.default_rng(0).bytes(path.stat().st_size))
    elif damage == "other-library":
        _replace(path, _other_library())
    elif damage == "other-record":                 # another library's file and its record
        other = _other_library_path()
        _replace(path, other.read_bytes())
        record.write_text(other.with_suffix(".sha256").read_text())
    elif damage == "damaged-record":
        record.write_text(f"{size}x {digest} {key}")
    elif damage == "unrecorded":
        record.unlink()
    else:
        record.write_text(f"{size} {digest}\n")
    _fresh_process_cache(monkeypatch)
    warned = damage not in ("unrecorded", "record-without-key")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = integrate(oscillator_network(omega=211.0), np.zeros(2), 0.05, solver="compiled")
    said = [str(w.message) for w in caught if issubclass(w.category, CacheWarning)]
    assert len(said) == int(warned) and all(str(path) in text for text in said), said
    assert res.metadata["solver"] == "compiled"
    assert res["osc.x"].max() == pytest.approx(_oscillator_peak(), rel=2e-3)
    assert compiled.native_model(oscillator_network(omega=211.0)).library_path == path
    data = path.read_bytes()
    assert record.read_text().split() == [str(len(data)), hashlib.sha256(data).hexdigest(), key]


def _replace(path, data):
    """Put other bytes at ``path`` as a new file: this process has the old one mapped, and
    rewriting a mapped library in place would crash the test itself."""
    tmp = path.with_suffix(".damaged")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def _other_library_path() -> Path:
    """A valid library of another model structure (two oscillators in a row)."""
    net = Network([Hold(name="source"), Oscillator(name="osc"),
                   Oscillator(name="osc2", connections={"u": "x", "x": "x2"})])
    return compiled.native_model(net).library_path


def _other_library() -> bytes:
    """The bytes of a valid library of another model structure."""
    return _other_library_path().read_bytes()


@needs_cc
def test_truncated_cached_library_does_not_crash_a_new_process(tmp_path):
    """Half a library (a disk filled mid-copy) mapped by the loader kills the process with
    SIGBUS; the recorded size and hash keep it from being loaded: the run rebuilds it."""
    code = (
        "import sys, numpy as np\n"
        f"sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
        "from test_compiled import oscillator_network, _oscillator_peak\n"
        "from hydroline import compiled\n"
        "from hydroline.engine import integrate\n"
        "res = integrate(oscillator_network(omega=215.0), np.zeros(2), 0.05, solver='compiled')\n"
        "assert abs(res['osc.x'].max() / _oscillator_peak() - 1) < 2e-3\n"
        "print(compiled.native_model(oscillator_network(omega=215.0)).library_path)\n")
    env = dict(os.environ, HYDROLINE_CACHE_DIR=str(tmp_path))
    first = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    path = Path(first.stdout.strip())
    data = path.read_bytes()
    _replace(path, data[:len(data) // 2])
    second = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert second.returncode == 0, second.stderr   # not -7 (SIGBUS)
    rebuilt = path.read_bytes()
    assert path.with_suffix(".sha256").read_text().split()[:2] == [
        str(len(rebuilt)), hashlib.sha256(rebuilt).hexdigest()]
    assert "CacheWarning" in second.stderr and str(path) in second.stderr


@needs_cc
def test_known_model_skips_code_generation(monkeypatch, tmp_path):
    """A model seen before (same graph and numbers) loads its library without writing C: the
    record in the cache directory holds its constants; the result is the same."""
    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    net = oscillator_network(omega=217.0)
    first = integrate(net, np.zeros(2), 0.05, solver="compiled")
    _fresh_process_cache(monkeypatch)
    import hydroline.compiled.codegen as codegen_module

    def no_codegen(model, functions=None):
        raise AssertionError("C generated for a known model")

    real_generate = codegen_module.generate
    monkeypatch.setattr(codegen_module, "generate", no_codegen)
    again = integrate(oscillator_network(omega=217.0), np.zeros(2), 0.05, solver="compiled")
    np.testing.assert_array_equal(again["osc.x"], first["osc.x"])
    # other numbers (a variant): a new record, same library (structure-only C)
    monkeypatch.setattr(codegen_module, "generate", real_generate)
    variant = compiled.native_model(oscillator_network(omega=218.0))
    assert variant.library_path == compiled.native_model(net).library_path


def test_unusable_cache_directory_falls_back(monkeypatch, tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(blocker / "cache"))   # below a file: no mkdir
    with pytest.warns(RuntimeWarning, match="compiled core unavailable"):
        res = integrate(oscillator_network(omega=212.0), np.zeros(2), 0.01, solver="auto")
    assert res.metadata["solver"] == "cvodes"


def test_cache_key_holds_the_cpu_instruction_set():
    # -march=native code is CPU-specific: the key must change with the CPU's feature flags
    ident = compiled.toolchain._cpu_id()
    assert ident
    try:
        flags = [ln for ln in open("/proc/cpuinfo") if ln.lower().startswith(("flags", "features"))]
    except OSError:
        flags = []
    if flags:
        assert flags[0] in ident


@needs_cc
def test_native_solver_refuses_wrong_sizes_and_times():
    net = oscillator_network(omega=213.0)
    nm = compiled.native_model(net)
    with pytest.raises(ValueError, match="parameter vector"):
        nm.solver(p=np.zeros(len(net.parameter_values) + 3))
    ns = nm.solver()
    with pytest.raises(ValueError, match="x0"):
        ns.start(0.0, np.zeros(5), 0.01)
    ns.start(0.0, np.zeros(2), 0.01)
    with pytest.raises(ValueError, match="within the segment"):
        ns.advance([0.005, 0.02])
    with pytest.raises(ValueError, match="rtol"):
        integrate(net, np.zeros(2), 0.01, rtol=0.0)
    with pytest.raises(ValueError, match="method"):
        nm.solver(method="euler")
    with pytest.raises(ValueError, match="fixed_step"):
        nm.solver(method="radau", fixed_step=1e-4)


@dataclass(kw_only=True)
class CeiledOscillator(Oscillator):
    """The oscillator with a ceiling on each state's absolute tolerance, ``resolution``
    times its scale (the scaled ceiling the same for both)."""

    resolution: float = 1e-9

    @property
    def states(self):
        return [State(s.name, s.unit, s.scale, atol_ceiling=self.resolution * s.scale)
                for s in super().states]


@needs_cc
@pytest.mark.parametrize("method", ["bdf", "radau"])
def test_tolerance_ceiling_below_atol_weighs_errors_as_that_atol(method):
    # every state's error weight is 1 / (min(atol, ceiling / scale) + rtol |y|) (bdf.c): a
    # ceiling of 1e-9 of the scale under atol 1e-6 runs step for step as atol 1e-9 without
    # ceilings; a ceiling above atol changes nothing
    t_out = np.linspace(0.0, 0.05, 51)

    def run(resolution, atol):
        osc = (Oscillator(name="osc", omega=213.0) if resolution is None
               else CeiledOscillator(name="osc", omega=213.0, resolution=resolution))
        ns = compiled.native_model(Network([Hold(name="source"), osc])).solver(
            rtol=1e-6, atol=atol, method=method)
        ns.start(0.0, np.zeros(2), 0.05)
        x, _ = ns.advance(t_out, signals=False)
        return x, ns.stats()["nsteps"]

    x_ceiled, n_ceiled = run(1e-9, 1e-6)
    x_tight, n_tight = run(None, 1e-9)
    x_loose, n_loose = run(None, 1e-6)
    assert np.array_equal(x_ceiled, x_tight) and n_ceiled == n_tight
    assert n_loose < n_tight                     # (the ceiling held: not the loose run)
    x_above, n_above = run(1e-3, 1e-6)
    assert np.array_equal(x_above, x_loose) and n_above == n_loose


def test_friction_holds_the_piston_velocity_tolerance_at_a_tenth_of_v_reg():
    # the Stribeck friction reads the actuator's velocity state (M36: tanh(v / v_reg)); no
    # other state of the default rig has a ceiling
    rig = load_rig(None)
    sc = build_scenario(rig, "open-loop-step")
    net = build_network(rig, sc.commands, sc.position_guess)
    ceilings = net.state_atol_ceilings
    i = net.state_names.index("actuator.velocity")
    assert ceilings[i] == pytest.approx(0.1 * 1e-4)
    assert np.isinf(np.delete(ceilings, i)).all()


@dataclass(kw_only=True)
class Blowup(Component):
    """dx/dt = 1/sqrt(t_end - t): finite until t_end, NaN after it (a model leaving its domain)."""

    t_end: float = 0.005
    inputs = {}
    outputs = {"x": Port("position")}
    feedthrough = False

    @property
    def states(self):
        return [State("x", "m", 1.0)]

    def outputs_of(self, t, x, u, p):
        return {"x": x["x"]}

    def derivatives(self, t, x, u, p):
        return {"x": 1.0 / ops.sqrt(self.t_end - t)}


@needs_cc
def test_non_finite_derivative_is_named_in_the_error():
    net = Network([Blowup(name="blowup")])
    with pytest.raises(RuntimeError, match=r"derivative of state 'blowup\.x' is not finite"):
        integrate(net, np.zeros(1), 0.01, solver="compiled")


@needs_cc
def test_known_structure_reads_only_the_constants(monkeypatch, tmp_path):
    """A variant of a known structure (other numbers, same graph) takes its constants from the
    graph without writing C: the same constants as a full code generation, the same library,
    and the oscillator's exact step response."""
    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    first = compiled.native_model(oscillator_network(omega=2 * np.pi * 40.0))
    _fresh_process_cache(monkeypatch)        # the structure record on disk is what is left
    import hydroline.compiled.codegen as codegen_module

    def no_codegen(model, functions=None):
        raise AssertionError("C generated for a known structure")

    real_generate = codegen_module.generate
    monkeypatch.setattr(codegen_module, "generate", no_codegen)
    net = oscillator_network(omega=2 * np.pi * 60.0, zeta=0.1)
    variant = compiled.native_model(net)
    assert variant.library_path == first.library_path
    full = real_generate(net.compile())
    np.testing.assert_array_equal(variant.generated.constants, full.constants)
    res = integrate(net, np.zeros(2), 0.05, solver="compiled")
    assert res["osc.x"].max() == pytest.approx(_oscillator_peak(0.1), rel=2e-3)
    # a value that CasADi would simplify away as a constant (zeta = 0: no damping term) is
    # the same structure: the C takes the components' numbers at run time
    assert codegen_module.structure_key(codegen_module.scaled_functions(
        oscillator_network(zeta=0.0).compile())) == codegen_module.structure_key(
        codegen_module.scaled_functions(net.compile()))
