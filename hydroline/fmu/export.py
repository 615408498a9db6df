"""Write a rig's plant as an FMI 2.0 or 3.0 FMU (Model Exchange and/or Co-Simulation).

The FMU holds the plant's generated C (:mod:`hydroline.compiled.codegen`: right-hand side,
exact sparse Jacobian, signals, sparse LU), hydroline's BDF integrator (``bdf.c``), the
instance logic (``fmu_core.c``) and an FMI wrapper (``fmi2_wrapper.c``/``fmi3_wrapper.c``),
compiled by the system C compiler for this platform into
``binaries/<platform>/``; the same sources are in ``sources/`` so other platforms can build
them. Nothing in the FMU needs Python.

Numbers are parameters: the binary holds the plant's structure only. Its numbers (the
components' numbers and the state scales at the head of the constants, the solved rest
state, the parameters' start values, the accumulators' charge) are in
``resources/plant_numbers.txt`` (:data:`NUMBERS_FILE`), read at instantiation. The binary and
``model.c`` are kept in the cache directory (:mod:`hydroline.cache`, table
:data:`BINARY_TABLE`) under the structure's key: a rig that differs only in numbers is
exported without writing C or compiling.
"""
from __future__ import annotations

import base64
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
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import casadi as ca
import numpy as np

from .. import compiled
from ..cache import load_table, prune_tables, source_tag, store_table
from ..compiled.codegen import constant_positions, constants_at, generate, scaled_functions, \
    structure_key
from ..compiled.toolchain import BDF_SOURCE
from ..components import PistonAccumulator
from ..rigs import Rig, load_rig
from .plant import INPUTS, OUTPUTS, Plant, rest_state, symbolic_model

__all__ = ["export_fmu", "FMI_VERSIONS", "KINDS", "platform_folder", "C_FLAGS", "NUMBERS_FILE",
           "BINARY_TABLE", "MAX_BINARIES"]

FMI_VERSIONS = (2, 3)
KINDS = ("cs", "me", "both")
#: Flags for the FMU's binary: portable (no -march=native), symbols hidden but the fmi2 API.
C_FLAGS = ["-O2", "-std=c99", "-shared", "-fPIC", "-fvisibility=hidden", "-fno-math-errno"]
_HERE = Path(__file__).parent
#: The FMU's numbers, in ``resources/`` (read by ``fmu_core.c`` at instantiation)
NUMBERS_FILE = "plant_numbers.txt"
#: First line of the numbers file (its format's version)
_NUMBERS_HEAD = "hydroline FMU numbers 1"
#: Table of the cache directory holding the FMU binaries built, one a structure (the binary,
#: ``model.c`` and where the graph's constants sit; ~1 MB each), and how many it keeps at
#: most, [-]
BINARY_TABLE = "fmu_binaries"
MAX_BINARIES = 20
#: The code an FMU binary is built from besides the plant's structure: a change makes the
#: cached binaries unused
_CODE_TAG = source_tag(_HERE / "fmu_core.c", _HERE / "fmi2_wrapper.c", _HERE / "fmi3_wrapper.c",
                       _HERE / "export.py", BDF_SOURCE,
                       Path(compiled.__file__).with_name("codegen.py"))
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


def platform_folder(fmi: int = 2) -> str:
    """Binaries folder of this platform: FMI 2.0 ``linux64``, ``darwin64``, ``win64``, ...;
    FMI 3.0 ``x86_64-linux``, ``aarch64-darwin``, ``x86_64-windows``, ...

    Parameters
    ----------
    fmi : int
        FMI version, 2 or 3

    Returns
    -------
    str
        Folder name under ``binaries/`` in the FMU
    """
    if fmi == 3:
        arch = {"amd64": "x86_64", "x86_64": "x86_64", "arm64": "aarch64", "aarch64": "aarch64",
                "i386": "x86", "i686": "x86", "x86": "x86"}.get(platform.machine().lower(),
                                                               platform.machine().lower())
        system = {"win32": "windows", "cygwin": "windows", "darwin": "darwin"}.get(
            sys.platform, "linux" if sys.platform.startswith("linux") else sys.platform)
        return f"{arch}-{system}"
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
    """A C identifier from a file stem: letters, digits and '_' (FMI 2.0 modelIdentifier).

    Parameters
    ----------
    name : str
        File stem, e.g. ``"servo-rig"``

    Returns
    -------
    str
        The stem with every other character replaced by '_' (``hl_`` prefixed when it would
        not start with a letter or '_')
    """
    ident = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in name)
    if not ident or not (ident[0].isalpha() or ident[0] == "_"):
        ident = "hl_" + ident
    return ident


