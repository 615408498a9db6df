"""``hydroline line-response``: one hose, exact vs modal frequency response, resonances and
the blocked-end pressure step.

Writes ``line_response.png`` (magnitude and phase of every entry of the chosen form, exact
dissipative model (M6) against each modal method, up to the frequency that
:func:`hydroline.lines.compare.compare_resonances` scans, so every tabulated resonance is on
the plot) and, unless ``--no-step``, ``line_step_response.png``: the blocked line (PQ form,
Q_d = 0) under a unit step of P_u, P_d over ``--step-periods`` wave periods (4 L/c each),
exact (numerical inverse Laplace transform of (M6),
:func:`hydroline.lines.inverse_laplace.exact_step_response`) against each method, with the
error in % of the step. Prints the resonance table and the step-error table (issue 7's
time-domain check), both methods side by side.
"""
from __future__ import annotations

import numpy as np

from ..fluid import Fluid
from ..lines import FORMS, Line, ModalLine, StateSpaceLine
from ..lines.compare import compare_resonances, resonance_f_max
from ..lines.inverse_laplace import exact_step_response
from ..plotting import plot_line_response
from .common import atomic_outputs, dump_json, out_dir, print_table, quantity

#: Most modes a line response computes (the frequency axis and the modal matrices grow with
#: them: 40 modes take ~1 GB and ~40 s on one core), [-].
MAX_MODES = 40
#: Longest blocked-end step, in wave periods, [-].
MAX_STEP_PERIODS = 1000

#: Samples per wave period (4 L/c) of the blocked-line step, [-].
STEP_SAMPLES_PER_PERIOD = 50

#: The step error "after the fronts have spread" is taken after this many wave periods, [-].
STEP_SETTLE_PERIODS = 2


def register(sub):
    """Add the ``hydroline line-response`` subcommand and its options to the command's parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers object of the ``hydroline`` parser
        (from ``add_subparsers``); ``run`` is set as the
        subcommand's ``func``
    """
    p = sub.add_parser("line-response", help="frequency response of one line: exact vs modal",
                       description="Magnitude and phase of every entry of a causal form, exact "
                       "(dissipative, M6) against the modal model(s); table of resonances; "
                       "blocked-end pressure step against the exact response.")
    p.add_argument("--length", required=True, help="line length, e.g. '3.048 m'")
    p.add_argument("--diameter", required=True, help="inner diameter, e.g. '12.7 mm'")
    p.add_argument("--bulk-modulus", help="effective bulk modulus, e.g. '2.07e8 Pa' (default: the oil's)")
    p.add_argument("--density", default="870 kg/m^3", help="oil density (default 870 kg/m^3)")
    p.add_argument("--viscosity", default="32 cSt", help="kinematic viscosity (default 32 cSt)")
    p.add_argument("--oil-bulk-modulus", default="1.5 GPa", help="oil bulk modulus (default 1.5 GPa)")
    p.add_argument("--creep-compliance", default=None,
                   help="viscoelastic wall (M44): creep compliances J_k of the Kelvin-Voigt "
                        "elements, comma-separated, e.g. '2e-10 1/Pa,1e-10 1/Pa' (default: "
                        "an elastic wall); the figure then also shows the elastic line")
    p.add_argument("--retardation-time", default=None,
                   help="their retardation times tau_k, e.g. '5 ms,50 ms'")
    p.add_argument("--modes", type=int, default=6, help="number of modes (default 6)")
    p.add_argument("--form", default="PQ", type=str.upper, choices=FORMS)
    p.add_argument("--method", default="both", choices=("yang-tobler", "residue", "both"),
                   help="modal method(s) to compare (default both)")
    p.add_argument("--step-periods", type=int, default=20,
                   help="wave periods (4 L/c each) of the blocked-end pressure step (default 20)")
    p.add_argument("--no-step", action="store_true",
                   help="skip the blocked-end pressure step (its exact response takes ~1 s)")
    p.add_argument("--out", default="hydroline-out",
                   help="output folder for line_response.png and line_step_response.png")
    p.add_argument("--json", action="store_true", help="print the tables as JSON")
    p.set_defaults(func=run)


