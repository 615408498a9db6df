"""``hydroline simulate``: run a scenario on a rig; CSV, JSON summary and the pressure figure."""
from __future__ import annotations

import json
import sys

import numpy as np

from ..rigs import load_rig
from ..rigs.parameters import defaults_used
from ..scenarios import SCENARIOS, default_scenario, simulate, summarize
from .common import atomic_outputs, dump_json, out_dir, print_table, progress_printer, quantity

#: The files written to --out.
OUTPUT_FILES = ("results.csv", "summary.json", "pressures.png")


def register(sub):
    p = sub.add_parser("simulate", help="simulate the test system (default: the 2005 paper's rig, "
                       "50 mA open-loop step)",
                       description="Simulate a rig from its solved steady state. Writes results.csv, "
                       "summary.json and pressures.png to --out and prints a summary.")
    p.add_argument("rig", nargs="?", help="rig TOML file or the name of a shipped rig, e.g. "
                   "two_axis (default: the embedded Ayalew & Kulakowski 2005 rig)")
    p.add_argument("--scenario", default=None, choices=SCENARIOS,
                   help="experiment (default: the rig's rig.scenario, else open-loop-step)")
    p.add_argument("--t-end", help="simulated time with unit, e.g. '0.25 s' (scenario default)")
    p.add_argument("--out", default="hydroline-out", help="output folder (default: hydroline-out)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout only")
    p.add_argument("--solver", default="auto", choices=("auto", "compiled", "cvodes", "scipy"),
                   help="auto (default: the compiled C core where a C compiler exists, else "
                   "CVODES), compiled, cvodes (CasADi + SUNDIALS) or the reference SciPy path")
    p.set_defaults(func=run)


#: What ``--json`` prints (issue 3): per port, then the actuator and the wall time.
PORT_KEYS = ("frequency_hz", "amplitude_mpa", "settling_time_s")
JSON_KEYS = ("supply", "return", "actuator_natural_frequency_hz", "wall_time_s")


def json_summary(summary: dict) -> dict:
    """The ``--json`` document: exactly ``{"supply": {frequency_hz, amplitude_mpa,
    settling_time_s}, "return": {...}, "actuator_natural_frequency_hz", "wall_time_s"}``
    (floats, [Hz], [MPa], [s]; frequency and settling time null when there is none).
    ``summary.json`` keeps the extras (metrics window, warnings, tracking error)."""
    out = {side: {k: _float_or_none(summary[side][k]) for k in PORT_KEYS}
           for side in ("supply", "return")}
    # amplitude_mpa is 0.0 where no oscillation was detected and null only where the window
    # is too short to tell (summary.json and stderr say why)
    out["actuator_natural_frequency_hz"] = float(summary["actuator_natural_frequency_hz"])
    out["wall_time_s"] = float(summary["wall_time_s"])
    return out


def json_axes_summary(summary: dict) -> dict:
    """The ``--json`` document of a multi-axis rig: ``{"axes": {"<axis>": {"supply": {...},
    "return": {...}, "position_disturbance_mm": float or null (the stepped axis), ...}},
    "wall_time_s": float}`` ([Hz], [MPa], [s], [mm])."""
    axes = {}
    for name, a in summary["axes"].items():
        entry = {side: {k: _float_or_none(a[side][k]) for k in PORT_KEYS} for side in ("supply", "return")}
        for k in ("position_disturbance_mm", "position_change_mm", "actuator_natural_frequency_hz"):
            if k in a:
                entry[k] = _float_or_none(a[k])
        axes[name] = entry
    return {"axes": axes, "wall_time_s": float(summary["wall_time_s"])}


def _settling_cell(m):
    v = m["settling_time_s"]
    if v is None:
        return None
    return f"~{v * 1e3:.4g}" if m.get("settling_method") == "estimated" else v * 1e3


def _float_or_none(v):
    return None if v is None else float(v)


