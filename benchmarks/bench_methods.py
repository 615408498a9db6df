"""Benchmark: which integration *method* would take fewer steps on the default scenario (issue 13
item 4), counted rather than timed.

The compiled core's BDF (orders 1-5) needs ~3 500 steps for the default scenario's 0.25 s at
the accuracy target; 150x real time would need ~2.5-4x less work. This script counts, at equal
accuracy, what other kinds of method would need, all on the *same* right-hand side (the
compiled model's f through ``NativeSolver.rhs``, so only counts mean anything here, not
times):

* ``bdf``: SciPy's BDF (the algorithm the C core follows), rtol 1e-6;
* ``dop853``: an explicit Runge-Kutta method of order 8 (Dormand-Prince, SciPy);
* ``radau``: the implicit Runge-Kutta method Radau IIA of order 5 (SciPy, exact finite-
  difference Jacobian), at several tolerances, to find the one with today's error;
* ``imex``: an additive (implicit-explicit) Runge-Kutta method of order 5, ARK5(4)8L[2]SA of
  Kennedy & Carpenter (Appl. Numer. Math. 44 (2003) 139-181, coefficients from their paper),
  with the actuator's chamber pressures and velocity implicit (where the Jacobian's stiff
  eigenvalues live: -5.5e4 1/s at rest, -7.8e4 1/s after the stop) and the other 55 states
  explicit. A plain prototype: simplified Newton on the 3 implicit states per stage, error
  from the embedded order-4 solution, PI step control.

Per method: steps (and where in time they fall: at rest before the step, while the piston
moves, after it stops), f evaluations, LU factorizations where there are any, and the largest
error of the valve port pressures and piston velocity against a CVODES rtol 1e-10 reference,
in % of each signal's excursion (as ``bench_integrator.py``). Each run calls f from Python
(~6 us a call): the script takes ~2 min.

Usage: python benchmarks/bench_methods.py [--only bdf,radau,dop853,imex]
"""
from __future__ import annotations

import argparse

import numpy as np

from tables import text_table

#: Phases of the default open-loop step (0.25 s): at rest, valve step at 10 ms, piston
#: moving ~0.015-0.11 s, at its stop from ~0.115 s with the hoses ringing.
PHASES = [(0.0, 0.01, "rest"), (0.01, 0.115, "moving"), (0.115, 0.25, "at the stop")]
KEYS = ("supply_port_pressure", "return_port_pressure", "piston_velocity")


def problem():
    """The default scenario's network from its solved steady state, its compiled f, the state
    scales and the CVODES rtol 1e-10 reference of the compared signals on the output grid."""
    from hydroline.compiled import native_model
    from hydroline.rigs import load_rig
    from hydroline.scenarios import build_scenario
    from hydroline.simulation import integrate, solve_steady_state
    from hydroline.system import build_network

    rig = load_rig(None)
    sc = build_scenario(rig, "open-loop-step")
    net = build_network(rig, sc.commands, sc.position_guess)
    ss = solve_steady_state(net)
    ref = integrate(net, ss.x, sc.t_end, p=ss.p, rtol=1e-10, atol_scale=1e-10, solver="cvodes")
    return dict(net=net, x0=np.asarray(ss.x, float), p=np.asarray(ss.p, float), t_end=sc.t_end,
                solver=native_model(net).solver(ss.p), t=np.asarray(ref.t),
                scale=np.asarray(net.state_scales, float),
                ref={k: np.asarray(ref[k]) for k in KEYS})


class Counted:
    """f(t, x) through the compiled model, counting the calls."""

    def __init__(self, solver):
        self.solver, self.calls = solver, 0

    def __call__(self, t, x):
        self.calls += 1
        return self.solver.rhs(t, x)


def error_percent(prob, X) -> float:
    """Largest error of the compared signals [% of the reference's excursion]; X: states on
    the reference's output grid, one row per time."""
    model = prob["net"].compile()
    names = list(prob["net"].signal_names)
    n = len(prob["t"])
    Y = np.asarray(model.signals.map(n)(prob["t"][None, :], X.T,
                                        np.repeat(prob["p"][:, None], n, axis=1)))
    return max(np.max(np.abs(Y[names.index(k)] - prob["ref"][k])) / np.ptp(prob["ref"][k])
               for k in KEYS) * 100


def steps_per_phase(t_steps) -> list[int]:
    edges = [a for a, _, _ in PHASES] + [PHASES[-1][1] + 1.0]
    return list(np.histogram(np.asarray(t_steps)[1:], edges)[0])


