"""The compiled core's NDF orders 3-5 are kept within their stability regions on a model's
lightly damped fast modes (hydroline.compiled.stability), checked against the roots of the
formulas' characteristic polynomials, and against a tight reference run of a rig with a
short hose (whose 10-25 kHz modes held the old step control at 3.9 us steps)."""
from __future__ import annotations

import numpy as np
import pytest

from hydroline.compiled import stability


def _unstable(q: int, z: complex) -> bool:
    """Independent check: NDF order q on y' = lambda y with z = h lambda has a root
    |zeta| > 1 of  sum_m (1/m) (1 - x)^m - kappa gamma (1 - x)^(q+1) - z = 0,  x = 1/zeta."""
    w = np.poly1d([-1.0, 1.0])
    poly = np.poly1d([0.0])
    for m in range(1, q + 1):
        poly = poly + (1.0 / m) * w**m
    gamma = sum(1.0 / j for j in range(1, q + 1))
    poly = poly - stability.KAPPA[q] * gamma * w ** (q + 1) - z
    return bool(np.any(np.abs(poly.r) < 1 - 1e-9))


@pytest.mark.parametrize("q", [3, 4, 5])
@pytest.mark.parametrize("degrees", [55, 70, 82, 86.5, 89.5])
def test_onset_is_where_the_characteristic_roots_leave_the_unit_circle(q, degrees):
    angle = np.radians(degrees)
    ray = np.exp(1j * (np.pi - angle))
    r1 = float(stability.unstable_onset(q, angle))
    if not np.isfinite(r1):      # the whole ray stable (inside the order's A(alpha) sector)
        assert not any(_unstable(q, r * ray) for r in np.linspace(0.01, 6, 300))
        return
    assert not any(_unstable(q, r * ray) for r in np.linspace(0.01, 0.99 * r1, 60))
    assert _unstable(q, 1.02 * r1 * ray)


def test_a_stable_orders_and_the_sectors_of_the_others():
    # orders 1-2: no limit on any ray; NDF3-5's A(alpha) angles (Shampine & Reichelt 1997:
    # 80.9, 66 and 51 degrees): rays just inside are stable, just outside are not
    for q in (1, 2):
        assert not any(_unstable(q, r * np.exp(1j * (np.pi - np.radians(89.9))))
                       for r in np.linspace(0.05, 20, 200))
    for q, alpha in ((3, 80.9), (4, 66.0), (5, 51.0)):
        assert not np.isfinite(stability.unstable_onset(q, np.radians(alpha - 1.0)))
        assert np.isfinite(stability.unstable_onset(q, np.radians(alpha + 1.5)))


def test_step_limits_of_a_hand_made_spectrum():
    # a 25 kHz mode at 6 % damping limits orders 3-5 to ~5 us; a real eigenvalue (however
    # fast) and a heavily damped pair limit nothing; orders 1-2 never
    w = 2 * np.pi * 25e3
    fast = -0.06 * w / np.sqrt(1 - 0.06**2) + 1j * w
    limits = stability.order_step_limits([fast, np.conj(fast), -7.8e4, -1e3 + 100j])
    assert limits[:2] == (np.inf, np.inf)
    angle = np.arctan2(fast.imag, -fast.real)
    for q in (3, 4, 5):
        expect = stability.MARGIN * stability.unstable_onset(q, angle) / abs(fast)
        assert limits[q - 1] == pytest.approx(expect)
        assert 3e-6 < limits[q - 1] < 6e-6
    assert stability.order_step_limits([-7.8e4, -1e3 + 100j]) == (np.inf,) * 5


def test_block_eigenvalues_of_a_two_block_matrix():
    J = np.zeros((5, 5))
    J[:2, :2] = [[-3.0, 7.0], [-2.0, -1.0]]              # -2 +- 3.606i (closed form)
    J[2:, 2:] = np.diag([-1.0, -2.0, -3.0]) + np.triu(np.ones((3, 3)), 1)
    J[0, 4] = 99.0                                        # off the blocks: ignored
    w = stability.block_eigenvalues(J, [slice(0, 2), slice(2, 5)])
    assert np.allclose(np.sort_complex(w), np.sort_complex(
        [-2 - 13**0.5 * 1j, -2 + 13**0.5 * 1j, -1, -2, -3]))


