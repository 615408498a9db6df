"""The bordered Jacobian of the compiled core (hydroline.compiled.codegen: the network cut open
at its connections) against independent truth: the connected network's own evaluation,
CasADi's dense Jacobian of the uncut graph, NumPy's dense solves; and its size against the
number of states."""
import numpy as np
import pytest

from hydroline import compiled
from hydroline.compiled import bordered
from hydroline.compiled.bordered import BorderedSystem
from hydroline.compiled.codegen import generate, interface_signals
from hydroline.engine import solve_steady_state, steady_state
from hydroline.rigs import load_rig
from hydroline.scenarios import build_scenario
from hydroline.system import build_network

needs_cc = pytest.mark.skipif(not compiled.available(), reason="no C compiler")


def default_network(modes=None, cavity_pressure=None):
    rig = load_rig(None)
    if modes is not None:
        rig.set("rig.modes_per_section", modes)
    if cavity_pressure is not None:
        rig.set("fluid.cavity_pressure", cavity_pressure)
    sc = build_scenario(rig, "open-loop-step")
    return build_network(rig, sc.commands, sc.position_guess)


@pytest.fixture(scope="module")
def rig_at_rest():
    """The default rig's network, a state near its rest state and its parameters."""
    net = default_network()
    ss = solve_steady_state(net)
    rng = np.random.default_rng(7)
    x = ss.x + 0.02 * rng.normal(size=len(ss.x)) * net.state_scales
    return net, x, ss.p


def test_a_network_cut_open_at_its_signals_evaluates_as_connected(rig_at_rest):
    """Every component reading the value its producer outputs (given) gives the connected
    network's derivatives and signals, bit for bit."""
    net, x, p = rig_at_rest
    dx, signals = net.evaluate(0.01, x, p)
    # (the connections; the hose ends' cavities, cut open inside, below)
    cut = [s for s in interface_signals(net) if isinstance(s, str)]
    assert cut and set(cut) <= set(signals)
    dx_cut, signals_cut = net.evaluate(0.01, x, p, given={s: signals[s] for s in cut})
    assert np.array_equal(np.array(dx_cut, dtype=float), np.array(dx, dtype=float))
    assert signals_cut == signals


@pytest.fixture(scope="module")
def cavitating_rig():
    """The default rig with its cavity model on (M42, M45), near its rest state, with the
    return hose's valve end (its upstream end) pulled to its cavity pressure: the end cavity's
    rank-one term in d(dz/dt)/dz is then at its full size (dw/dp~ = -1/(2|k|))."""
    net = default_network(cavity_pressure="5 kPa")
    ss = solve_steady_state(net)
    rng = np.random.default_rng(11)
    x = ss.x + 0.02 * rng.normal(size=len(ss.x)) * net.state_scales
    hose = next(c for c in net.components if c.name == "return.section1")
    (_, i, _, _), = hose.cavity_ends
    c = np.asarray(hose.model.C, dtype=float)[i]
    index = [net.state_names.index(f"{hose.name}.{s.name}") for s in hose.states]
    q = int(np.argmax(np.abs(c)))
    x[index[q]] += (5e3 - c @ x[index]) / c[q]          # p~ = p_cav
    assert c @ x[index] == pytest.approx(5e3, abs=1e-3)
    return net, x, ss.p, hose


def test_a_hose_end_cavity_is_cut_open_as_one_signal(cavitating_rig):
    """The end cavity's lift (M45, the hose's internal signal) given its own value, the
    network cut open there and at its connections evaluates as connected, bit for bit; the
    bordered Jacobian's blocks of the hose sections are their lines' A, as without a cavity
    model (the cavity adds one border row and column per end, not a dense block)."""
    net, x, p, hose = cavitating_rig
    assert hose.internal_signals == ("cavity_lift",)
    cut = interface_signals(net)
    ends = [(c.name, "cavity_lift") for c in net.components if getattr(c, "cavity_ends", ())]
    assert len(ends) == 4 and cut[-4:] == ends
    dx, signals = net.evaluate(0.01, x, p)
    # (an internal signal's own value: returned where it is cut, whatever it was given)
    _, own = net.evaluate(0.01, x, p, given={s: 0.0 for s in ends})
    own.update(signals)
    dx_cut, signals_cut = net.evaluate(0.01, x, p, given={s: own[s] for s in cut})
    assert np.array_equal(np.array(dx_cut, dtype=float), np.array(dx, dtype=float))
    assert {k: v for k, v in signals_cut.items() if isinstance(k, str)} == signals
    # the lift at p~ = p_cav: softplus(0, delta) = delta ln 2
    assert float(signals_cut[(hose.name, "cavity_lift")]) == pytest.approx(1e3 * np.log(2))

    def hose_blocks(network):
        pattern = generate_pattern(network)
        out = {}
        for c in network.components:
            if isinstance(c, type(hose)):
                rows = [network.state_names.index(f"{c.name}.{s.name}") for s in c.states]
                out[c.name] = pattern[np.ix_(rows, rows)]
        return out

    plain = hose_blocks(default_network())
    for name, block in hose_blocks(net).items():
        assert np.array_equal(block, plain[name]), name