@dataclass
class _Variable:
    """One FMU variable, independent of the FMI version."""

    name: str
    vr: int
    description: str
    causality: str
    variability: str
    initial: str | None = None
    unit: str = ""
    start: float | None = None
    nominal: float | None = None
    derivative_of: int | None = None     # value reference of the state
    kind: str = "Real"                    # "Real" or "Boolean"
    role: tuple = ()                      # "output", "derivative", "initial_unknown"
    depends_on: tuple | None = None       # value references of the states and inputs it
                                          # depends on in continuous time (None: all)


def _dependencies(sym, plant: Plant, vr_par: int):
    """Structural dependencies of the derivatives and the signals on the states and inputs,
    from the sparsity of the CasADi graph's Jacobians (the graph in the numbers' symbols
    where it has them: the same for every value of the numbers): (derivatives, signals),
    each a list of tuples of value references."""
    inputs = list(plant.inputs.values())
    known = ca.vertcat(sym.x, *[sym.p[k] for k in inputs])
    vrs = list(range(sym.x.numel())) + [vr_par + k for k in inputs]

    def rows(expr):
        sp = ca.jacobian(expr, known).sparsity()
        out = [[] for _ in range(expr.numel())]
        for i, j in zip(sp.row(), sp.get_col()):
            out[i].append(vrs[j])
        return [tuple(sorted(r)) for r in out]

    general = getattr(sym, "k", None) is not None
    return (rows(sym.dx_general if general else sym.dx),
            rows(sym.y_general if general else sym.y))


def _variables(plant: Plant, sym=None) -> list:
    """The FMU's variables with the value-reference layout of ``fmu_core.c``."""
    net = plant.network
    n, ny, m = len(net.state_names), len(net.signal_names), len(net.parameter_names)
    vr_der, vr_sig, vr_par = n, 2 * n, 2 * n + ny
    dep_dx, dep_y = _dependencies(sym, plant, vr_par) if sym is not None else ([None] * n, [None] * ny)
    vr_end = vr_par + m + len(plant.tunables)
    out = []
    # inputs (runtime parameters of the plant), then tunable parameters
    for name, k in plant.inputs.items():
        _, unit, meaning = INPUTS[name]
        out.append(_Variable(name, vr_par + k, meaning, "input", "continuous",
                             unit=_fmi_unit(unit), start=plant.p[k]))
    for j, tun in enumerate(plant.tunables):
        out.append(_Variable(tun.name, vr_par + m + j, tun.description, "parameter", "tunable",
                             "exact", unit=tun.unit, start=plant.tunable_values[j]))
    out.append(_Variable("solve_steady_state", vr_end, "re-solve the rest state at the end of "
                         "initialization when the start state is not at rest for the parameters "
                         "and inputs set", "parameter", "fixed", "exact", start=True,
                         kind="Boolean"))
    # outputs and the other signals (a signal equal to an input is not repeated)
    for i, s in enumerate(net.signal_names):
        c, port = net.producer[s]
        unit = _fmi_unit(c.outputs[port].unit)
        if s in OUTPUTS:
            out.append(_Variable(s, vr_sig + i, OUTPUTS[s], "output", "continuous", "calculated",
                                 unit=unit, role=("output", "initial_unknown"),
                                 depends_on=dep_y[i]))
        elif s not in plant.inputs:
            out.append(_Variable(s, vr_sig + i, f"{c.outputs[port].description} ({c.name}.{port})",
                                 "local", "continuous", "calculated", unit=unit))
    units = [_fmi_unit(st.unit) for c in net.components for st in c.states]
    for i, s in enumerate(net.state_names):
        out.append(_Variable(s, i, "state of the plant (rest state solved at export)", "local",
                             "continuous", "approx", unit=units[i], start=plant.x[i],
                             nominal=float(net.state_scales[i]), role=("initial_unknown",)))
    for i, s in enumerate(net.state_names):
        out.append(_Variable(f"der({s})", vr_der + i, f"time derivative of {s}", "local",
                             "continuous", "calculated", derivative_of=i,
                             role=("derivative", "initial_unknown"), depends_on=dep_dx[i]))
    return out


