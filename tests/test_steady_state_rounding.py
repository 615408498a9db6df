"""The rest state's Newton iteration where rounding keeps the residual above the tolerance
(issue 25: a layout sweep's short hoses fell back to the pseudo-transient continuation on
about 1 variant in 5, 5-170 ms each, though Newton had converged to ~1e-14 of the states)."""
import numpy as np

from hydroline.engine import steady_state


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