def _check_size(rig, scenario, t_end, out, name):
    """Rows and bytes of the run estimated before it starts: memory and free disk for
    results.csv (one line, ValueError, when it would not fit)."""
    from ..limits import check_output_size
    from ..scenarios import build_scenario
    from ..system import build_circuit

    circuit = build_circuit(rig)
    sc = build_scenario(rig, scenario, t_end, axes=circuit.axes)
    net = circuit.network(sc.commands)
    check_output_size(sc.t_end, 1e-4, len(net.signal_names) + len(net.state_names),
                      csv_folder=out, name=name or f"scenario.{scenario}.t_end")


def run(args) -> int:
    rig = load_rig(args.rig)
    t_end = quantity(args.t_end, "s", "--t-end") if args.t_end else None
    if t_end is not None and not t_end > 0:
        raise ValueError(f"--t-end must be > 0 s, got {args.t_end!r}")
    out = out_dir(args.out, OUTPUT_FILES)     # checked before the run, not after it
    scenario = args.scenario or default_scenario(rig)
    _check_size(rig, scenario, t_end, out, "--t-end" if args.t_end else None)
    defaults = defaults_used(rig, scenario)
    if defaults:   # every key that changes the result is given or reported (once)
        print("hydroline simulate: note: not in the rig, defaults used: "
              + "; ".join(f"{path} = {value}" for path, value in defaults), file=sys.stderr)
    res = simulate(rig, args.scenario, t_end, solver=args.solver,
                   progress=progress_printer("simulating", not args.json))
    summary = summarize(res)
    scenario = res.metadata["scenario"]
    with atomic_outputs(out) as temp:   # replaced together, or none (previous results kept)
        res.to_csv(temp("results.csv"))
        temp("summary.json").write_text(json.dumps(summary, indent=2) + "\n")
        if "axes" not in summary:       # (a multi-axis figure is drawn by _report_axes)
            res.plot(path=temp("pressures.png"),
                     title=f"{scenario} on {rig.get('rig.name', rig.source)}")
    if "axes" in summary:
        return _report_axes(args, rig, res, summary, scenario)
    if args.json:
        for w in summary["warnings"]:
            print(f"hydroline simulate: warning: {w}", file=sys.stderr)
        for side in ("supply", "return"):
            if summary[side].get("amplitude_note"):
                print(f"hydroline simulate: note: {side} port: {summary[side]['amplitude_note']}",
                      file=sys.stderr)
        dump_json(json_summary(summary))
        return 0
    print(f"hydroline simulate: {scenario} on {rig.get('rig.name', rig.source)}")
    print(f"  {res.metadata['n_states']} states, steady-state residual {res.steady_state.residual:.1e} 1/s, "
          f"wall time {summary['wall_time_s']:.2f} s "
          f"({res.t[-1] / max(res.wall_time, 1e-9):.1f}x real time in the integrator)")
    print(f"  {summary['metrics_window_note']}")
    if scenario == "closed-loop-sine":
        rows = [[f"{side} port", summary[side].get("ripple_pp_mpa"),
                 len(summary[side].get("ripple_pp_mpa_per_cycle", []))]
                for side in ("supply", "return")]
        print_table(["pressure", "ripple peak-to-peak, largest cycle [MPa]", "full cycles"], rows)
        print(f"  tracking error (reference - position): rms {summary['tracking_error_rms_mm']:.2f} mm, "
              f"max {summary['tracking_error_max_mm']:.2f} mm")
    else:
        rows = []
        for side in ("supply", "return"):
            m = summary[side]
            rows.append([f"{side} port", m["frequency_hz"], m["amplitude_mpa"],
                         m["first_excursion_mpa"], m["steady_change_mpa"], m["peak_to_peak_mpa"],
                         _settling_cell(m)])
        print_table(["pressure", "oscillation [Hz]", "amplitude [MPa]", "first excursion [MPa]",
                     "steady change [MPa]", "peak-to-peak [MPa]", "settling [ms]"], rows)
        print("  amplitude: half the largest swing about the pressure's one-period mean (+-);"
              " first excursion: largest |p - p0|; '~' settling estimated from the decay")
        for side in ("supply", "return"):
            m = summary[side]
            if m.get("amplitude_note"):
                print(f"  {side} port: {m['amplitude_note']}")
            elif m["settling_time_s"] is None and m.get("settling_note"):
                print(f"  {side} port settling '-': {m['settling_note']}")
    print(f"  actuator hydraulic natural frequency: {summary['actuator_natural_frequency_hz']:.1f} Hz")
    for w in summary["warnings"]:
        print(f"  WARNING: {w}")
    print(f"  wrote {out / 'results.csv'}, {out / 'summary.json'}, {out / 'pressures.png'}")
    return 0