def _unit_definitions(variables) -> str:
    lines = []
    for u in sorted({v.unit for v in variables if v.unit}):
        base = _UNITS.get(u)
        if base:
            b = " ".join(f'{k}="{e}"' for k, e in base.items())
            lines.append(f'    <Unit name="{u}">\n      <BaseUnit {b}/>\n    </Unit>')
        else:
            lines.append(f'    <Unit name="{u}"/>')
    return "  <UnitDefinitions>\n" + "\n".join(lines) + "\n  </UnitDefinitions>"


def _header(plant: Plant, ident: str, version: str, token_attr: str, extra="") -> str:
    from .. import __version__

    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    desc = (f"hydroline plant of rig {plant.rig.get('rig.name', plant.rig.source)}: hoses, HSM, "
            f"accumulators, servovalve, actuator, friction, load; starts at the {plant.start} "
            f"rest state")
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="{version}" '
            f'modelName={quoteattr(ident)} {token_attr}\n  description={quoteattr(desc)} '
            f'generationTool="hydroline {__version__}"\n  generationDateAndTime="{now}" '
            f'variableNamingConvention="flat"{extra}>')


def _model_description_2(plant, variables, ident, guid, kinds, stop_time) -> str:
    """modelDescription.xml of FMI 2.0."""
    index = {}   # value reference of a Real -> 1-based index in ModelVariables
    body = []
    for v in variables:
        attrs = (f"name={quoteattr(v.name)} valueReference=\"{v.vr}\" "
                 f"description={quoteattr(v.description)} causality=\"{v.causality}\" "
                 f"variability=\"{v.variability}\"" + (f' initial="{v.initial}"' if v.initial else ""))
        if v.kind == "Boolean":
            typ = f'<Boolean start="{str(bool(v.start)).lower()}"/>'
        else:
            t = [f'unit="{v.unit}"' if v.unit else "",
                 f'start="{float(v.start)!r}"' if v.start is not None else "",
                 f'nominal="{v.nominal!r}"' if v.nominal is not None else "",
                 f'derivative="{index[v.derivative_of]}"' if v.derivative_of is not None else ""]
            typ = "<Real " + " ".join(x for x in t if x) + "/>"
            index[v.vr] = len(body) + 1
        body.append(f"    <ScalarVariable {attrs}>\n      {typ}\n    </ScalarVariable>")
    pos = {id(v): k + 1 for k, v in enumerate(variables)}

    def unknowns(role):
        lines = []
        for v in variables:
            if role not in v.role:
                continue
            deps = ""
            if role != "initial_unknown" and v.depends_on is not None:
                deps = ' dependencies="' + " ".join(str(k) for k in sorted(index[d] for d in v.depends_on)) + '"'
            lines.append(f'      <Unknown index="{pos[id(v)]}"{deps}/>')
        return "\n".join(lines)

    src = '      <SourceFiles>\n        <File name="fmi2_wrapper.c"/>\n      </SourceFiles>'
    common = (f'modelIdentifier="{ident}" canGetAndSetFMUstate="true" '
              f'canSerializeFMUstate="true" providesDirectionalDerivative="true"')
    parts = []
    if "me" in kinds:
        parts.append(f'  <ModelExchange {common} completedIntegratorStepNotNeeded="true">\n{src}\n'
                     f'  </ModelExchange>')
    if "cs" in kinds:
        parts.append(f'  <CoSimulation {common} canHandleVariableCommunicationStepSize="true" '
                     f'canInterpolateInputs="false" maxOutputDerivativeOrder="0">\n{src}\n'
                     f'  </CoSimulation>')
    return "\n".join([
        _header(plant, ident, "2.0", f'guid="{guid}"', ' numberOfEventIndicators="0"'), *parts,
        _unit_definitions(variables),
        f'  <DefaultExperiment startTime="0.0" stopTime="{stop_time!r}" tolerance="1e-06"/>',
        "  <ModelVariables>", *body, "  </ModelVariables>",
        "  <ModelStructure>", "    <Outputs>", unknowns("output"), "    </Outputs>",
        "    <Derivatives>", unknowns("derivative"), "    </Derivatives>",
        "    <InitialUnknowns>", unknowns("initial_unknown"), "    </InitialUnknowns>",
        "  </ModelStructure>", "</fmiModelDescription>", ""])


