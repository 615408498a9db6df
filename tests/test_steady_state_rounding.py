"""The rest state's Newton iteration where rounding keeps the residual above the tolerance
(issue 25: a layout sweep's short hoses fell back to the pseudo-transient continuation on
about 1 variant in 5, 5-170 ms each, though Newton had converged to ~1e-14 of the states),
and its chord steps (one inverse Jacobian kept through the solves of a network)."""
import numpy as np
import pytest

from hydroline import compiled
from hydroline.engine import solve_steady_state, steady_state
from hydroline.rigs import load_rig
from hydroline.scenarios import build_scenario
from hydroline.system import build_network


class NoisyLinear:
    """``f(x) = J (x - x*)`` plus a deterministic "rounding" term that changes with every bit
    of x, of amplitude ``noise`` on the fastest equation and in proportion to each
    equation's rate on the others (the rounding of a sum scales with its terms), [1/s].
    ``J``: rates up to 1e6 1/s, like a short hose's fast tail states."""

    def __init__(self, noise):
        self.J = np.array([[-1e6, 2e3, 0.0], [0.0, -5e3, 1.0], [10.0, 0.0, -2.0]])
        self.x_star = np.array([0.3, -1.2, 2.5])
        self.noise = noise
        self.calls = 0

    def rhs(self, t, x, p):
        self.calls += 1
        bits = np.frombuffer(np.asarray(x, dtype=float).tobytes(), dtype=np.uint64)
        jitter = ((bits * np.uint64(2654435761)) % np.uint64(1000)).astype(float) / 500.0 - 1.0
        rate = np.abs(np.diag(self.J))
        return self.J @ (x - self.x_star) + self.noise * rate / rate.max() * jitter

    def jacobian(self, t, x, p):
        return self.J


def test_newton_stalled_by_rounding_counts_as_converged():
    """With a rounding floor of 1e-8 1/s (ten times the tolerance) Newton's steps shrink to
    ~1e-14 and the residual stops falling: the state is x* to ~1e-14 (J^-1 times the
    floor), and that is converged, not a case for the continuation."""
    model = NoisyLinear(noise=1e-8)
    scales = np.ones(3)
    x, converged = steady_state._newton(model, 0.0, np.zeros(3), None, scales, tol=1e-9)
    assert converged
    assert np.max(np.abs(model.rhs(0.0, x, None))) > 1e-9       # the floor: above tol
    assert np.abs(x - model.x_star).max() < 1e-12         # |J^-1 floor| ~ 1e-14


def test_newton_stalled_far_above_rounding_is_not_converged():
    """A floor of 1e-3 1/s is no rounding (a kink, a state still moving): Newton reports
    no convergence and the caller goes on to the continuation."""
    model = NoisyLinear(noise=1e-3)
    x0 = np.zeros(3)
    x, converged = steady_state._newton(model, 0.0, x0, None, np.ones(3), tol=1e-9)
    assert not converged
    assert np.array_equal(x, x0)


def test_chord_steps_converge_where_the_kept_inverse_is_another_states():
    """An inverse Jacobian kept from another model (rows scaled by 1.5, 1, 0.7: its chord
    steps would cut the error by 0.33-0.43 a step, not to CHORD_RATE): it is replaced by
    the inverse at the current state, and the iteration ends at x*."""
    model = NoisyLinear(noise=0.0)
    chord = {"inverse": np.linalg.inv(model.J * np.array([1.5, 1.0, 0.7]))}
    x, converged = steady_state._newton(model, 0.0, np.zeros(3), None, np.ones(3), tol=1e-9,
                                        chord=chord)
    assert converged and np.abs(x - model.x_star).max() < 1e-12
    assert np.allclose(chord["inverse"] @ model.J, np.eye(3), atol=1e-12)


@pytest.mark.skipif(not compiled.available(), reason="no C compiler")
def test_rest_state_by_chord_steps_is_the_one_by_newtons_steps(monkeypatch):
    """The default rig's rest state with chord steps (an inverse kept through the rounds and
    for the next solve of the network) and with a Newton step through the bordered system at
    every iteration (CHORD_STATES = 0): the same states to the solver's tolerance (a scaled
    residual of 1e-9 1/s: the states within 1e-6 of their scales, as in
    test_compiled_bordered), the second solve of the same network too."""
    rig = load_rig(None)

    def network():
        sc = build_scenario(rig, "open-loop-step")
        return build_network(rig, sc.commands, sc.position_guess)

    monkeypatch.setattr(steady_state, "CHORD_STATES", 0)
    ref = solve_steady_state(network())
    monkeypatch.undo()
    net = network()
    first = solve_steady_state(net)
    second = solve_steady_state(net, x_guess=first.x * (1.0 + 1e-3))   # the inverse kept
    for ss in (first, second):
        assert ss.residual < 1e-6
        assert np.all(np.abs(ss.x - ref.x) <= 1e-6 * net.state_scales)


