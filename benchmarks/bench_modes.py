"""Benchmark: cost against the model's size (issue 25 item 5): the default rig at several
modes per section, the first build in an empty cache and the integration.

Per ``rig.modes_per_section``: the states; the compiled core's size (C source, bordered
Jacobian nonzeros, LU slots and flops); the first build in an empty cache (a fresh
``$HYDROLINE_CACHE_DIR``, in its own process: wall, this process's CPU, the C compiler's CPU
and peak memory); the integration of the default scenario (the least CPU time of
``--repeat`` runs in one process, which other jobs on the machine move less than a wall time;
its wall time beside it), its steps and its ratio to the first row. Run it under another
source tree (``PYTHONPATH=TREE python benchmarks/bench_modes.py``) for a before/after table.

Usage: python benchmarks/bench_modes.py [--modes 6,10,20,30] [--repeat 7] [--no-build]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")     # as the command line asks (before NumPy loads)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tables import text_table  # noqa: E402

#: Run in an empty cache (its own process): the first simulate() at ``modes``, with its
#: compiled model's build (C written and compiled) timed; prints one JSON line.
FIRST_BUILD = """
import json, resource, sys, time
import hydroline, hydroline.compiled as compiled
built = []
init = compiled.NativeModel.__init__
def record(self, network, *args, **kwargs):
    init(self, network, *args, **kwargs)
    built.append((self.build_time, self.generated))
compiled.NativeModel.__init__ = record
rig = hydroline.load_rig()
rig.set("rig.modes_per_section", int(sys.argv[1]))
rig.set("rig.allow_implausible", ["rig.modes_per_section"])
tic, cpu = time.perf_counter(), time.process_time()
hydroline.simulate(rig)
wall, cpu = time.perf_counter() - tic, time.process_time() - cpu
child = resource.getrusage(resource.RUSAGE_CHILDREN)
build, gen = built[0]
print(json.dumps({"build": build, "first": wall, "cpu": cpu,
                  "cc_cpu": child.ru_utime + child.ru_stime, "cc_mb": child.ru_maxrss / 1024,
                  "states": gen.n_states, "source_kb": len(gen.source) / 1e3,
                  "lu_slots": gen.lu_slots, "lu_flops": gen.lu_flops}))
"""


def first_build(modes: int) -> dict:
    """The first build and simulate() at ``modes`` per section in an empty cache."""
    with tempfile.TemporaryDirectory() as empty:
        env = dict(os.environ, HYDROLINE_CACHE_DIR=empty)
        out = subprocess.run([sys.executable, "-c", FIRST_BUILD, str(modes)], env=env,
                             capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def integration(modes: int, repeat: int) -> tuple[float, float, int]:
    """(least CPU [s], least wall [s], steps) of the compiled integration of the default
    scenario at ``modes`` per section, over ``repeat`` runs after one that builds it."""
    import hydroline
    from hydroline.engine import backends

    backend = backends.CompiledBackend
    original = backend.advance
    spent = [0.0]

    def advance(self, *args, **kwargs):
        tic = time.thread_time()
        try:
            return original(self, *args, **kwargs)
        finally:
            spent[0] += time.thread_time() - tic

    rig = hydroline.load_rig()
    rig.set("rig.modes_per_section", modes)
    rig.set("rig.allow_implausible", ["rig.modes_per_section"])
    hydroline.simulate(rig)
    backend.advance = advance
    cpu = wall = float("inf")
    try:
        for _ in range(repeat):
            spent[0] = 0.0
            res = hydroline.simulate(rig)
            cpu, wall = min(cpu, spent[0]), min(wall, res.wall_time)
    finally:
        backend.advance = original
    return cpu, wall, res.stats["nsteps"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--modes", default="6,10,20,30", help="modes per section, comma-separated")
    ap.add_argument("--repeat", type=int, default=7, help="integrations per row (least)")
    ap.add_argument("--no-build", action="store_true", help="skip the first builds")
    args = ap.parse_args()
    modes = [int(m) for m in args.modes.split(",")]
    rows, base = [], None
    with tempfile.TemporaryDirectory() as cache:
        os.environ["HYDROLINE_CACHE_DIR"] = cache
        for m in modes:
            b = {} if args.no_build else first_build(m)
            cpu, wall, steps = integration(m, args.repeat)
            base = base or cpu
            rows.append((m, b.get("states", ""), f"{b['source_kb']:.0f}" if b else "",
                         b.get("lu_slots", ""), b.get("lu_flops", ""),
                         f"{b['build']:.2f}" if b else "", f"{b['first']:.2f}" if b else "",
                         f"{b['cpu']:.2f} + {b['cc_cpu']:.2f}" if b else "",
                         f"{b['cc_mb']:.0f}" if b else "",
                         f"{cpu * 1e3:.1f}", f"{wall * 1e3:.1f}", steps, f"{cpu / base:.2f}"))
            print(f"  ({m} modes done)", file=sys.stderr, flush=True)
    print(f"load average {os.getloadavg()[0]:.1f}; first build in an empty cache, its own "
          f"process; integration: least of {args.repeat} runs")
    print(text_table(("modes", "states", "C kB", "LU slots", "LU flops", "build s", "first s",
                      "CPU s (py + cc)", "cc MB", "integ CPU ms", "wall ms", "steps", "x"),
                     rows))


if __name__ == "__main__":
    main()
