"""Benchmark: what a user waits for (issue 25), every row of the issue's table cold and warm,
beside its target and Hopsan's figure where one exists, in one command.

Cold is a new user's first run: an empty hydroline cache (a fresh temporary directory as
``$HYDROLINE_CACHE_DIR`` for each run: no compiled library, no model record, no line tables);
Matplotlib's font cache and Python's bytecode are kept, as after an install; the detached
background build a cold run starts is awaited before the next run (its CPU is not the
command's: the cold cell's CPU is the command's own, its figure process included). Warm is the median
of ``--repeat`` runs after one warm-up in a cache of the benchmark's own. Whole processes are
timed from outside (``subprocess``: wall, and the children's CPU from ``getrusage``); the
in-process rows run in this process, with one BLAS thread as the command line has it.

Rows (the issue's table, then its targets):

* ``hydroline simulate --json``; with CSV and PNG (``--out``); ``layout``; ``bode``; ``fit``
  (of ``simulate``'s own record, the section II bulk moduli): cold and warm
* a rig file that changes one hose's bulk modulus, or one section's length (a value no run
  has seen: whole process in the warm cache, against the unchanged rig's warm run, and the
  C libraries it compiled); a 6-variant sweep over the accumulator capacity (libraries
  compiled)
* ``hydroline.simulate()`` with new numbers in one process (the accumulator capacity changed
  before each call), and the integration's share and real-time factor on the default rig
* the layout sweep's variants (``benchmarks/bench_sweep.py``, 2 workers, scaled to 1000)
* cost against the model's size (item 5): 30 against 6 modes per section (the integration's
  CPU time, least of ``--repeat``: a ratio other jobs move less than a wall time) and the
  first build of 30 modes in an empty cache; a 4-axis rig against a 1-axis one
  (``two_axis.toml``'s axis 2 copied, or dropped; integration CPU, least of ``--repeat``)

Usage: python benchmarks/bench_user.py [--repeat 5] [--cold 2] [--sweep 200] [--only ROWS]
       ROWS: comma-separated of simulate,out,layout,bode,fit,changed,api,sweep,modes,axes
"""
from __future__ import annotations

import argparse
import os
import resource
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")     # as the command line asks (before NumPy loads)

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from tables import text_table  # noqa: E402

#: The command a user types (the installed script), else ``python -m hydroline``
BIN = ([str(Path(sys.executable).with_name("hydroline"))]
       if Path(sys.executable).with_name("hydroline").exists() else [sys.executable, "-m", "hydroline"])
#: The children run as a user's would: Python caches compiled bytecode (with
#: PYTHONDONTWRITEBYTECODE set, as in some sandboxes, every process compiles hydroline's
#: modules from source again, ~0.13 s a command).
CHILD_ENV = {k: v for k, v in os.environ.items()
             if k not in ("PYTHONDONTWRITEBYTECODE", "HYDROLINE_CACHE_DIR")}
#: Hopsan's whole process on the default rig (its start-up 7 ms), [s]
HOPSAN_WHOLE_PROCESS = 0.084
ROWS = ("simulate", "out", "layout", "bode", "fit", "changed", "api", "sweep", "modes", "axes")
BULK = "supply.section2.bulk_modulus,return.section2.bulk_modulus"


def run(cmd, cache: Path, cwd: Path) -> tuple[float, float]:
    """Wall and CPU [s] of one whole process with ``cache`` as its hydroline cache."""
    env = dict(CHILD_ENV, HYDROLINE_CACHE_DIR=str(cache))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    tic = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, env=env, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - tic
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, cmd))} failed: {proc.stderr.strip()[-500:]}")
    return wall, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def background_builds_ended(cache: Path) -> None:
    """Wait until no background build goes on in ``cache`` (each holds its library's lock
    until it ends): a cold run's build, detached, would otherwise share the CPU with the
    next run."""
    import fcntl

    for lock in cache.glob("*.lock"):
        with open(lock) as f:
            fcntl.flock(f, fcntl.LOCK_EX)


def cold_and_warm(cmd, warm_cache: Path, work: Path, cold: int, repeat: int):
    """(cold cell, warm wall): the medians of ``cold`` runs each in an empty cache (its
    background build awaited before the next run) as "wall (CPU ...)" text, the command's
    CPU with its figure process, not the detached build; the median wall [s] of ``repeat``
    runs after a warm-up in ``warm_cache``."""
    colds = []
    for _ in range(cold):
        with tempfile.TemporaryDirectory(dir=work) as empty:
            colds.append(run(cmd, Path(empty), work))
            background_builds_ended(Path(empty))
    run(cmd, warm_cache, work)
    background_builds_ended(warm_cache)   # (the warm-up's build: not beside the warm runs)
    warms = [run(cmd, warm_cache, work)[0] for _ in range(repeat)]
    cell = (f"{s(statistics.median(w for w, _ in colds))} "
            f"(CPU {s(statistics.median(c for _, c in colds))})") if colds else "-"
    return cell, statistics.median(warms)