def generate_pattern(network):
    """The bordered Jacobian's pattern (states first), dense booleans."""
    from hydroline.compiled.codegen import scaled_functions

    _, jac, _ = scaled_functions(network.compile())
    sp = jac.sparsity_out(0)
    M = np.zeros(sp.shape, dtype=bool)
    M[sp.row(), sp.get_col()] = True
    return M


@needs_cc
def test_jacobian_with_open_end_cavities_is_casadis(cavitating_rig):
    """As below, with the cavity model on and the return hose's end at its cavity pressure:
    the rank-one term of the end cavity (through the cut lift) is in the assembled J."""
    net, x, p, _ = cavitating_rig
    s = net.state_scales
    ref = net.compile().jacobian(0.01, x, p) * s[None, :] / s[:, None]
    J = compiled.native_model(net).solver(p).scaled_jacobian(0.01, x)
    assert np.abs(J - ref).max() <= 1e-10 * np.abs(ref).max()
    assert np.all((ref != 0) <= (J != 0) | (np.abs(ref) < 1e-12 * np.abs(ref).max()))


@needs_cc
def test_jacobian_assembled_from_the_bordered_one_is_casadis(rig_at_rest):
    """d(dz/dt)/dz from the C library (the Schur complement of the bordered Jacobian, with
    row exchanges in the small dense solve of the cut signals, whose SI magnitudes span 11
    decades) against CasADi's Jacobian of the uncut graph, to rounding."""
    net, x, p = rig_at_rest
    s = net.state_scales
    ref = net.compile().jacobian(0.01, x, p) * s[None, :] / s[:, None]
    J = compiled.native_model(net).solver(p).scaled_jacobian(0.01, x)
    assert np.abs(J - ref).max() <= 1e-10 * np.abs(ref).max()
    assert np.all((ref != 0) <= (J != 0) | (np.abs(ref) < 1e-12 * np.abs(ref).max()))


@needs_cc
@pytest.mark.parametrize("shift", [0.0, 1e3, 1e6])
def test_sparse_shifted_solve_equals_numpys_dense_solve(rig_at_rest, shift):
    """(shift I - J) dz = b through the bordered system (SuperLU) against numpy.linalg.solve
    on CasADi's dense J: Newton's step (shift 0) and pseudo-transient steps."""
    net, x, p = rig_at_rest
    s = net.state_scales
    J = net.compile().jacobian(0.0, x, p) * s[None, :] / s[:, None]
    b = np.random.default_rng(3).normal(size=len(x))
    dense = np.linalg.solve(shift * np.eye(len(x)) - J, b)
    sparse = BorderedSystem(compiled.native_model(net)).solve_shifted(0.0, x, p, shift, b)
    assert np.abs(sparse - dense).max() <= 1e-8 * np.abs(dense).max()


def casadi_rest_state(net, monkeypatch):
    """The rest state found with CasADi's dense d(dz/dt)/dz (no compiled core: the steady
    state's fallback), the reference of the bordered solves."""
    with monkeypatch.context() as m:
        m.setattr(compiled, "native_model", no_compiler)
        return solve_steady_state(net)


def no_compiler(network):
    raise compiled.CompilerUnavailable("(test)")


@needs_cc
@pytest.mark.parametrize("sparse_from", [bordered.SPARSE_STATES, 0])
def test_rest_state_through_the_bordered_system_is_casadis(monkeypatch, sparse_from):
    """The rest state solved through the bordered system (LAPACK below SPARSE_STATES states,
    SuperLU from there: forced here on the default rig's 138) is the one Newton finds with
    CasADi's dense Jacobian, to the solver's tolerance (1e-9 1/s scaled residual: the states
    within a few 1e-9 of their scales)."""
    ref = casadi_rest_state(default_network(), monkeypatch)
    monkeypatch.setattr(bordered, "SPARSE_STATES", sparse_from)
    monkeypatch.setattr(steady_state, "CHORD_STATES", 0)     # (no dense chord steps)
    net = default_network()
    ss = solve_steady_state(net)
    assert ss.residual < 1e-9
    assert np.all(np.abs(ss.x - ref.x) <= 1e-6 * net.state_scales)


def test_factors_and_code_grow_like_the_states():
    """6 and 18 modes per section (138 and 234 states): the bordered LU's slots and flops, and
    the C source, per state within 1.3x (the full Jacobian's LU grew 1.9x in slots and 3.7x
    in flops per state over this range: 3 690 slots and 54 000 flops at 138 states, 11 700
    and 337 000 at 234; its source 4.5 kB and 12 kB per state)."""
    sizes = {}
    for modes in (6, 18):
        gen = generate(default_network(modes).compile())
        n = gen.n_states
        sizes[modes] = (gen.lu_slots / n, gen.lu_flops / n, len(gen.source) / n)
    for small, large in zip(sizes[6], sizes[18]):
        assert large <= 1.3 * small, sizes
