"""The rest state from the components' guess over a sweep of section II lengths (issue 25).

For each length (both section II hoses of the default rig, open-loop step): a fresh network
(no inverse Jacobian kept from another solve, no neighbour's rest state), then
:func:`hydroline.engine.solve_steady_state` timed (CPU and wall), with its Newton and shifted
steps (``SteadyState.newton_steps``, ``shifted_steps``; absent on older trees) and whether the
pseudo-transient continuation ran (counted by wrapping ``steady_state.pseudo_transient``, so
that the same script measures an older tree too: ``PYTHONPATH=/tmp/before python ...``).
``--save FILE`` writes the lengths and rest states (``.npz``) to compare two trees' states.

Usage: ``python benchmarks/bench_rest_state.py [--lengths 60] [--shortest 0.02]
[--longest 3.0] [--save FILE]``
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None):
    """Print one row per length and a summary.

    Parameters
    ----------
    argv : list
        Command-line arguments (``sys.argv[1:]`` when None)
    """
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lengths", type=int, default=60)
    ap.add_argument("--shortest", type=float, default=0.02)
    ap.add_argument("--longest", type=float, default=3.0)
    ap.add_argument("--save", default=None)
    args = ap.parse_args(argv)

    from hydroline.engine import steady_state
    from hydroline.rigs import load_rig
    from hydroline.scenarios import build_scenario
    from hydroline.system import build_network

    continued = []
    real = steady_state.pseudo_transient

    def counting(*a, **k):
        continued.append(1)
        return real(*a, **k)

    steady_state.pseudo_transient = counting

    def network(length):
        rig = load_rig(None)
        rig.set("supply.section2.length", f"{length!r} m")
        rig.set("return.section2.length", f"{length!r} m")
        sc = build_scenario(rig, "open-loop-step")
        return build_network(rig, sc.commands, sc.position_guess)

    steady_state.solve_steady_state(network(args.longest))     # the library loaded
    lengths = np.geomspace(args.shortest, args.longest, args.lengths)
    cpu, wall, states, fell_back, worst = [], [], [], 0, 0.0
    for L in lengths:
        net = network(float(L))
        continued.clear()
        c0, w0 = time.process_time(), time.perf_counter()
        ss = steady_state.solve_steady_state(net)
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
        states.append(ss.x)
        fell_back += bool(continued)
        worst = max(worst, ss.residual)
        print(f"{L:7.4f} m  {cpu[-1] * 1e3:8.1f} ms CPU {wall[-1] * 1e3:8.1f} ms wall  steps "
              f"{getattr(ss, 'newton_steps', '-')}/{getattr(ss, 'shifted_steps', '-')}  "
              f"continuation {'yes' if continued else 'no'}  residual {ss.residual:.1e} 1/s",
              flush=True)
    print(f"{len(lengths)} lengths {args.shortest}-{args.longest} m: CPU total {sum(cpu):.2f} s, "
          f"median {np.median(cpu) * 1e3:.1f} ms, max {max(cpu) * 1e3:.1f} ms; wall total "
          f"{sum(wall):.2f} s; continuation {fell_back}/{len(lengths)}; largest residual "
          f"{worst:.1e} 1/s")
    if args.save:
        np.savez(args.save, lengths=lengths, x=np.array(states), scales=net.state_scales)


if __name__ == "__main__":
    main()