def _model_description_3(plant, variables, ident, guid, kinds, stop_time) -> str:
    """modelDescription.xml of FMI 3.0 (Float64 and Boolean variables, time independent)."""
    vr_time = max(v.vr for v in variables if v.kind == "Boolean") + 1   # as fmu_core.c
    body = [f'    <Float64 name="time" valueReference="{vr_time}" causality="independent" '
            f'variability="continuous" description="simulation time" unit="s"/>']
    for v in variables:
        attrs = (f"name={quoteattr(v.name)} valueReference=\"{v.vr}\" "
                 f"description={quoteattr(v.description)} causality=\"{v.causality}\" "
                 f"variability=\"{v.variability}\"" + (f' initial="{v.initial}"' if v.initial else ""))
        if v.kind == "Boolean":
            body.append(f'    <Boolean {attrs} start="{str(bool(v.start)).lower()}"/>')
            continue
        t = [f'unit="{v.unit}"' if v.unit else "",
             f'start="{float(v.start)!r}"' if v.start is not None else "",
             f'nominal="{v.nominal!r}"' if v.nominal is not None else "",
             f'derivative="{v.derivative_of}"' if v.derivative_of is not None else ""]
        body.append(f"    <Float64 {attrs} " + " ".join(x for x in t if x) + "/>")

    def unknowns(tag, role):
        out = []
        for v in variables:
            if role not in v.role:
                continue
            deps = ""
            if role != "initial_unknown" and v.depends_on is not None:
                deps = ' dependencies="' + " ".join(str(d) for d in v.depends_on) + '"'
            out.append(f'    <{tag} valueReference="{v.vr}"{deps}/>')
        return out

    common = (f'modelIdentifier="{ident}" canGetAndSetFMUState="true" '
              f'canSerializeFMUState="true" providesDirectionalDerivatives="true"')
    parts = []
    if "me" in kinds:
        parts.append(f'  <ModelExchange {common} needsCompletedIntegratorStep="false"/>')
    if "cs" in kinds:
        parts.append(f'  <CoSimulation {common} canHandleVariableCommunicationStepSize="true" '
                     f'maxOutputDerivativeOrder="0"/>')
    variables_with_time = variables + [_Variable("time", vr_time, "", "independent", "continuous",
                                                 unit="s")]
    return "\n".join([
        _header(plant, ident, "3.0", f'instantiationToken="{guid}"'), *parts,
        _unit_definitions(variables_with_time),
        f'  <DefaultExperiment startTime="0.0" stopTime="{stop_time!r}" tolerance="1e-06"/>',
        "  <ModelVariables>", *body, "  </ModelVariables>",
        "  <ModelStructure>", *unknowns("Output", "output"),
        *unknowns("ContinuousStateDerivative", "derivative"),
        *unknowns("InitialUnknown", "initial_unknown"),
        "  </ModelStructure>", "</fmiModelDescription>", ""])