def fd_jacobian(f, t, x, scale):
    """Forward-difference Jacobian [1/s]: steps of 1e-7 of each state's scale."""
    f0 = f(t, x)
    J = np.empty((len(x), len(x)))
    for j in range(len(x)):
        xp = x.copy()
        xp[j] += 1e-7 * scale[j]
        J[:, j] = (f(t, xp) - f0) / (1e-7 * scale[j])
    return J


def run_scipy(prob, method, rtol):
    from scipy.integrate import solve_ivp

    f = Counted(prob["solver"])
    options = {}
    if method != "DOP853":   # the Jacobian's evaluations are not counted as f
        g = Counted(prob["solver"])
        options["jac"] = lambda t, x: fd_jacobian(g, t, x, prob["scale"])
    sol = solve_ivp(f, (0.0, prob["t_end"]), prob["x0"], method=method, rtol=rtol,
                    atol=1e-7 * (rtol / 1e-6) * prob["scale"], dense_output=True, **options)
    if not sol.success:
        raise RuntimeError(sol.message)
    return dict(steps=len(sol.t) - 1, phases=steps_per_phase(sol.t), f=f.calls,
                lu=getattr(sol, "nlu", 0), err=error_percent(prob, sol.sol(prob["t"]).T))


def ark548_tables():
    """ARK5(4)8L[2]SA (Kennedy & Carpenter 2003, tables 5-6): explicit A, implicit A, b, the
    embedded b-hat, c."""
    g = 41 / 200
    ae, ai = np.zeros((8, 8)), np.zeros((8, 8))
    ae[1, 0] = 41 / 100
    ae[2, :2] = [367902744464 / 2072280473677, 677623207551 / 8224143866563]
    ae[3, [0, 2]] = [1268023523408 / 10340822734521, 1029933939417 / 13636558850479]
    ae[4, [0, 2, 3]] = [14463281900351 / 6315353703477, 66114435211212 / 5879490589093,
                        -54053170152839 / 4284798021562]
    ae[5, [0, 2, 3, 4]] = [14090043504691 / 34967701212078, 15191511035443 / 11219624916014,
                           -18461159152457 / 12425892160975, -281667163811 / 9011619295870]
    ae[6, [0, 2, 3, 4, 5]] = [19230459214898 / 13134317526959, 21275331358303 / 2942455364971,
                              -38145345988419 / 4862620318723, -1 / 8, -1 / 8]
    ae[7, [0, 2, 3, 4, 5, 6]] = [-19977161125411 / 11928030595625,
                                 -40795976796054 / 6384907823539,
                                 177454434618887 / 12078138498510,
                                 782672205425 / 8267701900261,
                                 -69563011059811 / 9646580694205,
                                 7356628210526 / 4942186776405]
    ai[1, :2] = [g, g]
    ai[2, :3] = [41 / 400, -567603406766 / 11931857230679, g]
    ai[3, [0, 2, 3]] = [683785636431 / 9252920307686, -110385047103 / 1367015193373, g]
    ai[4, [0, 2, 3, 4]] = [3016520224154 / 10081342136671, 30586259806659 / 12414158314087,
                           -22760509404356 / 11113319521817, g]
    ai[5, [0, 2, 3, 4, 5]] = [218866479029 / 1489978393911, 638256894668 / 5436446318841,
                              -1179710474555 / 5321154724896, -60928119172 / 8023461067671, g]
    ai[6, [0, 2, 3, 4, 5, 6]] = [1020004230633 / 5715676835656,
                                 25762820946817 / 25263940353407,
                                 -2161375909145 / 9755907335909,
                                 -211217309593 / 5846859502534,
                                 -4269925059573 / 7827059040749, g]
    b = np.zeros(8)
    b[[0, 3, 4, 5, 6, 7]] = [-872700587467 / 9133579230613, 22348218063261 / 9555858737531,
                             -1143369518992 / 8141816002931, -39379526789629 / 19018526304540,
                             32727382324388 / 42900044865799, g]
    ai[7] = b
    bhat = np.zeros(8)
    bhat[[0, 3, 4, 5, 6, 7]] = [-975461918565 / 9796059967033, 78070527104295 / 32432590147079,
                                -548382580838 / 3424219808633,
                                -33438840321285 / 15594753105479,
                                3629800801594 / 4656183773603, 4035322873751 / 18575991585200]
    c = ai.sum(axis=1)
    assert np.allclose(ae.sum(axis=1), c, atol=1e-12) and abs(b.sum() - 1) < 1e-12
    return ae, ai, b, bhat, c