def libraries(cache: Path) -> int:
    """Compiled libraries in a cache directory."""
    return len(list(cache.glob("hl_*.so")))


def rig_file(work: Path, name: str, text: str) -> Path:
    path = work / name
    path.write_text(text)
    return path


def changed_numbers(warm_cache: Path, work: Path, repeat: int, unchanged: float) -> list:
    """Whole processes of rigs that differ from the default in one number never run before,
    in the warm cache: (what, wall [s], ratio to the unchanged warm run, libraries built)."""
    rows = []
    for what, table, key, values in (
            ("one hose's bulk modulus", "supply.section1", "bulk_modulus",
             [f'"{190 + 0.37 * k:.2f} MPa"' for k in range(repeat)]),
            ("one section's length", "supply.section2", "length",
             [f'"{2.5 + 0.0131 * k:.4f} m"' for k in range(repeat)])):
        walls, built = [], 0
        for k, value in enumerate(values):
            rig = rig_file(work, f"changed_{key}_{k}.toml",
                           f'[rig]\nbase = "default"\n\n[{table}]\n{key} = {value}\n')
            n0 = libraries(warm_cache)
            walls.append(run([*BIN, "simulate", str(rig), "--json"], warm_cache, work)[0])
            built += libraries(warm_cache) - n0
        wall = statistics.median(walls)
        rows.append((what, wall, wall / unchanged, built, len(values)))
    return rows


def capacity_sweep(warm_cache: Path, work: Path) -> tuple[float, int]:
    """A 6-variant sweep over the supply accumulator's capacity, 2 workers, in the warm cache:
    wall [s] and libraries compiled."""
    n0 = libraries(warm_cache)
    with tempfile.TemporaryDirectory(dir=work) as out:
        wall, _ = run([*BIN, "sweep", "--set",
                       "supply.accumulator.capacity=0.5 L,0.75 L,1.5 L,2 L,3 L,4 L",
                       "--workers", "2", "--out", out, "--json"], warm_cache, work)
    return wall, libraries(warm_cache) - n0


def new_numbers_in_process(repeat: int):
    """``hydroline.simulate()`` with a new accumulator capacity before each call: median wall
    per call [s] and its integration [s]; the default rig's integration (same numbers) [s],
    each result dropped before the next run as in the first row (a program that keeps every
    result gets each run's table, 3.3 MB, on memory no run has touched: its page faults,
    ~1.5 ms a run on the 2-core test machine, fall in the integration, which writes the rows
    into it), the same with every result kept [s], and its simulated time [s]."""
    import hydroline

    rig = hydroline.load_rig()
    res = hydroline.simulate(rig)
    calls, integ = [], []
    for k in range(max(repeat, 5) * 4):
        rig.set("supply.accumulator.capacity", f"{1.0 + 0.0137 * (k + 1):.4f} L")
        tic = time.perf_counter()
        res = hydroline.simulate(rig)
        calls.append(time.perf_counter() - tic)
        integ.append(res.wall_time)
    same = hydroline.load_rig()
    hydroline.simulate(same)
    dropped, kept = [], []
    for _ in range(max(repeat, 5) * 4):
        res = hydroline.simulate(same)
        dropped.append(res.wall_time)
    for _ in range(max(repeat, 5) * 4):
        kept.append(hydroline.simulate(same))
    return (statistics.median(calls), statistics.median(integ), statistics.median(dropped),
            statistics.median(r.wall_time for r in kept), res.t[-1])


def layout_sweep(variants: int):
    """The layout sweep (bench_sweep.py) on 2 workers: wall per 1000 variants [s], failed."""
    import numpy as np
    from bench_sweep import sweep as run_sweep

    run_sweep(np.linspace(0.05, 3.048, 8), 2)   # warm both workers' caches
    rows, wall = run_sweep(np.linspace(0.05, 3.048, variants), 2)
    return wall * 1000 / variants, sum("error" in r for r in rows)


def best_integration(rig, repeat: int) -> float:
    """Least CPU time [s] of the compiled integration over ``repeat`` runs of a rig (after one
    that builds it): CPU, not wall, so that other jobs on the machine move the ratios of
    these rows less (the integration runs in this thread); the run's wall time where the
    backend cannot be timed so."""
    import hydroline
    from hydroline.engine import backends

    backend = getattr(backends, "CompiledBackend", None)
    spent = [0.0]
    original = getattr(backend, "advance", None)

    def advance(self, *args, **kwargs):
        tic = time.thread_time()
        try:
            return original(self, *args, **kwargs)
        finally:
            spent[0] += time.thread_time() - tic

    hydroline.simulate(rig)
    best = float("inf")
    if original is None:
        return min(hydroline.simulate(rig).wall_time for _ in range(max(repeat, 3)))
    backend.advance = advance
    try:
        for _ in range(max(repeat, 3)):
            spent[0] = 0.0
            hydroline.simulate(rig)
            best = min(best, spent[0])
    finally:
        backend.advance = original
    return best