def smooth_step_filter(line: Line, n_modes: int):
    """A step that n modes resolve: four real lags in series, ``W(s) = prod a_k/(s + a_k)``.

    ``a_k = (4/T) (0.8, 0.93, 1.07, 1.2)``, ``T = 20/omega_n``, ``omega_n = (n - 1/2) pi c/L``
    (M9): rise time ~0.6 L/c for n = 10, ``|W| < 1e-3`` at the first dropped mode, W(0) = 1.

    Parameters
    ----------
    line : Line
        The line (its wave time L/c sets the filter's corners)
    n_modes : int
        Modes of the models the step is for, [-]

    Returns
    -------
    W : callable
        ``W(s)``, the filter's transfer function, [-]
    (A, B, C) : tuple of ndarray
        Its state-space form (one input, one output), [1/s]
    """
    omega_n = (n_modes - 0.5) * np.pi / line.wave_time
    a = 4.0 / (20.0 / omega_n) * np.array([0.8, 0.93, 1.07, 1.2])
    A = np.diag(-a) + np.diag(a[1:], -1)
    B = np.zeros((4, 1))
    B[0, 0] = a[0]
    C = np.zeros((1, 4))
    C[0, 3] = 1.0

    def W(s):
        s = np.asarray(s)
        return np.prod(a / (s[..., None] + a), axis=-1)

    return W, (A, B, C)


class _Filtered(StateSpaceLine):
    """A line model whose first input passes through a SISO filter first (series)."""

    def __init__(self, model, A_f, B_f, C_f):
        nf, nm = A_f.shape[0], model.n_states
        self.A = np.block([[A_f, np.zeros((nf, nm))], [model.B[:, :1] @ C_f, model.A]])
        self.B = np.vstack([np.hstack([B_f, np.zeros((nf, 1))]), np.zeros((nm, 2))])
        self.C = np.hstack([np.zeros((2, nf)), model.C])
        self.D = np.zeros((2, 2))


def blocked_step_errors(line: Line, models: dict, periods: int = 20,
                        samples_per_period: int = STEP_SAMPLES_PER_PERIOD):
    """Blocked end (PQ, Q_d = 0), unit step of P_u: each model's P_d against the exact one.

    Parameters
    ----------
    line : Line
        The line
    models : dict
        label -> PQ-form model (:class:`StateSpaceLine`), all with the same
        number of modes ``n_modes``
    periods : int
        Wave periods (4 L/c each) simulated, >= 1, [-]
    samples_per_period : int
        Time samples per wave period, [-]

    Returns
    -------
    t : ndarray
        Times, [s]
    exact : ndarray
        The exact response, [Pa/Pa]
    responses : dict
        Label -> the model's response, [Pa/Pa]
    errors : dict
        Label -> dict of errors in % of the step: ``max_pct``, ``rms_pct`` over the
        whole run, ``max_settled_pct`` after ``STEP_SETTLE_PERIODS`` wave periods, and
        ``max_smooth_pct``, over the whole run, for the step through
        :func:`smooth_step_filter`

    Notes
    -----
    The exact response jumps at the wave fronts, which no finite modal model follows
    (~half the jump next to the first ones, Gibbs; on lightly damped lines the ringing
    lasts many periods), hence the smoothed step, which the retained modes resolve: its
    error measures the model, not truncation.
    """
    if int(periods) != periods or periods < 1:
        raise ValueError(f"--step-periods must be an integer >= 1, got {periods!r}")
    tau = line.wave_time
    t = np.linspace(0.0, 4 * periods * tau, samples_per_period * periods + 1)[1:]
    exact = exact_step_response(line, t, "PQ", (0, 0))
    n = max(m.n_modes for m in models.values()) if models else 1
    W, filt = smooth_step_filter(line, n)
    exact_smooth = exact_step_response(line, t, "PQ", (0, 0), input_filter=W)
    settled = t > 4 * STEP_SETTLE_PERIODS * tau
    responses, errors = {}, {}
    for label, model in models.items():
        y = model.step_response(t, 0)[:, 0]
        ys = _Filtered(model, *filt).step_response(t, 0)[:, 0]
        e = np.abs(y - exact)
        responses[label] = y
        errors[label] = {"max_pct": 100 * float(e.max()),
                         "rms_pct": 100 * float(np.sqrt(np.mean(e**2))),
                         "max_settled_pct": 100 * float(e[settled].max()) if settled.any() else None,
                         "max_smooth_pct": 100 * float(np.abs(ys - exact_smooth).max())}
    return t, exact, responses, errors