def _build_description(ident: str) -> str:
    """sources/buildDescription.xml of FMI 3.0."""
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiBuildDescription fmiVersion="3.0">\n'
            f'  <BuildConfiguration modelIdentifier="{ident}">\n'
            f'    <SourceFileSet language="C99">\n      <SourceFile name="fmi3_wrapper.c"/>\n'
            f'    </SourceFileSet>\n  </BuildConfiguration>\n</fmiBuildDescription>\n')


def _structure_header(plant: Plant, kinds: set) -> str:
    """``fmu_data.h`` without its structure key: what the binary holds besides ``model.c``
    (the names, where the accumulators and the mirrored parameter sit, the kinds); no
    number of the rig."""
    net = plant.network
    mirrors = []
    if "valve_current" in plant.inputs:   # the plant's current source: command.initial = final
        k = plant.inputs["valve_current"]
        mirrors.append((net.parameter_names.index("command.initial"), k))
    acc = []   # accumulators: gas state, reference parameter, node signal
    for c in _accumulators(net):
        acc.append("{%d,%d,%d}" % (net.state_names.index(f"{c.name}.gas_volume"),
                                   net.parameter_names.index(f"{c.name}.reference_pressure"),
                                   net.signal_names.index(c.signal("pressure"))))
    lines = [
        "/* This FMU's structure (written by hydroline.fmu); its numbers are in",
        f" * resources/{NUMBERS_FILE}, read at instantiation. */",
        f"#define HL_FMU_NUMBERS_FILE {_c_string(NUMBERS_FILE)}",
        f"#define HL_FMU_NUMBERS_HEAD {_c_string(_NUMBERS_HEAD)}",
        f"#define HL_FMU_ME {int('me' in kinds)}",
        f"#define HL_FMU_CS {int('cs' in kinds)}",
        "#define HL_FMU_RTOL 1e-6",
        f"#define HL_FMU_STEADY_TOL {STEADY_TOL!r}",
        f"#define HL_FMU_NMIRROR {len(mirrors)}",
        "static const int hl_fmu_mirror[][2] = {" + (",".join(f"{{{a},{b}}}" for a, b in mirrors)
                                                     or "{0,0}") + "};",
        f"#define HL_FMU_NACC {len(acc)}",
        "typedef struct { int gas_state, reference_parameter, node_signal; } hl_fmu_accumulator;",
        "static const hl_fmu_accumulator hl_fmu_acc[] = {" + (",".join(acc) or "{0,0,0}") + "};",
        _c_array("char*", "hl_fmu_state_names", net.state_names, _c_string),
        _c_array("char*", "hl_fmu_parameter_names",
                 list(net.parameter_names) + [t.name for t in plant.tunables], _c_string),
    ]
    return "\n".join(lines) + "\n"


def _accumulators(net) -> list:
    return [c for c in net.components if isinstance(c, PistonAccumulator)]


def _numbers_text(plant: Plant, constants, structure: str, guid: str) -> str:
    """``resources/plant_numbers.txt``: this FMU's numbers as ``fmu_core.c`` reads them, each
    value as its IEEE-754 bit pattern in hexadecimal (exact, whatever the importer's locale)
    followed by its decimal value."""
    net = plant.network
    p0 = np.concatenate([plant.p, plant.tunable_values])
    nominal = np.maximum(np.abs(p0), 1e-300)
    for name, k in plant.inputs.items():
        nominal[k] = max(abs(p0[k]), _INPUT_NOMINAL[name])
    nominal[nominal == 0] = 1.0
    acc = _accumulators(net)
    constants = np.asarray(constants, dtype=float)
    sections = [("constants", constants if constants.size else np.zeros(1)),
                ("state_scales", net.state_scales), ("rest_state", plant.x),
                ("parameters", p0 if p0.size else np.zeros(1)),
                ("parameter_nominals", nominal if nominal.size else np.ones(1)),
                ("accumulator_capacities", [c.capacity for c in acc]),
                ("accumulator_precharges", [c.precharge_pressure for c in acc])]
    lines = [_NUMBERS_HEAD, f"guid {guid}", f"structure {structure}"]
    for label, values in sections:
        values = np.asarray(values, dtype=float)
        lines.append(f"{label} {values.size}")
        lines += [f"{v.view(np.uint64):016x} {_c_double(v)}" for v in values]
    return "\n".join(lines) + "\n"


