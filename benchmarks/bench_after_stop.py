"""Benchmark: issue 25's stretch (>= 90x real time) by a cheaper treatment once the piston rests
on its stop -- the frozen linearisation stepped exactly, measured against the full run.

On the default rig's default run (the valve step at 10 ms, the piston on its top stop from
~113 ms to the end at 250 ms) it measures, against the full nonlinear run (the compiled core
at rtol 1e-10 / atol 1e-11):

1. **Accuracy.** From the reference's state x_s at a switch time t_s, the deviation is
   propagated exactly on the 0.1 ms output grid, ``z_{k+1} = E z_k`` with ``E = expm(M dt)``
   on the scaled states, either

   * about the switch state (the frozen linearisation: ``dx/dt = f(x_s) + J(x_s) (x - x_s)``,
     the affine term in an extra row of ``M``), or
   * about the rest state the run goes to (``x_eq``, ``f(x_eq) = 0``, solved from the
     reference's last row by pseudo-transient continuation, the accumulators' charge kept);

   the largest error of each trace (port pressures, piston position and velocity) after t_s is
   printed as % of its excursion up to the stop, as ``bench_integration.py`` reads it.
   Beside it the switch test's quantity: the error ``e = x - x_lin`` of the frozen
   linearisation obeys ``de/dt = J e + r`` exactly, ``r = f(x) - f(x_s) - J (x - x_s)`` the
   nonlinear residual along the run, so ``|e(t)| <= gamma int_{t_s}^t |r(s)| ds`` with
   ``gamma = sup ||exp(J tau)||`` (max norms on the scaled states; gamma estimated as the
   largest norm of E^(2^j), j = 0..10, i.e. up to 102 ms); printed with the largest scaled
   residual after t_s, the condition number of J's eigenvectors (the modal form's) and
   J's slowest decay rate.
2. **Cost.** The one-time costs of a switch (the dense Jacobian, ``expm`` of the 139 x 139
   augmented matrix, an eigendecomposition, the rest-state solve) and the per-row cost of
   the exact stepping (a dense matrix-vector product per row, and all rows at once from the
   modal form), against the compiled core's cost per output row after the stop (the whole run
   less the run to the stop).

Usage: python benchmarks/bench_after_stop.py [--switch 0.115 0.12 0.13 0.15 0.2] [--repeat 20]
"""
from __future__ import annotations

import argparse
import time

from hydroline.blas import single_threaded_blas

single_threaded_blas()   # (before NumPy: a BLAS thread pool made expm 20x slower here)

import numpy as np  # noqa: E402
import scipy.linalg  # noqa: E402

from tables import text_table  # noqa: E402

TRACES = ("supply_port_pressure", "return_port_pressure", "piston_position", "piston_velocity")


class _Rest:
    """f, its Jacobian and the signals from a compiled solver, as the steady-state solver's
    ``pseudo_transient`` asks for them (p fixed: the run's, the accumulators' charge kept)."""

    def __init__(self, solver, scales):
        self.solver, self.scales = solver, scales

    def rhs(self, t, x, p):
        return self.solver.rhs(t, x)

    def scaled_jacobian(self, t, x, p):
        return self.solver.scaled_jacobian(t, x)

    def jacobian(self, t, x, p):
        return self.scaled_jacobian(t, x, p) * self.scales[:, None] / self.scales[None, :]


def best_ms(fn, repeat):
    """Least CPU [ms] of ``repeat`` calls of fn (process time: the load of other work aside)."""
    out = []
    for _ in range(repeat):
        c = time.process_time()
        fn()
        out.append(time.process_time() - c)
    return min(out) * 1e3