def plot_step(line, t, exact, responses, path):
    """Two panels: P_d/P_u step of the blocked line, and model minus exact in % of the step.

    Parameters
    ----------
    line : Line
        The line (length, diameter, dissipation number in the title)
    t : ndarray
        Time samples, [s]
    exact : ndarray
        Exact P_d/P_u step response at ``t`` (as
        :func:`blocked_step_errors` returns it), [-]
    responses : dict
        label -> model's P_d/P_u step response at ``t``, [-]
    path : str or Path
        PNG to write
    """
    from ..plotting import new_figure, save_png, tight_layout

    fig = new_figure((9, 6.5))
    ay, ae = fig.subplots(2, 1, sharex=True)
    x = t / (4 * line.wave_time)
    ay.plot(x, exact, "k", lw=1.4, label=("viscoelastic wall, " if line.viscoelastic else "")
            + "exact (dissipative, inverse Laplace)")
    for label, y in responses.items():
        ay.plot(x, y, "--", lw=1.0, label=label)
        ae.plot(x, 100 * (y - exact), lw=0.9, label=label)
    ay.set_ylabel("P_d / P_u step [-]")
    ae.set_ylabel("model - exact [% of step]")
    ae.set_ylim(-10, 10)
    ae.axvline(STEP_SETTLE_PERIODS, color="0.6", lw=0.8, ls=":")
    ae.set_xlabel("time [wave periods 4 L/c]")
    for ax in (ay, ae):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    fig.suptitle(f"blocked line, pressure step: L = {line.length:g} m, d = {line.diameter * 1e3:g} mm, "
                 f"Dn = {line.dissipation_number:.3g}")
    tight_layout(fig)
    save_png(fig, path, dpi=100)


def _models(line, n, form, methods, strict):
    out = {}
    for m in methods:
        try:
            out[m] = ModalLine(line, n, form, method=m)
        except ImportError:
            if strict:
                raise ValueError(f"--method {m} is not available in this installation") from None
    return out