def _binary_key(functions, header: str, fmi: int, cc: str) -> str:
    """The cache key of an FMU binary: the plant's structure (the graph's listing with its
    constants masked, the Jacobian's pattern), ``fmu_data.h``, the FMI version, the code and
    the compiler with its flags."""
    sp = functions[1].sparsity_out(0)
    h = hashlib.sha256()
    for part in (structure_key(functions), repr(sp.colind()), repr(sp.row()), header, str(fmi),
                 _CODE_TAG, cc, " ".join(C_FLAGS), sys.platform, platform.machine()):
        h.update(part.encode())
        h.update(b"\0")
    return "fmu:" + h.hexdigest()


def _known_binary(key: str, functions, network):
    """(model.c, binary, constants) of a structure built before (the cache's
    :data:`BINARY_TABLE`), with this model's constants read from its graph; None if unknown."""
    rec = load_table(BINARY_TABLE, key)
    if rec is None:
        return None
    try:
        constants = constants_at(functions, rec["positions"], network)
        if len(constants) != rec["n_constants"]:
            return None
        return rec["model_c"], base64.b64decode(rec["binary"]), constants
    except (TypeError, KeyError, ValueError, RuntimeError):
        return None


def _remember_binary(key: str, functions, gen, binary: bytes) -> None:
    """Keep a new structure's binary and ``model.c`` in the cache (:data:`BINARY_TABLE`)."""
    store_table(BINARY_TABLE, key, {
        "model_c": gen.source, "binary": base64.b64encode(binary).decode(),
        "positions": constant_positions(functions), "n_constants": len(gen.constants)})
    prune_tables(BINARY_TABLE, MAX_BINARIES)


def _c_compiler() -> str | None:
    """The system C compiler, found as the compiled core finds it: ``$CC``, else ``cc``,
    ``gcc`` or ``clang`` on the PATH (None if there is none)."""
    cc = os.environ.get("CC")
    if cc and shutil.which(cc):
        return shutil.which(cc)
    for name in ("cc", "gcc", "clang"):
        if shutil.which(name):
            return shutil.which(name)
    return None