def plot_axes(res, summary, path, title=""):
    """Per-axis figure of a multi-axis run: valve supply and return port pressures [MPa] and
    piston position change [mm] of every axis against time [ms]; the metrics window shaded.

    Parameters
    ----------
    res : SimulationResult   The run (``metadata["axes"]`` holds the handles)
    summary : dict           Its summary (for the metrics window)
    path : str or Path       PNG to write
    title : str              Figure title
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    axes = res.metadata["axes"]
    t0, t1 = summary["metrics_window_s"]
    fig, ax = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    t = res.t * 1e3
    i0 = int(np.searchsorted(res.t, t0))
    for name, a in axes.items():
        ax[0].plot(t, res[a.supply_pressure] / 1e6, label=name)
        ax[1].plot(t, res[a.return_pressure] / 1e6, label=name)
        x = res[a.position]
        ax[2].plot(t, (x - x[i0]) * 1e3, label=name)
    for a_, lab in zip(ax, ("Supply port [MPa]", "Return port [MPa]", "Position change [mm]")):
        a_.set_ylabel(lab)
        a_.axvspan(t0 * 1e3, t1 * 1e3, color="0.93", zorder=0)
        a_.legend(loc="best", fontsize=8)
        a_.grid(alpha=0.3)
    ax[2].set_yscale("symlog", linthresh=1e-4)
    ax[2].set_xlabel("time [ms]")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _report_axes(args, rig, res, summary, scenario) -> int:
    """Print a multi-axis run: per axis the port metrics and the position disturbance."""
    out = out_dir(args.out)
    plot_axes(res, summary, out / "pressures.png", f"{scenario} on {rig.get('rig.name', rig.source)}")
    if args.json:
        for w in summary["warnings"]:
            print(f"hydroline simulate: warning: {w}", file=sys.stderr)
        dump_json(json_axes_summary(summary))
        return 0
    print(f"hydroline simulate: {scenario} on {rig.get('rig.name', rig.source)}")
    print(f"  {res.metadata['n_states']} states, wall time {summary['wall_time_s']:.2f} s")
    print(f"  {summary['metrics_window_note']}")
    rows = []
    for name, a in summary["axes"].items():
        for side in ("supply", "return"):
            m = a[side]
            rows.append([f"{name} {side} port", m["frequency_hz"], m["amplitude_mpa"],
                         m.get("first_excursion_mpa"), m.get("peak_to_peak_mpa"), _settling_cell(m)])
    print_table(["pressure", "oscillation [Hz]", "amplitude [MPa]", "first excursion [MPa]",
                 "peak-to-peak [MPa]", "settling [ms]"], rows)
    for name, a in summary["axes"].items():
        d = a["position_disturbance_mm"]
        what = (f"moved {a['position_change_mm']:.3g} mm (driven by the experiment)" if d is None
                else f"position disturbance {d * 1e3:.3g} um")
        print(f"  {name}: {what}")
    for w in summary["warnings"]:
        print(f"  warning: {w}")
    print(f"  wrote {out / 'results.csv'}, {out / 'summary.json'}, {out / 'pressures.png'}")
    return 0
