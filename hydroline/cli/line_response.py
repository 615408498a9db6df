"""``hydroline line-response``: one hose, exact vs modal frequency response and resonances."""
from __future__ import annotations

import numpy as np

from ..fluid import Fluid, MINERAL_OIL
from ..lines import FORMS, Line, ModalLine
from ..lines.compare import compare_resonances
from ..plotting import plot_line_response
from .common import dump_json, out_dir, print_table, quantity


def register(sub):
    p = sub.add_parser("line-response", help="frequency response of one line: exact vs modal",
                       description="Magnitude and phase of every entry of a causal form, exact "
                       "(dissipative, M6) against the modal model(s); table of resonances.")
    p.add_argument("--length", required=True, help="line length, e.g. '3.048 m'")
    p.add_argument("--diameter", required=True, help="inner diameter, e.g. '12.7 mm'")
    p.add_argument("--bulk-modulus", help="effective bulk modulus, e.g. '2.07e8 Pa' (default: the oil's)")
    p.add_argument("--density", default="870 kg/m^3", help="oil density (default 870 kg/m^3)")
    p.add_argument("--viscosity", default="32 cSt", help="kinematic viscosity (default 32 cSt)")
    p.add_argument("--oil-bulk-modulus", default="1.5 GPa", help="oil bulk modulus (default 1.5 GPa)")
    p.add_argument("--modes", type=int, default=6, help="number of modes (default 6)")
    p.add_argument("--form", default="PQ", type=str.upper, choices=FORMS)
    p.add_argument("--method", default="both", choices=("yang-tobler", "residue", "both"),
                   help="modal method(s) to compare (default both)")
    p.add_argument("--out", default="hydroline-out", help="output folder for line_response.png")
    p.add_argument("--json", action="store_true", help="print the resonance table as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    fluid = Fluid(quantity(args.density, "kg/m^3", "--density"),
                  quantity(args.viscosity, "m^2/s", "--viscosity"),
                  quantity(args.oil_bulk_modulus, "Pa", "--oil-bulk-modulus"))
    beta = quantity(args.bulk_modulus, "Pa", "--bulk-modulus") if args.bulk_modulus else None
    line = Line(quantity(args.length, "m", "--length"), quantity(args.diameter, "m", "--diameter"),
                fluid, beta)
    methods = ("yang-tobler", "residue") if args.method == "both" else (args.method,)
    models = {}
    for m in methods:
        try:
            models[m] = ModalLine(line, args.modes, args.form, method=m)
        except ImportError:
            if args.method != "both":
                raise ValueError(f"--method {m} is not available in this installation") from None
    n = args.modes
    f_top = (n + 1) / (2 if args.form in ("PP", "QQ") else 4) * 2 / line.wave_time / 2
    f = np.linspace(f_top / 4000, f_top, 4000)
    out = out_dir(args.out)
    png = out / "line_response.png"
    plot_line_response(line, {f"modal {k}, n={n}": v for k, v in models.items()}, f, args.form, path=png)
    report = {"line": {"length_m": line.length, "diameter_m": line.diameter,
                       "wave_speed_m_s": line.wave_speed, "dissipation_number": line.dissipation_number,
                       "impedance_pa_s_m3": line.impedance}, "form": args.form, "resonances": []}
    rows = []
    for label, model in models.items():
        for r in compare_resonances(line, model):
            entry = r.entry_name(args.form)
            report["resonances"].append({
                "method": label, "entry": entry, "mode": r.mode,
                "exact_frequency_hz": r.exact_frequency_hz, "model_frequency_hz": r.model_frequency_hz,
                "frequency_error_pct": r.frequency_error_pct, "exact_peak": r.exact_magnitude,
                "model_peak": r.model_magnitude, "peak_error_pct": r.magnitude_error_pct})
            rows.append([label, entry, r.mode, r.exact_frequency_hz, r.frequency_error_pct,
                         r.exact_magnitude, r.magnitude_error_pct])
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
    print(f"wrote {png}")
    return 0