def _compile(cc: str, source: Path, out: Path) -> None:
    cmd = [cc, *C_FLAGS, "-o", str(out), str(source), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise compiled.CompilerUnavailable(f"C compiler failed on the FMU sources: "
                                           f"{proc.stderr.strip()[:2000]}")


def export_fmu(rig: Rig | str | None = None, out="hydroline.fmu", fmi: int = 2, kind: str = "cs",
               start: str = "open-loop-step", stop_time: float | None = None) -> Path:
    """Export the rig's plant as an FMU.

    Parameters
    ----------
    rig : Rig, str or None
        The rig (a path, or None for the embedded default)
    out : path
        The .fmu file to write; its stem is the modelIdentifier
    fmi : int
        FMI version: 2 (FMI 2.0) or 3 (FMI 3.0)
    kind : str
        "cs" (Co-Simulation: hydroline's BDF integrator between
        communication points), "me" (Model Exchange: the ODE, the
        importer integrates), or "both"
    start : str
        Scenario whose rest state the FMU starts from
        ("open-loop-step" or "closed-loop-sine", see
        :func:`hydroline.fmu.plant.rest_state`)
    stop_time : float
        DefaultExperiment stop time, [s] (the scenario's t_end if None)

    Returns
    -------
    Path
        The FMU written

    Raises
    ------
    ValueError
        Bad arguments (one line)
    CompilerUnavailable
        No C compiler, or it failed
    """
    if fmi not in FMI_VERSIONS:
        raise ValueError(f"--fmi: must be 2 (FMI 2.0) or 3 (FMI 3.0), got {fmi!r}")
    if kind not in KINDS:
        raise ValueError(f"--kind: must be one of {', '.join(KINDS)}, got {kind!r}")
    out = Path(out)
    if out.suffix.lower() != ".fmu":
        raise ValueError(f"--out: an FMU file name ends in .fmu, got {str(out)!r}")
    part = out.with_name(out.name + ".part")
    if out.parent.exists() and not out.parent.is_dir():
        raise ValueError(f"--out: {str(out.parent)!r} is not a folder")
    try:                                   # refuse an unwritable place before the build
        out.parent.mkdir(parents=True, exist_ok=True)
        with open(part, "wb"):
            pass
        part.unlink()
    except OSError as e:
        raise ValueError(f"--out: cannot write {str(out)!r}: {e.strerror or e}") from None
    cc = _c_compiler()
    if cc is None:
        raise compiled.CompilerUnavailable("no C compiler found (set CC, or install gcc): the FMU's "
                                           "binary is built with the system C compiler")
    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    plant = rest_state(rig, start)
    sym = symbolic_model(plant)
    functions = scaled_functions(sym)
    if stop_time is None:
        from ..scenarios.experiments import build_scenario
        stop_time = build_scenario(rig, start).t_end
    kinds = {"cs", "me"} if kind == "both" else {kind}
    ident = model_identifier(out.stem)
    header = _structure_header(plant, kinds)
    key = _binary_key(functions, header, fmi, cc)
    structure = key[len("fmu:"):][:32]
    header += f"#define HL_FMU_STRUCTURE {_c_string(structure)}\n"
    wrapper = f"fmi{fmi}_wrapper.c"
    binary_name = ident + _library_suffix()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "fmu"
        src = root / "sources"
        src.mkdir(parents=True)
        shutil.copy(Path(compiled.__file__).with_name("bdf.c"), src / "bdf.c")
        for name in ("fmu_core.c", wrapper):
            shutil.copy(_HERE / name, src / name)
        (src / "fmu_data.h").write_text(header)
        if fmi == 3:
            (src / "buildDescription.xml").write_text(_build_description(ident))
        binaries = root / "binaries" / platform_folder(fmi)
        binaries.mkdir(parents=True)
        known = _known_binary(key, functions, sym.network)
        if known is not None:          # this structure built before: no C written, no compile
            model_c, binary, constants = known
            (src / "model.c").write_text(model_c)
            (binaries / binary_name).write_bytes(binary)
        else:
            gen = generate(sym, functions)
            constants = gen.constants
            (src / "model.c").write_text(gen.source)
            _compile(cc, src / wrapper, binaries / binary_name)
            _remember_binary(key, functions, gen, (binaries / binary_name).read_bytes())
        numbers = _numbers_text(plant, constants, structure, "{}")
        digest = hashlib.sha256((key + numbers + ident + kind + str(fmi)).encode())
        guid = "{" + str(uuid.UUID(bytes=digest.digest()[:16])) + "}"
        resources = root / "resources"
        resources.mkdir()
        (resources / NUMBERS_FILE).write_text(_numbers_text(plant, constants, structure, guid))
        variables = _variables(plant, sym)
        describe = _model_description_2 if fmi == 2 else _model_description_3
        (root / "modelDescription.xml").write_text(
            describe(plant, variables, ident, guid, kinds, float(stop_time)))
        doc = root / "documentation"
        doc.mkdir()
        (doc / "index.html").write_text(
            f"<html><body><h1>{ident}</h1><p>{_documentation_text(plant, ident)}</p></body></html>\n")
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            for f in sorted(root.rglob("*")):
                if f.is_file():
                    z.write(f, f.relative_to(root).as_posix())
        os.replace(part, out)   # a reader never sees a half-written FMU
    return out


def _documentation_text(plant: Plant, ident: str) -> str:
    from xml.sax.saxutils import escape

    return escape(f"hydroline plant {ident}: rig {plant.rig.source}, starting at the "
                  f"{plant.start} rest state. Inputs: {', '.join(plant.inputs)}. Outputs: "
                  f"{', '.join(OUTPUTS)}. Built on {platform.system()} {platform.machine()}.")