def run(args) -> int:
    """Run ``hydroline line-response``: one hose's exact vs modal frequency response, resonances and blocked-end pressure step.

    Bad input raises a ``ValueError`` (or one of its kind) whose one-line message
    :func:`hydroline.cli.main` prints.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line, with the options :func:`register` adds

    Returns
    -------
    int
        Exit code, 0 on success
    """
    fluid = Fluid(quantity(args.density, "kg/m^3", "--density"),
                  quantity(args.viscosity, "m^2/s", "--viscosity"),
                  quantity(args.oil_bulk_modulus, "Pa", "--oil-bulk-modulus"))
    beta = quantity(args.bulk_modulus, "Pa", "--bulk-modulus") if args.bulk_modulus else None
    creep = tuple(quantity(v, "1/Pa", "--creep-compliance")
                  for v in (args.creep_compliance or "").split(",") if v.strip())
    times = tuple(quantity(v, "s", "--retardation-time")
                  for v in (args.retardation_time or "").split(",") if v.strip())
    elastic = Line(quantity(args.length, "m", "--length"), quantity(args.diameter, "m", "--diameter"),
                   fluid, beta)
    line = Line(elastic.length, elastic.diameter, fluid, beta, creep, times) if creep or times \
        else elastic
    if args.step_periods < 1:
        raise ValueError(f"--step-periods must be an integer >= 1, got {args.step_periods!r}")
    if not 1 <= args.modes <= MAX_MODES:
        raise ValueError(f"--modes must be an integer within 1 ... {MAX_MODES} [-] (memory and "
                         f"time grow about with its square: {MAX_MODES} modes take ~1 GB), got "
                         f"{args.modes}")
    if args.step_periods > MAX_STEP_PERIODS:
        raise ValueError(f"--step-periods must be at most {MAX_STEP_PERIODS} [-], got "
                         f"{args.step_periods}")
    out = out_dir(args.out)           # checked before the responses are computed
    methods = ("yang-tobler", "residue") if args.method == "both" else (args.method,)
    if line.viscoelastic and args.method == "both":
        methods = ("residue",)          # the Yang-Tobler line has an elastic wall only
    n = args.modes
    models = _models(line, n, args.form, methods, args.method != "both")
    wall = "viscoelastic wall, " if line.viscoelastic else ""
    curves = {f"{wall}modal {k}, n={n}": v for k, v in models.items()}
    references = None
    if line.viscoelastic:               # elastic vs viscoelastic (M44), on the figure
        references = {"elastic wall, exact (dissipative)": elastic}
        curves[f"elastic wall, modal residue, n={n}"] = ModalLine(elastic, n, args.form,
                                                                  method="residue")
    # frequency axis: up to the scan limit of compare_resonances, so every tabulated
    # resonance is on the plot
    f_top = resonance_f_max(line, args.form, n)
    f = np.linspace(f_top / 4000, f_top, 4000)
    with atomic_outputs(out) as temp:   # the figures replaced together, or none
        png = out / "line_response.png"
        extra = {}                      # viscoelastic wall: its title and the elastic line
        if line.viscoelastic:
            extra["references"] = references
            extra["title"] = (f"{args.form} line: L = {line.length:g} m, d = {line.diameter * 1e3:g} mm, "
                     f"Dn = {line.dissipation_number:.3g}; viscoelastic wall J = "
                     + ", ".join(f"{J:.3g}" for J in line.creep_compliances) + " 1/Pa, tau = "
                     + ", ".join(f"{1e3 * t:.3g}" for t in line.retardation_times) + " ms")
        plot_line_response(line, curves, f, args.form, path=temp(png.name), **extra)
        report = {"line": {"length_m": line.length, "diameter_m": line.diameter,
                           "wave_speed_m_s": line.wave_speed, "dissipation_number": line.dissipation_number,
                           "impedance_pa_s_m3": line.impedance}, "form": args.form, "resonances": []}
        rows = []
        for label, model in models.items():
            for r in compare_resonances(line, model, f_max=f_top):
                entry = r.entry_name(args.form)
                report["resonances"].append({
                    "method": label, "entry": entry, "mode": r.mode,
                    "exact_frequency_hz": r.exact_frequency_hz, "model_frequency_hz": r.model_frequency_hz,
                    "frequency_error_pct": r.frequency_error_pct, "exact_peak": r.exact_magnitude,
                    "model_peak": r.model_magnitude, "peak_error_pct": r.magnitude_error_pct})
                rows.append([label, entry, r.mode, r.exact_frequency_hz, r.frequency_error_pct,
                             r.exact_magnitude, r.magnitude_error_pct])
        report["figures"] = [str(png)]

        step_rows = []
        if not args.no_step:
            pq = models if args.form == "PQ" else _models(line, n, "PQ", list(models), False)
            t, exact, responses, errors = blocked_step_errors(line, pq, args.step_periods)
            step_png = out / "line_step_response.png"
            plot_step(line, t, exact, {f"{wall}modal {k}, n={n}": y for k, y in responses.items()},
                      temp(step_png.name))
            report["figures"].append(str(step_png))
            report["step_response"] = {"case": "blocked end (PQ, Q_d = 0), unit step of P_u; error of "
                                               "P_d in % of the step",
                                       "periods": args.step_periods, "settle_periods": STEP_SETTLE_PERIODS,
                                       "errors": [{"method": k, "modes": n, **v} for k, v in errors.items()]}
            step_rows = [[k, n, v["max_pct"], v["rms_pct"], v["max_settled_pct"], v["max_smooth_pct"]]
                         for k, v in errors.items()]
    if args.json:
        dump_json(report)
        return 0
    print(f"line: L = {line.length:g} m, d = {line.diameter * 1e3:g} mm, c = {line.wave_speed:.1f} m/s, "
          f"Z0 = {line.impedance:.3g} Pa s/m^3, Dn = {line.dissipation_number:.3g}; form {args.form}")
    print_table(["method", "entry", "mode", "f exact [Hz]", "f error [%]", "peak exact [SI]",
                 "peak error [%]"], rows)
    for label in models:
        sel = [r for r in rows if r[0] == label]
        print(f"worst {label}: frequency {max(abs(r[4]) for r in sel):.3f} %, "
              f"peak {max(abs(r[6]) for r in sel):.2f} %")
    if step_rows:
        print(f"\nblocked end, unit pressure step, {args.step_periods} wave periods: P_d error "
              "against the exact response, % of the step")
        print_table(["method", "modes", "max [%]", "rms [%]",
                     f"max after {STEP_SETTLE_PERIODS} periods [%]", "smoothed step max [%]"],
                    step_rows)
        print("(the exact response jumps at the wave fronts, which a finite modal line cannot "
              "follow: ~half the jump\n next to the first ones, ringing after; the smoothed "
              "step, resolved by the modes, measures the model)")
    for p in report["figures"]:
        print(f"wrote {p}")
    return 0
