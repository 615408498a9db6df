"""Write a rig's plant as an FMI 2.0 FMU (Model Exchange and/or Co-Simulation).

The FMU holds the plant's generated C (:mod:`hydroline.compiled.codegen`: right-hand side,
exact sparse Jacobian, signals, sparse LU), hydroline's BDF integrator (``bdf.c``) and an FMI
2.0 wrapper (``fmi2_wrapper.c``), compiled by the system C compiler for this platform into
``binaries/<platform>/``; the same sources are in ``sources/`` so other platforms can build
them. Nothing in the FMU needs Python.
"""
from __future__ import annotations

import datetime
import hashlib
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from .. import compiled
from ..compiled.codegen import generate
from ..rigs import Rig, load_rig
from .plant import INPUTS, OUTPUTS, Plant, rest_state, symbolic_model

__all__ = ["export_fmu", "FMI_VERSIONS", "KINDS", "platform_folder", "C_FLAGS"]

FMI_VERSIONS = (2,)
KINDS = ("cs", "me", "both")
#: Flags for the FMU's binary: portable (no -march=native), symbols hidden but the fmi2 API.
C_FLAGS = ["-O2", "-std=c99", "-shared", "-fPIC", "-fvisibility=hidden", "-fno-math-errno"]
_HERE = Path(__file__).parent
#: Scaled residual below which the start state counts as at rest, [1/s] (as solve_steady_state)
STEADY_TOL = 1e-9

#: FMI unit name -> SI base-unit exponents
_UNITS = {
    "Pa": {"kg": 1, "m": -1, "s": -2}, "m3/s": {"m": 3, "s": -1}, "m3": {"m": 3},
    "m/s": {"m": 1, "s": -1}, "m": {"m": 1}, "A": {"A": 1}, "N": {"kg": 1, "m": 1, "s": -2},
    "kg": {"kg": 1}, "N/m": {"kg": 1, "s": -2}, "N.s/m": {"kg": 1, "s": -1},
    "Pa.s/m3": {"kg": 1, "m": -4, "s": -1}, "m.s": {"m": 1, "s": 1}, "s": {"s": 1},
}
#: Typical magnitudes of the inputs (directional derivatives by differences), [SI]
_INPUT_NOMINAL = {"valve_current": 0.05, "external_force": 1e3, "pump_pressure": 1e7,
                  "tank_pressure": 1e5}


def platform_folder() -> str:
    """FMI 2.0 binaries folder of this platform (``linux64``, ``darwin64``, ``win64``, ...)."""
    bits = "64" if sys.maxsize > 2**32 else "32"
    if sys.platform.startswith("linux"):
        return "linux" + bits
    if sys.platform == "darwin":
        return "darwin" + bits
    if sys.platform in ("win32", "cygwin"):
        return "win" + bits
    return sys.platform + bits


def _library_suffix() -> str:
    return {"darwin": ".dylib", "win32": ".dll", "cygwin": ".dll"}.get(sys.platform, ".so")


def _fmi_unit(unit: str) -> str:
    u = unit.replace("^", "").replace(" ", ".").replace("*", ".")
    return "" if u in ("-", "", "1") else u


def _c_array(ctype, name, values, fmt=repr):
    body = ",\n  ".join(",".join(fmt(v) for v in values[i:i + 6]) for i in range(0, len(values), 6))
    return f"static const {ctype} {name}[] = {{\n  {body or '0'}\n}};"


def _c_double(v: float) -> str:
    v = float(v)
    if not np.isfinite(v):
        raise ValueError(f"non-finite constant {v!r} in the generated model")
    return repr(v)


def _c_string(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def model_identifier(name: str) -> str:
    """A C identifier from a file stem: letters, digits and '_' (FMI 2.0 modelIdentifier)."""
    ident = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in name)
    if not ident or not (ident[0].isalpha() or ident[0] == "_"):
        ident = "hl_" + ident
    return ident