#: Run in an empty cache: the first simulate() of 30 modes per section, and the time its
#: compiled model took to build (C written and compiled: NativeModel.build_time)
FIRST_BUILD = """
import time, hydroline, hydroline.compiled as compiled
built = []
init = compiled.NativeModel.__init__
def record(self, network, *args, **kwargs):
    init(self, network, *args, **kwargs)
    built.append(self.build_time)
compiled.NativeModel.__init__ = record
rig = hydroline.load_rig()
rig.set("rig.modes_per_section", 30)
tic = time.perf_counter()
hydroline.simulate(rig)
print(sum(built), time.perf_counter() - tic)
"""


def modes_rows(work: Path, repeat: int):
    """30 against 6 modes per section: integration CPU (least of twice ``repeat``); the first build
    of 30 modes in an empty cache (C written and compiled, [s]) and its whole first
    ``simulate()`` [s]."""
    import hydroline

    times = {}
    for modes in (6, 30):
        rig = hydroline.load_rig()
        rig.set("rig.modes_per_section", modes)
        times[modes] = best_integration(rig, 2 * repeat)
    with tempfile.TemporaryDirectory(dir=work) as empty:
        out = subprocess.run([sys.executable, "-c", FIRST_BUILD], env=dict(
            CHILD_ENV, HYDROLINE_CACHE_DIR=empty), capture_output=True, text=True, check=True)
    build, first = (float(v) for v in out.stdout.split()[-2:])
    return times[6], times[30], build, first


def axis_rig(n: int, work: Path) -> Path | None:
    """``two_axis.toml`` with ``n`` axes: its ``[circuit.axis2]`` instance of the shared
    ``[subcircuit.axis]`` copied as axis 3.., or dropped for one, and the manifolds'
    junctions' terms and ports made to match; None where its layout is not the one this
    edits."""
    from importlib import resources

    text = resources.files("hydroline.rigs").joinpath("two_axis.toml").read_text()
    block = re.search(r"^\[circuit\.axis2\][^\n]*\n(?:(?!\[|#|\n).*\n)*", text, re.M)
    terms = "axis1 = 1, axis2 = 1, "
    if block is None or text.count(terms) != 2:
        return None
    text = text.replace(terms, "".join(f"axis{k} = 1, " for k in range(1, n + 1)))
    for kind in ("supply_hose_inflow", "return_hose_outflow"):
        old = f'axis1 = "axis1.{kind}", axis2 = "axis2.{kind}", '
        if old not in text:
            return None
        text = text.replace(old, "".join(f'axis{k} = "axis{k}.{kind}", '
                                         for k in range(1, n + 1)))
    axis2 = block.group(0)
    copies = "".join(axis2.replace("axis2", f"axis{k}") for k in range(2, n + 1))
    text = text.replace(axis2, copies, 1)
    return rig_file(work, f"axes_{n}.toml", text)


def axes_rows(work: Path, repeat: int):
    """Integration CPU of a 1-axis and a 4-axis rig (least of twice ``repeat``), [s]; None
    where the rigs cannot be made."""
    import hydroline

    paths = [axis_rig(n, work) for n in (1, 4)]
    if None in paths:
        return None
    return tuple(best_integration(hydroline.load_rig(str(p)), 2 * repeat) for p in paths)


def yardstick() -> float:
    """Seconds of a fixed pure-Python loop (best of 3): the machine's speed, to compare tables
    taken in different sessions."""
    best = float("inf")
    for _ in range(3):
        tic = time.perf_counter()
        total = 0
        for i in range(10_000_000):
            total += i
        best = min(best, time.perf_counter() - tic)
    return best


