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

Before that, a resonance table on the same hose (issue 2's frequency-domain check, both
methods side by side, issue 7): for every form and n = 6, 10, 20 modes, the worst error in
frequency and in peak magnitude of the first n resonances of every entry against the exact
dissipative model (M6), split into modes 1..n-1 and mode n (the one next to the first
dropped mode).

Then issue 7's time-domain check on the same hose, both methods side by side: blocked end,
unit pressure step, 20 wave periods, each model by its exact matrix exponential against the
exact response (``hydroline.cli.line_response.blocked_step_errors``): max and rms error,
max after two periods, and max for a step smoothed so that the n retained modes resolve it
(the raw step's error near the first wave fronts is truncation, ~half the jump, for any
finite modal line).

Usage: python benchmarks/bench_lines.py [--resonances-only | --accuracy-only]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import hydroline
from hydroline import components as comp
from hydroline.cli.line_response import blocked_step_errors
from hydroline.lines import FORMS, ModalLine
from hydroline.lines.compare import compare_resonances
from hydroline.lines.characteristics import CharacteristicsLine
from hydroline.lines.inverse_laplace import exact_step_response
from hydroline.lines.lumped import LumpedLine
from hydroline.engine import Network
from hydroline.engine import integrate
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


def resonance_table(line, modes=(6, 10, 20)):
    """Print the worst resonance errors per method, form and n against the exact line (M6)."""
    print(f"Resonances against the exact dissipative line: L = {line.length:g} m, "
          f"d = {line.diameter * 1e3:g} mm, Dn = {line.dissipation_number:.4f}; worst over "
          "the 4 entries, in %")
    head = ["method", "form", "n", "freq err", "peak err modes 1..n-1", "peak err mode n",
            "build [ms]"]
    rows = []
    for method in ("yang-tobler", "residue"):
        for form in FORMS:
            for n in modes:
                tic = time.perf_counter()
                model = ModalLine(line, n, form, method=method)
                build = 1e3 * (time.perf_counter() - tic)
                res = compare_resonances(line, model)
                if len(res) != 4 * n:
                    rows.append([method, form, n, f"{len(res)} of {4 * n} peaks found", "-", "-",
                                 f"{build:.0f}"])
                    continue
                fe = max(abs(r.frequency_error_pct) for r in res)
                inner = max((abs(r.magnitude_error_pct) for r in res if r.mode < n), default=0.0)
                top = max(abs(r.magnitude_error_pct) for r in res if r.mode == n)
                rows.append([method, form, n, f"{fe:.3f}", f"{inner:.2f}", f"{top:.2f}",
                             f"{build:.0f}"])
    widths = [max(len(str(r[i])) for r in rows + [head]) for i in range(len(head))]
    print("  ".join(h.rjust(w) for h, w in zip(head, widths)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(str(c).rjust(w) for c, w in zip(r, widths)))
    print()


def step_table(line, modes=(6, 10, 20), periods=20):
    """Print the blocked-line step errors per method and n (exact matrix exponential)."""
    print(f"Blocked end, unit pressure step, {periods} wave periods, against the exact "
          "dissipative response; error in % of the step")
    head = ["method", "n", "max", "rms", "max after 2 periods", "smoothed step max"]
    rows = []
    for n in modes:
        models = {m: ModalLine(line, n, "PQ", method=m) for m in ("yang-tobler", "residue")}
        _, _, _, err = blocked_step_errors(line, models, periods)
        for m, e in err.items():
            rows.append([m, n, f"{e['max_pct']:.2f}", f"{e['rms_pct']:.3f}",
                         f"{e['max_settled_pct']:.3f}", f"{e['max_smooth_pct']:.3f}"])
    widths = [max(len(str(r[i])) for r in rows + [head]) for i in range(len(head))]
    print("  ".join(h.rjust(w) for h, w in zip(head, widths)))
    print("  ".join("-" * w for w in widths))
    for r in sorted(rows, key=lambda r: (r[0], r[1])):
        print("  ".join(str(c).rjust(w) for c, w in zip(r, widths)))
    print()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resonances-only", action="store_true",
                    help="print the resonance table only (no time-domain runs)")
    ap.add_argument("--accuracy-only", action="store_true",
                    help="print the resonance and step-error tables only (no timing)")
    args = ap.parse_args(argv)
    line = hose_lines(hydroline.load_rig())["supply.section1"]
    resonance_table(line)
    if args.resonances_only:
        return
    step_table(line)
    if args.accuracy_only:
        return
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

    # equal accuracy: the cheapest configuration of each family under an error bound, by the
    # rms error away from the wave fronts and by the max error (which the fronts dominate)
    for col, what, bounds in ((3, "rms", (3.0, 1.6, 1.0, 0.5)), (4, "max", (15.0, 8.5, 4.5))):
        print(f"\nCheapest configuration per family at equal accuracy ({what} error bound; ratio "
              "in CPU, and in state updates per simulated second):")
        fam = {}
        for r in rows:
            if r[col] == "-":
                continue
            fam.setdefault(r[0], []).append((float(r[col]), float(r[5]), r[1], float(r[6])))
        for bound in bounds:
            best = {f: min((c, n, u) for e, c, n, u in v if e <= bound)
                    if any(e <= bound for e, *_ in v) else None for f, v in fam.items()}
            modal = [b for f, b in best.items() if f.startswith("modal") and b]
            ref = min(modal) if modal else None
            parts = []
            for f, b in best.items():
                if b is None:
                    parts.append(f"{f}: not reached")
                else:
                    ratio = (f" ({b[0] / ref[0]:.0f}x / {b[2] / ref[2]:.0f}x modal)"
                             if ref and not f.startswith("modal") else "")
                    parts.append(f"{f} N={b[1]}: {b[0]:.1f} ms/s{ratio}")
            print(f"  {what} <= {bound:g} %: " + "; ".join(parts))
    print("CPU = process time, best of 3, one core. State-space models: compiled C core "
          "(rtol 1e-6); characteristics: NumPy implementation.")


if __name__ == "__main__":
    main()