def run_imex(prob, rtol=1e-6, implicit=("actuator.bottom_pressure", "actuator.top_pressure",
                                        "actuator.velocity")):
    """ARK5(4)8L[2]SA with the named states implicit, the others explicit; returns the same
    counts as :func:`run_scipy` (f includes the Newton iterations' evaluations; the 3 x 3
    Jacobians by differences are not counted)."""
    from scipy.interpolate import CubicHermiteSpline

    ae, ai, b, bhat, c = ark548_tables()
    g = ai[1, 1]
    names = list(prob["net"].state_names)
    S = np.array([names.index(k) for k in implicit])
    f = Counted(prob["solver"])
    rhs = prob["solver"].rhs
    scale, atol = prob["scale"], 1e-7 * (rtol / 1e-6) * prob["scale"]
    t, y, T = 0.0, prob["x0"].copy(), prob["t_end"]
    fy, h, err_old = f(t, y), 1e-5, 1.0
    ts, ys, fs = [t], [y.copy()], [fy.copy()]
    K = np.zeros((8, len(y)))
    while t < T * (1 - 1e-12):
        h = min(h, T - t)
        J = np.empty((len(S), len(S)))
        for k, j in enumerate(S):
            xp = y.copy()
            xp[j] += 1e-7 * scale[j]
            J[:, k] = (rhs(t, xp)[S] - fy[S]) / (1e-7 * scale[j])
        M = np.linalg.inv(np.eye(len(S)) - h * g * J)
        K[0], ok = fy, True
        for i in range(1, 8):
            z = y + h * (ae[i, :i] @ K[:i])                  # explicit states: final
            known = y[S] + h * (ai[i, :i] @ K[:i, S])
            z[S] = known + h * g * K[i - 1, S]
            for _ in range(8):                               # implicit states: Newton
                fz = f(t + c[i] * h, z)
                dz = -M @ (z[S] - known - h * g * fz[S])
                z[S] += dz
                if np.sqrt(np.mean((dz / (atol[S] + rtol * np.abs(z[S]))) ** 2)) < 0.03:
                    break
            else:
                ok = False
                break
            K[i] = f(t + c[i] * h, z)
            K[i, S] = (z[S] - known) / (h * g)
        if ok:
            y_new = y + h * (b @ K)
            w = atol + rtol * np.maximum(np.abs(y), np.abs(y_new))
            en = np.sqrt(np.mean((h * ((b - bhat) @ K) / w) ** 2))
        if ok and en <= 1.0:
            t, y = t + h, y_new
            fy = f(t, y)
            ts.append(t), ys.append(y.copy()), fs.append(fy.copy())
            h *= min(5.0, max(0.2, 0.9 * max(en, 1e-10) ** (-0.14) * err_old ** 0.08))
            err_old = max(en, 1e-4)
        else:
            h *= max(0.2, 0.9 * en ** -0.2) if ok else 0.25
    # states on the output grid: cubic Hermite between steps would add its own error, so the
    # error is taken at the steps against a reference interpolated there (the reference grid
    # is 0.1 ms; its interpolation error is far below the method's)
    spline = CubicHermiteSpline(np.array(ts), np.array(ys), np.array(fs))
    return dict(steps=len(ts) - 1, phases=steps_per_phase(ts), f=f.calls, lu=0,
                err=error_percent(prob, spline(prob["t"])))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="bdf,radau,dop853,imex")
    args = ap.parse_args(argv)
    chosen = args.only.split(",")
    prob = problem()
    runs = []
    if "bdf" in chosen:
        runs.append(("BDF 1-5 (SciPy)", 1e-6, lambda: run_scipy(prob, "BDF", 1e-6)))
    if "radau" in chosen:
        for rtol in (1e-6, 1e-5, 3e-5, 1e-4):
            runs.append(("Radau IIA 5 (SciPy)", rtol,
                         lambda rtol=rtol: run_scipy(prob, "Radau", rtol)))
    if "dop853" in chosen:
        for rtol in (1e-6, 1e-7):
            runs.append(("DOP853 (explicit)", rtol,
                         lambda rtol=rtol: run_scipy(prob, "DOP853", rtol)))
    if "imex" in chosen:
        runs.append(("ARK5(4)8L IMEX", 1e-6, lambda: run_imex(prob)))
    head = ["method", "rtol", "steps", "rest", "moving", "at the stop", "f evals", "LU",
            "max err [%]"]
    rows = []
    for label, rtol, fn in runs:
        r = fn()
        rows.append([label, f"{rtol:g}", r["steps"], *r["phases"], r["f"], r["lu"] or "-",
                     f"{r['err']:.2e}"])
        print(f"  {label} rtol {rtol:g}: {r['steps']} steps", flush=True)
    print("Methods on the default scenario (0.25 s), f from the compiled model; steps per "
          "phase: rest 0-10 ms, moving 10-115 ms, at the stop 115-250 ms")
    print(text_table(head, rows))


if __name__ == "__main__":
    main()