def test_blocks_cut_from_the_nonzeros_and_solved_together():
    """block_gather's cut of a compressed-column matrix gives its dense diagonal blocks (zeros
    where it has no nonzero, entries off the blocks ignored), and two new blocks of one size
    solved in one call give each block's own eigenvalues (triangular: its diagonal; a
    rotation-scaling pair a +- b i beside a real one)."""
    J = np.zeros((8, 8))
    J[:3, :3] = [[-1.0, 2.0, 0.5], [0.0, -4.0, 3.0], [0.0, 0.0, -9.0]]        # -1, -4, -9
    J[3:6, 3:6] = [[-2.0, -5.0, 0.0], [5.0, -2.0, 0.0], [1.0, 0.0, -7.0]]      # -2 +- 5i, -7
    J[6:, 6:] = [[-3.0, 7.0], [-2.0, -1.0]]                                      # -2 +- 3.606i
    J[0, 7] = J[7, 1] = 42.0                                                     # off the blocks
    cols = [np.flatnonzero(J[:, c]) for c in range(8)]
    colind = np.concatenate(([0], np.cumsum([len(r) for r in cols])))
    rows = np.concatenate(cols)
    jnz = np.concatenate([J[r, c] for c, r in enumerate(cols)])
    blocks = [slice(0, 3), slice(3, 6), slice(6, 8)]
    take, place, sizes = stability.block_gather(colind, rows, blocks)
    assert sizes == (3, 3, 2)
    flat = np.zeros(sum(m * m for m in sizes))
    flat[place] = jnz[take]
    subs = [flat[:9].reshape(3, 3), flat[9:18].reshape(3, 3), flat[18:].reshape(2, 2)]
    for sub, b in zip(subs, blocks):
        assert np.array_equal(sub, J[b, b])
    stability._EIGEN_CACHE.clear()      # both 3 x 3 blocks new: one stacked LAPACK call
    w = stability.eigenvalues_of_blocks(subs)
    expected = [-1, -4, -9, -2 + 5j, -2 - 5j, -7, -2 + 13**0.5 * 1j, -2 - 13**0.5 * 1j]
    assert np.allclose(np.sort_complex(w), np.sort_complex(expected))
    # met before: from the memory, the same numbers
    assert np.array_equal(stability.eigenvalues_of_blocks(subs), w)


def _short_hose_run(length: str, limits: bool, rtol: float):
    from hydroline import compiled
    from hydroline.rigs import load_rig
    from hydroline.scenarios import build_scenario
    from hydroline.simulation import solve_steady_state
    from hydroline.system import build_network

    rig = load_rig()
    # the Yang-Tobler line, on which the limits' figures below were measured: its short
    # sections' lightly damped 10-25 kHz modes are what the limits are for (the exact-pole
    # line's fitted tail of dropped modes is well damped)
    rig.set("rig.line_method", "yang-tobler")
    rig.set("supply.section2.length", length)
    rig.set("return.section2.length", length)
    sc = build_scenario(rig, "open-loop-step")
    net = build_network(rig, sc.commands, sc.position_guess)
    ss = solve_steady_state(net)
    solver = compiled.native_model(net).solver(ss.p, rtol=rtol, atol=rtol / 10,
                                               order_limits=limits)
    grid = np.arange(1, 2501) * 1e-4
    rows, x = [], ss.x
    for a, b in ((0.0, 0.01), (0.01, 0.25)):          # the valve step at 10 ms
        solver.start(a, x, b)
        X, Y = solver.advance(grid[(grid > a + 1e-12) & (grid <= b + 1e-12)])
        rows.append(Y)
        x = X[-1]
    names = list(net.signal_names)
    cols = [names.index(k) for k in ("supply_port_pressure", "return_port_pressure",
                                     "piston_velocity")]
    return np.vstack(rows)[:, cols], solver


def test_a_short_hose_runs_in_far_fewer_steps_at_the_tolerance():
    from hydroline import compiled

    if not compiled.available():
        pytest.skip("no C compiler")
    ref, _ = _short_hose_run("0.05 m", True, 1e-10)
    old, s_old = _short_hose_run("0.05 m", False, 1e-6)
    new, s_new = _short_hose_run("0.05 m", True, 1e-6)
    lim = s_new.order_limits
    assert lim[:2] == (np.inf, np.inf) and all(2e-6 < h < 1e-5 for h in lim[2:])
    # ~5 000 against 41 000-57 000 steps (the step control's path depends on rounding, so at
    # three tolerances a rounding apart): at least 2.5x fewer at each. Before the drop's
    # backoff was capped (bdf.c HL_MAX_BACKOFF), 2 of 5 such runs took 28 000-37 000
    assert s_new.stats()["nsteps"] < s_old.stats()["nsteps"] / 2.5
    for rtol in (0.99e-6, 1.01e-6):
        steps = [_short_hose_run("0.05 m", limits, rtol)[1].stats()["nsteps"]
                 for limits in (True, False)]
        assert steps[0] < steps[1] / 2.5, rtol
    span = np.ptp(ref, axis=0)
    err_new = np.max(np.abs(new - ref), axis=0) / span
    err_old = np.max(np.abs(old - ref), axis=0) / span
    assert np.all(err_new < 2e-4)                     # 2e-2 % of each signal's excursion
    assert np.max(err_new) <= 1.5 * np.max(err_old)


def test_the_default_rig_is_not_limited():
    """The paper's hoses (3 m): every step the accuracy asks for is below the limits, so the
    run is the one without them, bit for bit."""
    from hydroline import compiled

    if not compiled.available():
        pytest.skip("no C compiler")
    with_limits, s = _short_hose_run("3.048 m", True, 1e-6)
    without, _ = _short_hose_run("3.048 m", False, 1e-6)
    assert np.isfinite(s.order_limits[2]) and np.array_equal(with_limits, without)
