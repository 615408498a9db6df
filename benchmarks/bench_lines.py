"""Benchmark: line models on one hose, accuracy against the exact dissipative line and cost.

The hose is the default rig's supply section I. Each model gets a 1 MPa pressure step at its
upstream end with the downstream end blocked (PQ form, Q_d = 0) and runs ten wave periods
(40 L/c). Error: the downstream pressure against the exact dissipative model (M6), computed by
a numerical inverse Laplace transform (``exact_step_response``, wave-front Talbot), in % of the
step -- rms and max over the run at times more than 0.1 L/c away from the wave fronts (any
finite model smears the jumps of the exact response, by ~50 % of the step right at them). Cost: CPU time
per simulated second. The state-space models (modal Yang-Tobler, modal residue, lumped R-I-C
segments) run as a network with the compiled core (C code, sparse-Jacobian BDF, rtol 1e-6:
its error is far below every model's); the characteristics line runs as written (NumPy,
one vectorised update per time step dt = L/(N c)). "State updates per s": states times
right-hand-side evaluations (ODE models) or nodes times unknowns per node times time steps
(characteristics) per simulated second, a language-neutral measure of work.

Usage: python benchmarks/bench_lines.py
"""
from __future__ import annotations

import time

import numpy as np

import hydroline
from hydroline import components as comp
from hydroline.lines import ModalLine
from hydroline.lines.characteristics import CharacteristicsLine
from hydroline.lines.inverse_laplace import exact_step_response
from hydroline.lines.lumped import LumpedLine
from hydroline.network import Network
from hydroline.simulation import integrate
from hydroline.system import hose_lines

STEP = 1e6   # [Pa]


def network_for(model):
    return Network([
        comp.StepCommand(name="source", quantity="pressure", initial=STEP, final=STEP, time=0.0,
                         connections={"command": "pu"}),
        comp.StepCommand(name="blocked", quantity="flow", initial=0.0, final=0.0, time=0.0,
                         connections={"command": "qd"}),
        comp.HoseSection(name="hose", model=model, nominal_pressure=STEP,
                         connections={"upstream_pressure": "pu", "downstream_flow": "qd",
                                      "downstream_pressure": "pd", "upstream_flow": "qu"}),
    ])


def errors(t, y, line, exact_cache={}):
    """rms and max error [% of the step] at times more than 0.1 L/c away from the wave fronts
    (the downstream pressure of a blocked line jumps at odd multiples of L/c)."""
    key = (line.length, len(t), float(t[-1]))
    if key not in exact_cache:
        exact_cache[key] = exact_step_response(line, t, "PQ", (0, 0))
    e = y - exact_cache[key]
    away = np.abs((t / line.wave_time) % 2.0 - 1.0) > 0.1
    return 100 * np.sqrt(np.mean(e[away] ** 2)), 100 * np.max(np.abs(e[away]))


def run_state_space(model, line, t_end, dt_out, repeat=3):
    net = network_for(model)
    integrate(net, np.zeros(len(net.state_names)), t_end, dt_out=dt_out, solver="compiled")
    best, res = np.inf, None
    for _ in range(repeat):
        tic = time.process_time()
        res = integrate(net, np.zeros(len(net.state_names)), t_end, dt_out=dt_out,
                        solver="compiled", rtol=1e-6, atol_scale=1e-8)
        best = min(best, time.process_time() - tic)
    return res.t, res["pd"] / STEP, best, res.stats


def main():
    line = hose_lines(hydroline.load_rig())["supply.section1"]
    tau = line.wave_time
    t_end = 40 * tau
    dt_out = t_end / 2000
    print(f"Hose: default rig supply section I, L = {line.length:g} m, d = {line.diameter * 1e3:g} mm,"
          f" c = {line.wave_speed:.0f} m/s, Dn = {line.dissipation_number:.4f}; blocked end, "
          f"pressure step, ten wave periods ({t_end * 1e3:.1f} ms)")
    rows = []
    configs = [("modal Yang-Tobler", n, lambda n: ModalLine(line, n, "PQ")) for n in (6, 10, 20)]
    configs += [("modal residue", n, lambda n: ModalLine(line, n, "PQ", method="residue"))
                for n in (6, 10, 20)]
    configs += [("lumped R-I-C", n, lambda n: LumpedLine(line, n)) for n in (5, 10, 20, 40, 80)]
    for name, n, make in configs:
        try:
            model = make(n)
        except Exception as e:   # e.g. a method not available in this version
            rows.append([name, n, "-", "-", "-", "-", "-", f"unavailable: {e}"])
            continue
        t, y, cpu, st = run_state_space(model, line, t_end, dt_out)
        rms, late = errors(t, y, line)
        rows.append([name, n, model.n_states, f"{rms:.2f}", f"{late:.2f}",
                     f"{cpu / t_end * 1e3:.1f}", f"{st['nfevals'] * model.n_states / t_end:.2e}",
                     f"{st['nsteps']} steps, {st['nfevals']} f"])
    for n in (16, 32, 64, 128):
        moc = CharacteristicsLine(line, n)
        moc.step_response(t_end)   # warm-up
        best = np.inf
        for _ in range(3):
            tic = time.process_time()
            r = moc.step_response(t_end)
            best = min(best, time.process_time() - tic)
        t = np.asarray(r.t)
        keep = np.unique(np.linspace(0, len(t) - 1, min(len(t), 2001)).astype(int))
        rms, late = errors(t[keep], np.asarray(r.downstream_pressure)[keep], line)
        states = (n + 1) * (2 + moc.n_terms)
        rows.append(["characteristics", n, states, f"{rms:.2f}", f"{late:.2f}",
                     f"{best / t_end * 1e3:.1f}", f"{(len(t) - 1) * states / t_end:.2e}",
                     f"{len(t) - 1} steps of {moc.dt * 1e6:.1f} us"])
    head = ["model", "N", "states", "rms err [%]", "max err [%]",
            "CPU [ms per s simulated]", "state updates per s", "work"]
    widths = [max(len(str(r[i])) for r in rows + [head]) for i in range(len(head))]
    print("  ".join(h.rjust(w) for h, w in zip(head, widths)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(str(c).rjust(w) for c, w in zip(r, widths)))

    # equal accuracy: the cheapest configuration of each family under an rms error bound
    print("\nCheapest configuration per family at equal accuracy (rms error bound, away from fronts):")
    fam = {}
    for r in rows:
        if r[3] == "-":
            continue
        fam.setdefault(r[0], []).append((float(r[3]), float(r[5]), r[1]))
    for bound in (3.0, 1.6, 1.0, 0.5):
        best = {f: min((c, n) for e, c, n in v if e <= bound) if any(e <= bound for e, _, _ in v)
                else None for f, v in fam.items()}
        modal = [b for f, b in best.items() if f.startswith("modal") and b]
        ref = min(modal)[0] if modal else None
        parts = []
        for f, b in best.items():
            if b is None:
                parts.append(f"{f}: not reached")
            else:
                ratio = f" ({b[0] / ref:.0f}x modal)" if ref and not f.startswith("modal") else ""
                parts.append(f"{f} N={b[1]}: {b[0]:.1f} ms/s{ratio}")
        print(f"  rms <= {bound:g} %: " + "; ".join(parts))
    print("CPU = process time, best of 3, one core. State-space models: compiled C core "
          "(rtol 1e-6); characteristics: NumPy implementation.")


if __name__ == "__main__":
    main()