class _Layout:
    """Value references and descriptions of every FMU variable."""

    def __init__(self, plant: Plant, gen):
        net = plant.network
        self.n, self.ny = gen.n_states, gen.n_signals
        self.m = len(net.parameter_names)
        self.np = self.m + len(plant.tunables)
        self.vr_der, self.vr_sig, self.vr_par = self.n, 2 * self.n, 2 * self.n + self.ny
        self.signal_units = {}
        for s in net.signal_names:
            c, port = net.producer[s]
            self.signal_units[s] = _fmi_unit(c.outputs[port].unit)
        self.state_units = [_fmi_unit(st.unit) for c in net.components for st in c.states]


def _model_description(plant: Plant, gen, lay: _Layout, ident: str, guid: str, kinds: set,
                       stop_time: float) -> str:
    net = plant.network
    vars_, outputs, derivatives, initial_unknowns = [], [], [], []
    used_units = set()

    def var(name, vr, description, causality, variability, initial=None, unit="", start=None,
            extra=""):
        attrs = [f"name={quoteattr(name)}", f'valueReference="{vr}"',
                 f"description={quoteattr(description)}", f'causality="{causality}"',
                 f'variability="{variability}"']
        if initial:
            attrs.append(f'initial="{initial}"')
        real = []
        if unit:
            real.append(f'unit="{unit}"')
            used_units.add(unit)
        if start is not None:
            real.append(f'start="{float(start)!r}"')
        real.append(extra)
        vars_.append(f"    <ScalarVariable {' '.join(attrs)}>\n"
                     f"      <Real {' '.join(r for r in real if r)}/>\n    </ScalarVariable>")
        return len(vars_)    # 1-based index in ModelVariables

    # inputs (runtime parameters of the plant), then tunable parameters
    for name, k in plant.inputs.items():
        _, unit, meaning = INPUTS[name]
        var(name, lay.vr_par + k, meaning,
            "input", "continuous", unit=_fmi_unit(unit), start=plant.p[k])
    for j, tun in enumerate(plant.tunables):
        var(tun.name, lay.vr_par + lay.m + j, tun.description, "parameter", "tunable", "exact",
            unit=tun.unit, start=plant.tunable_values[j])
    # outputs and the other signals
    hidden = set(plant.inputs)   # a signal equal to an input (valve_current, pump_pressure)
    for i, s in enumerate(net.signal_names):
        if s in OUTPUTS:
            idx = var(s, lay.vr_sig + i, OUTPUTS[s], "output", "continuous", "calculated",
                      unit=lay.signal_units[s])
            outputs.append(idx)
            initial_unknowns.append(idx)
        elif s not in hidden:
            c, port = net.producer[s]
            var(s, lay.vr_sig + i, f"{c.outputs[port].description} ({c.name}.{port})", "local",
                "continuous", "calculated", unit=lay.signal_units[s])
    # states and their derivatives
    state_index = []
    for i, s in enumerate(net.state_names):
        idx = var(s, i, "state of the plant (steady state solved at export)", "local",
                  "continuous", "approx", unit=lay.state_units[i], start=plant.x[i],
                  extra=f'nominal="{float(net.state_scales[i])!r}"')
        state_index.append(idx)
    for i, s in enumerate(net.state_names):
        du = lay.state_units[i]
        unit = (du + "/s") if du and "/" not in du else ""
        idx = var(f"der({s})", lay.vr_der + i, f"time derivative of {s}", "local", "continuous",
                  "calculated", extra=f'derivative="{state_index[i]}"')
        derivatives.append(idx)
    initial_unknowns += state_index + derivatives
    initial_unknowns.sort()
    units = []
    for u in sorted(used_units):
        base = _UNITS.get(u)
        if base:
            b = " ".join(f'{k}="{v}"' for k, v in base.items())
            units.append(f'    <Unit name="{u}">\n      <BaseUnit {b}/>\n    </Unit>')
        else:
            units.append(f'    <Unit name="{u}"/>')
    src = '      <SourceFiles>\n        <File name="fmi2_wrapper.c"/>\n      </SourceFiles>'
    common = (f'modelIdentifier="{ident}" canGetAndSetFMUstate="true" '
              f'canSerializeFMUstate="true" providesDirectionalDerivative="true"')
    parts = []
    if "me" in kinds:
        parts.append(f"  <ModelExchange {common} completedIntegratorStepNotNeeded=\"true\">\n{src}\n  </ModelExchange>")
    if "cs" in kinds:
        parts.append(f"  <CoSimulation {common} canHandleVariableCommunicationStepSize=\"true\" "
                     f"canInterpolateInputs=\"false\" maxOutputDerivativeOrder=\"0\">\n{src}\n  </CoSimulation>")
    desc = (f"hydroline plant of rig {plant.rig.get('rig.name', plant.rig.source)}: hoses, HSM, "
            f"accumulators, servovalve, actuator, friction, load; starts at the {plant.start} rest state")
    boolean = ('    <ScalarVariable name="solve_steady_state" valueReference="0" description='
               '"re-solve the rest state at the end of initialization when the start state is not '
               'at rest for the parameters and inputs set" causality="parameter" variability="fixed" '
               'initial="exact">\n      <Boolean start="true"/>\n    </ScalarVariable>')
    vars_.append(boolean)
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    from .. import __version__ as version

    def unknowns(indices, deps=None):
        return "\n".join(f'      <Unknown index="{i}"/>' for i in indices)

    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(ident)} guid="{guid}"
  description={quoteattr(desc)} generationTool="hydroline {version}"
  generationDateAndTime="{now}" variableNamingConvention="flat" numberOfEventIndicators="0">
{chr(10).join(parts)}
  <UnitDefinitions>
{chr(10).join(units)}
  </UnitDefinitions>
  <DefaultExperiment startTime="0.0" stopTime="{stop_time!r}" tolerance="1e-06"/>
  <ModelVariables>
{chr(10).join(vars_)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{unknowns(outputs)}
    </Outputs>
    <Derivatives>
{unknowns(derivatives)}
    </Derivatives>
    <InitialUnknowns>
{unknowns(initial_unknowns)}
    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def _data_header(plant: Plant, gen, lay: _Layout, guid: str, kinds: set) -> str:
    net = plant.network
    p0 = np.concatenate([plant.p, plant.tunable_values])
    nominal = np.maximum(np.abs(p0), 1e-300)
    for name, k in plant.inputs.items():
        nominal[k] = max(abs(p0[k]), _INPUT_NOMINAL[name])
    nominal[nominal == 0] = 1.0
    mirrors = []
    if "valve_current" in plant.inputs:   # the plant's current source: command.initial = final
        k = plant.inputs["valve_current"]
        mirrors.append((net.parameter_names.index("command.initial"), k))
    consts = gen.constants if gen.constants.size else np.zeros(1)
    lines = [
        "/* This FMU's numbers (written by hydroline.fmu). */",
        f"#define HL_FMU_GUID {_c_string(guid)}",
        f"#define HL_FMU_ME {int('me' in kinds)}",
        f"#define HL_FMU_CS {int('cs' in kinds)}",
        f"#define HL_FMU_RTOL 1e-6",
        f"#define HL_FMU_STEADY_TOL {STEADY_TOL!r}",
        f"#define HL_FMU_NMIRROR {len(mirrors)}",
        _c_array("double", "hl_fmu_c", consts, _c_double),
        _c_array("double", "hl_fmu_scale", net.state_scales, _c_double),
        _c_array("double", "hl_fmu_x0", plant.x, _c_double),
        _c_array("double", "hl_fmu_p0", p0, _c_double),
        _c_array("double", "hl_fmu_pnominal", nominal, _c_double),
        "static const int hl_fmu_mirror[][2] = {" + (",".join(f"{{{a},{b}}}" for a, b in mirrors)
                                                     or "{0,0}") + "};",
        _c_array("char*", "hl_fmu_state_names", net.state_names, _c_string),
        _c_array("char*", "hl_fmu_parameter_names",
                 list(net.parameter_names) + [t.name for t in plant.tunables], _c_string),
    ]
    return "\n".join(lines) + "\n"


def _compile(cc: str, src_dir: Path, out: Path) -> None:
    cmd = [cc, *C_FLAGS, "-o", str(out), str(src_dir / "fmi2_wrapper.c"), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise compiled.CompilerUnavailable(f"C compiler failed on the FMU sources: "
                                           f"{proc.stderr.strip()[:2000]}")


def export_fmu(rig: Rig | str | None = None, out="hydroline.fmu", fmi: int = 2, kind: str = "cs",
               start: str = "open-loop-step", stop_time: float | None = None) -> Path:
    """Export the rig's plant as an FMU.

    Parameters
    ----------
    rig : Rig, str or None   The rig (a path, or None for the embedded default)
    out : path               The .fmu file to write; its stem is the modelIdentifier
    fmi : int                FMI version (2)
    kind : str               "cs" (Co-Simulation: hydroline's BDF integrator between
                             communication points), "me" (Model Exchange: the ODE, the
                             importer integrates), or "both"
    start : str              Scenario whose rest state the FMU starts from
                             ("open-loop-step" or "closed-loop-sine", see
                             :func:`hydroline.fmu.plant.rest_state`)
    stop_time : float        DefaultExperiment stop time, [s] (the scenario's t_end if None)

    Returns
    -------
    Path  The FMU written

    Raises
    ------
    ValueError             Bad arguments (one line)
    CompilerUnavailable    No C compiler, or it failed
    """
    if fmi not in FMI_VERSIONS:
        raise ValueError(f"--fmi: FMI {fmi} export is not available; give 2 (FMI 2.0)")
    if kind not in KINDS:
        raise ValueError(f"--kind: must be one of {', '.join(KINDS)}, got {kind!r}")
    out = Path(out)
    if out.suffix.lower() != ".fmu":
        raise ValueError(f"--out: an FMU file name ends in .fmu, got {str(out)!r}")
    cc = compiled._compiler()
    if cc is None:
        raise compiled.CompilerUnavailable("no C compiler found (set CC, or install gcc): the FMU's "
                                           "binary is built with the system C compiler")
    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    plant = rest_state(rig, start)
    gen = generate(symbolic_model(plant))
    lay = _Layout(plant, gen)
    if stop_time is None:
        from ..scenarios import build_scenario
        stop_time = build_scenario(rig, start).t_end
    kinds = {"cs", "me"} if kind == "both" else {kind}
    ident = model_identifier(out.stem)
    digest = hashlib.sha256((gen.source + repr(plant.x.tolist()) + repr(plant.p.tolist())
                             + repr(plant.tunable_values.tolist()) + ident + kind).encode())
    guid = "{" + str(uuid.UUID(bytes=digest.digest()[:16])) + "}"
    xml = _model_description(plant, gen, lay, ident, guid, kinds, float(stop_time))
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "fmu"
        src = root / "sources"
        src.mkdir(parents=True)
        (src / "model.c").write_text(gen.source)
        shutil.copy(Path(compiled.__file__).with_name("bdf.c"), src / "bdf.c")
        shutil.copy(_HERE / "fmi2_wrapper.c", src / "fmi2_wrapper.c")
        (src / "fmu_data.h").write_text(_data_header(plant, gen, lay, guid, kinds))
        binaries = root / "binaries" / platform_folder()
        binaries.mkdir(parents=True)
        _compile(cc, src, binaries / (ident + _library_suffix()))
        (root / "modelDescription.xml").write_text(xml)
        doc = root / "documentation"
        doc.mkdir()
        (doc / "index.html").write_text(
            f"<html><body><h1>{ident}</h1><p>{xml_escape_text(plant, ident)}</p></body></html>\n")
        out.parent.mkdir(parents=True, exist_ok=True)
        part = out.with_name(out.name + ".part")
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            for f in sorted(root.rglob("*")):
                if f.is_file():
                    z.write(f, f.relative_to(root).as_posix())
        os.replace(part, out)   # a reader never sees a half-written FMU
    return out


def xml_escape_text(plant: Plant, ident: str) -> str:
    from xml.sax.saxutils import escape

    return escape(f"hydroline plant {ident}: rig {plant.rig.source}, starting at the "
                  f"{plant.start} rest state. Inputs: {', '.join(plant.inputs)}. Outputs: "
                  f"{', '.join(OUTPUTS)}. Built on {platform.system()} {platform.machine()}.")