@pytest.mark.skipif(not compiled.available(), reason="no C compiler")
@pytest.mark.parametrize("length", [0.02, 0.05, 0.3])
def test_short_hoses_rest_state_from_the_guess_needs_no_continuation(length):
    """Issue 25: the default rig with both section II hoses ``length`` long, from the
    components' guess. The guess puts the return check valve at zero flow, the middle of its
    switch, where the rest state passes the servovalve's leakage (~100 transition flows
    away): Newton's first step, linearised there, fails, and the rest state used to come from
    the pseudo-transient continuation (0.02-1.7 s; at 0.02-0.03 m not even to the
    tolerance). The Newton iteration's shifted steps cross the switch: no continuation
    (``fallback``), and the rest state satisfies f(x) = 0 by the reference NumPy
    right-hand side (another evaluation than the compiled one the solver used) to the
    solver's rounding bound ROUNDING_RESIDUAL in every state."""
    rig = load_rig(None)
    rig.set("supply.section2.length", f"{length} m")
    rig.set("return.section2.length", f"{length} m")
    sc = build_scenario(rig, "open-loop-step")
    net = build_network(rig, sc.commands, sc.position_guess)
    ss = solve_steady_state(net)
    assert not ss.fallback
    assert ss.newton_steps > 0
    f = net.rhs(0.0, ss.x, ss.p) / net.state_scales
    assert np.max(np.abs(f)) < steady_state.ROUNDING_RESIDUAL
    flows = net.signals_at(0.0, ss.x, ss.p)
    # at rest the leakage through the servovalve's return port is the return line's flow
    # through the check valve to the tank (the accumulators at rest carry none)
    assert flows["return.manifold_flow"] > 0.0
    assert flows["return.manifold_flow"] == pytest.approx(flows["return_port_flow"], rel=1e-6)


@pytest.mark.skipif(not compiled.available(), reason="no C compiler")
def test_new_numbers_rest_state_starts_from_the_kept_neighbour():
    """Issue 25: ``simulate()`` with new numbers in one process starts the new rig's rest state
    from the last kept model of the same states (its rest state and inverse Jacobian: no
    shifted steps), instead of the components' guess. The rest state is the one a fresh
    process finds from the guess, within the solver's tolerance (states within 1e-6 of their
    scales, as above), f(x) = 0 by the NumPy right-hand side to the rounding bound, and the
    run agrees with a fresh one to the integration's accuracy (traces within 1e-4 of their
    excursion: rtol 1e-6 keeps them within ~1e-5, simulate's docstring)."""
    from hydroline.scenarios.running import Simulation

    kept = Simulation()
    kept.run(load_rig(None))
    rig = load_rig(None).set("supply.accumulator.capacity", "1.3 L")
    near = kept.run(rig)
    (_, _, net, ss), = list(kept.models.values())[-1:]
    assert ss.shifted_steps == 0 and not ss.fallback
    fresh_sim = Simulation()
    fresh = fresh_sim.run(rig)
    (_, _, _, ref), = fresh_sim.models.values()
    assert ref.shifted_steps > 0            # the guess's start needed them
    assert np.all(np.abs(ss.x - ref.x) <= 1e-6 * net.state_scales)
    f = net.rhs(0.0, ss.x, ss.p) / net.state_scales
    assert np.max(np.abs(f)) < steady_state.ROUNDING_RESIDUAL
    for k in ("supply_port_pressure", "return_port_pressure", "piston_position"):
        assert np.max(np.abs(near[k] - fresh[k])) < 1e-4 * np.ptp(fresh[k]), k
    again = kept.run(load_rig(None))        # the same numbers: the kept rest state itself
    assert np.array_equal(again["supply_port_pressure"],
                          Simulation().run(load_rig(None))["supply_port_pressure"])


def test_polished_rest_state_has_the_same_bits_from_two_starts():
    """Two converged states 1e-14 apart (two paths to one root, rounding-level apart: what a
    neighbour's start and the components' guess give) are polished onto the same grid point
    of 2**-30 of the scales and one Newton step from there: the same bits, within rounding of
    the root (the linear model's exact root x*). The root sits mid-cell of the grid, so
    neither start straddles a grid boundary."""
    model = NoisyLinear(noise=0.0)
    scales = np.ones(3)
    grid = 2.0 ** -steady_state.CANONICAL_BITS
    model.x_star = (np.floor(model.x_star / grid) + 0.5) * grid      # mid-cell
    a = steady_state.polished(model, 0.0, model.x_star + 1e-14, None, scales, 1e-9)
    b = steady_state.polished(model, 0.0, model.x_star - 1e-14, None, scales, 1e-9)
    assert np.array_equal(a, b)
    assert np.all(np.abs(a - model.x_star) <= 1e-15 * np.maximum(np.abs(model.x_star), 1.0))