def s(x) -> str:
    """A duration [s] as text."""
    if x is None:
        return "-"
    return f"{x * 1e3:.1f} ms" if x < 0.1 else (f"{x * 1e3:.0f} ms" if x < 1 else f"{x:.2f} s")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="warm runs per row (median)")
    ap.add_argument("--cold", type=int, default=2, help="cold runs per row (median)")
    ap.add_argument("--sweep", type=int, default=200, help="variants of the layout sweep (0: skip)")
    ap.add_argument("--only", default=",".join(ROWS), help="rows: " + ",".join(ROWS))
    args = ap.parse_args()
    only = set(args.only.split(","))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        cache = work / "cache"
        os.environ["HYDROLINE_CACHE_DIR"] = str(cache)      # this process's rows too
        warm_json = None
        if only & {"simulate", "changed"}:
            cold, warm_json = cold_and_warm([*BIN, "simulate", "--json"], cache, work,
                                            args.cold, args.repeat)
            rows.append(("hydroline simulate --json (whole process)", cold, s(warm_json),
                         "cold <= 1.0 s, warm <= 0.2 s",
                         f"{HOPSAN_WHOLE_PROCESS * 1e3:.0f} ms (start-up 7 ms)"))
        if "out" in only:
            cold, warm = cold_and_warm([*BIN, "simulate", "--out", str(work / "out")], cache,
                                       work, args.cold, args.repeat)
            rows.append(("hydroline simulate with CSV + PNG", cold, s(warm), "cold <= 1.5 s",
                         ""))
        for name in ("layout", "bode"):
            if name in only:
                cold, warm = cold_and_warm([*BIN, name, "--out", str(work / name)], cache, work,
                                           args.cold, args.repeat)
                rows.append((f"hydroline {name}", cold, s(warm), "cold <= 2 s", ""))
        if "fit" in only:
            run([*BIN, "simulate", "--out", str(work / "record")], cache, work)
            cold, warm = cold_and_warm([*BIN, "fit", str(work / "record" / "results.csv"),
                                        "--params", BULK, "--out", str(work / "fit")],
                                       cache, work, args.cold, args.repeat)
            rows.append(("hydroline fit (section II bulk moduli)", cold, s(warm),
                         "cold <= 2 s", ""))
        if "changed" in only:
            for what, wall, ratio, built, runs in changed_numbers(cache, work, args.repeat,
                                                                  warm_json):
                rows.append((f"rig file changing {what} (whole process)", "",
                             f"{s(wall)} = {ratio:.2f}x unchanged, {built} of {runs} compiled",
                             "<= 1.2x unchanged, none compiled", ""))
            wall, built = capacity_sweep(cache, work)
            rows.append(("sweep of 6 accumulator capacities, 2 workers", "",
                         f"{s(wall)}, {built} of 6 compiled", "none compiled", ""))
        if "api" in only:
            call, integ, same, kept, t_end = new_numbers_in_process(args.repeat)
            rows.append(("hydroline.simulate() with new numbers, in-process", "",
                         f"{s(call)} ({s(integ)} integration)", "<= 15 ms", ""))
            rows.append(("integration, default scenario", "",
                         f"{s(same)}, {t_end / same:.0f}x real time",
                         ">= 50x (stretch 90x) at the issue's accuracy", ""))
            rows.append(("  the same, every result kept (fresh memory)", "",
                         f"{s(kept)}, {t_end / kept:.0f}x real time", "", ""))
        if "sweep" in only and args.sweep:
            per_1000, failed = layout_sweep(args.sweep)
            rows.append((f"layout sweep, 2 workers ({args.sweep} variants, scaled)", "",
                         f"{per_1000:.1f} s per 1000 ({failed} failed)", "<= 5 s", ""))
        if "modes" in only:
            six, thirty, build, first = modes_rows(work, args.repeat)
            rows.append(("30 modes per section: integration CPU against 6", "",
                         f"{s(thirty)} / {s(six)} = {thirty / six:.1f}x", "<= 4x", ""))
            rows.append(("30 modes per section: first build (C written, compiled)", s(build),
                         "", "<= 3 s", ""))
            rows.append(("30 modes per section: first simulate()", s(first), "", "", ""))
        if "axes" in only:
            axes = axes_rows(work, args.repeat)
            got = "n/a (two_axis.toml not in the layout copied)" if axes is None else \
                f"{s(axes[1])} / {s(axes[0])} = {axes[1] / axes[0]:.1f}x"
            rows.append(("4 axes against 1: integration CPU", "", got, "<= 4x", ""))
    print(f"hydroline, Python {sys.version.split()[0]}, {os.cpu_count()} CPUs; cold: median of "
          f"{args.cold} in an empty cache, warm: median of {args.repeat} after a warm-up; load "
          f"average {os.getloadavg()[0]:.1f} (other jobs inflate every figure: compare runs at "
          f"equal load); yardstick: a 10-million-step Python loop takes {yardstick():.2f} s "
          f"on this machine now")
    if "PYTHONDONTWRITEBYTECODE" in os.environ:
        print("PYTHONDONTWRITEBYTECODE is set here: the timed processes ran without it, as a "
              "user's do (bytecode cached)")
    print(text_table(("what", "cold", "warm", "target", "Hopsan"), rows))


if __name__ == "__main__":
    main()