def propagate(E, d0, rows):
    """``rows`` rows of z_{k+1} = E z_k from z_0 = d0 (z_0 included)."""
    out = np.empty((rows, len(d0)))
    out[0] = d0
    for k in range(1, rows):
        out[k] = E @ out[k - 1]
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--switch", type=float, nargs="+", default=(0.115, 0.12, 0.13, 0.15, 0.2),
                    help="switch times t_s [s] (the piston reaches its stop at ~0.113 s)")
    ap.add_argument("--repeat", type=int, default=20, help="timed calls per cost row")
    args = ap.parse_args(argv)
    import hydroline
    from hydroline import compiled
    from hydroline.engine.steady_state import pseudo_transient
    from hydroline.scenarios.running import Simulation

    sim = Simulation()
    ref = sim.run(solver="compiled", rtol=1e-10, atol_scale=1e-11)
    (_, _, net, ss), = sim.models.values()
    dt = float(ref.t[1] - ref.t[0])
    t_stop = ref.metadata["metrics_window"][1]
    solver = compiled.native_model(net).solver(ss.p)
    S = np.asarray(net.state_scales, dtype=float)
    X = np.asarray(ref.data[list(net.state_names)])
    Y = np.asarray(ref.data[list(net.signal_names)])
    t, n = ref.t, X.shape[1]
    signal_index = [list(net.signal_names).index(k) for k in TRACES]
    excursion = np.array([np.ptp(Y[t <= t_stop, j]) for j in signal_index])

    def trace_error(i, Z):
        """Largest error [%] of each trace from row i on, states Z (scaled) from there."""
        got = np.array([solver.signals(t[i + m], Z[m] * S)[signal_index] for m in range(len(Z))])
        return np.max(np.abs(got - Y[i:, signal_index]), axis=0) / excursion * 100

    rest = _Rest(solver, S)
    c0 = time.process_time()
    x_eq = pseudo_transient(rest, float(t[-1]), X[-1], ss.p, S, 1e-9)
    eq_ms = (time.process_time() - c0) * 1e3
    J_eq = solver.scaled_jacobian(float(t[-1]), x_eq)
    E_eq = scipy.linalg.expm(J_eq * dt)
    z_eq = x_eq / S

    def frozen_at(ts):
        """Row i of the switch at ts, rows m from there, its state, the scaled Jacobian J and
        f there, and the augmented matrix [[J dt, f dt], [0, 0]] whose exponential steps the
        frozen linearisation (the constant term f carried as an extra state of value 1)."""
        i = int(round(ts / dt))
        xs = X[i]
        J = solver.scaled_jacobian(float(t[i]), xs)
        f = solver.rhs(float(t[i]), xs) / S
        M = np.zeros((n + 1, n + 1))
        M[:n, :n], M[:n, n] = J * dt, f * dt
        return i, len(t) - i, xs, J, f, M

    rows = []
    for ts in args.switch:
        i, m, xs, J, f, M = frozen_at(ts)
        aug = np.zeros(n + 1)
        aug[n] = 1.0
        Z = X[i] / S + propagate(scipy.linalg.expm(M), aug, m)[:, :n]
        frozen = trace_error(i, Z)
        about_eq = trace_error(i, z_eq + propagate(E_eq, X[i] / S - z_eq, m))
        # the switch test's quantity along the reference: r = f(x) - f(x_s) - J (x - x_s)
        r = np.array([np.max(np.abs(solver.rhs(float(t[k]), X[k]) / S - f - J @ (X[k] / S - xs / S)))
                      for k in range(i, len(t))])
        lam, V = np.linalg.eig(J)
        alpha = float(lam.real.max())
        kappa = float(np.linalg.cond(V))
        E = scipy.linalg.expm(J * dt)
        gamma = 1.0
        for _ in range(11):
            gamma = max(gamma, float(np.linalg.norm(E, np.inf)))
            E = E @ E
        bound = gamma * np.sum(r) * dt   # at the run's end
        err_states = np.max(np.abs(Z - X[i:] / S))
        rows.append((f"{ts * 1e3:.1f}", f"{(ts - t_stop) * 1e3:.1f}", m - 1,
                     " / ".join(f"{e:.3g}" for e in frozen),
                     " / ".join(f"{e:.3g}" for e in about_eq),
                     f"{r.max():.3g}", f"{kappa:.3g}", f"{alpha:.3g}", f"{gamma:.3g}", f"{bound:.3g}",
                     f"{err_states:.3g}"))
    print(f"Frozen linearisation after the stop (t_stop = {t_stop * 1e3:.1f} ms), exact on the "
          f"{dt * 1e3:g} ms grid, against the full run (compiled core, rtol 1e-10); errors [%] of "
          f"the excursion up to the stop: " + " / ".join(TRACES))
    print(text_table(("t_s [ms]", "after stop [ms]", "rows", "about x_s", "about x_eq",
                      "max |r| [1/s]", "cond(V)", "alpha [1/s]", "gamma", "bound |e| [-]",
                      "actual |e| [-]"), rows))

    # costs
    i, m, xs, J, f, M = frozen_at(args.switch[0])
    E = scipy.linalg.expm(M)
    lam, V = np.linalg.eig(J)
    Vinv = np.linalg.inv(V)
    d0 = X[i] / S - z_eq
    k = np.arange(m)

    def modal():   # every row at once: z_k = V diag(exp(lam k dt)) V^-1 d0
        return ((np.exp(np.outer(k * dt, lam)) * (Vinv @ d0)) @ V.T).real

    jac_ms = best_ms(lambda: solver.scaled_jacobian(float(t[i]), xs), args.repeat)
    expm_ms = best_ms(lambda: scipy.linalg.expm(M), max(args.repeat // 4, 3))
    eig_ms = best_ms(lambda: np.linalg.eig(J), max(args.repeat // 4, 3))
    loop_ms = best_ms(lambda: propagate(E, np.append(d0, 1.0), m), max(args.repeat // 4, 3))
    modal_ms = best_ms(modal, max(args.repeat // 4, 3))

    def integration_ms(**kw):   # the integration loop's wall (res.wall_time), least of repeat
        return min(sim.run(solver="compiled", **kw).wall_time for _ in range(args.repeat)) * 1e3

    full_ms = integration_ms()
    to_stop_ms = integration_ms(t_end=t_stop)
    after_rows = int(round((t[-1] - t_stop) / dt))
    print()
    print(f"Costs (least of {args.repeat} or {max(args.repeat // 4, 3)} calls: the runs' integration "
          f"wall, the rest CPU; one BLAS thread; "
          f"{n} states, {after_rows} rows after the stop)")
    print(text_table(("what", "CPU [ms]", "per row after the stop [us]"), [
        ("whole default run, compiled core (integration, warm)", f"{full_ms:.2f}", ""),
        ("run to the stop only (t_end = t_stop)", f"{to_stop_ms:.2f}", ""),
        ("  difference: the compiled core after the stop", f"{full_ms - to_stop_ms:.2f}",
         f"{(full_ms - to_stop_ms) / after_rows * 1e3:.2f}"),
        ("dense Jacobian at the switch state", f"{jac_ms:.3f}", ""),
        ("expm of the augmented scaled matrix (scipy)", f"{expm_ms:.2f}", ""),
        ("eigendecomposition of J (numpy)", f"{eig_ms:.2f}", ""),
        ("rest state x_eq (pseudo-transient, once)", f"{eq_ms:.1f}", ""),
        (f"exact stepping, E @ z per row ({m} rows)", f"{loop_ms:.2f}", f"{loop_ms / m * 1e3:.2f}"),
        (f"exact stepping, modal form, all rows at once ({m} rows)", f"{modal_ms:.2f}",
         f"{modal_ms / m * 1e3:.2f}"),
    ]))
    budget = float(t[-1]) / 90 * 1e3
    print(f"\n90x real time: the whole run in {budget:.2f} ms; the run to the stop leaves "
          f"{budget - to_stop_ms:.2f} ms for {after_rows} rows after it "
          f"({(budget - to_stop_ms) / after_rows * 1e3:.2f} us a row, signals included).")
    osc = np.sum((np.abs(lam.imag) > 1.0) & (lam.real > -2e3))
    print(f"Modes of J at the switch state: {osc} oscillatory with |Re| < 2000 1/s of {n}; "
          f"slowest decay {lam.real.max():.3g} 1/s.")


if __name__ == "__main__":
    main()
