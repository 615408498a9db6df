"""The component types a circuit file may use, with their parameters declared once.

Each type names a component class of :mod:`hydroline.components` (whose dataclass fields
declare unit, bounds, description and default, see :class:`hydroline.engine.Parameter`) or a
small factory over one (a hose from its length and bore, an accumulator from its connection
passage). Rig schemas, rig validation, circuit-file parsing and ``hydroline circuit`` read
these tables; nothing else repeats a unit, a bound or a default.

What a component takes from the rig around it besides its own parameters (the oil, the rig's
modes per hose section, ...: :data:`CONTEXT`) is declared by its type (``context``, else the
component class's ``context``), and the builder hands each by name: a new component that
needs the fluid declares ``context = ("fluid",)`` and a ``fluid`` field, nothing else.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Callable

from .. import components as comp
from ..engine.component import Parameter
from ..fluid import entrained_air_bulk_modulus
from ..lines import DEFAULT_LINE_METHOD, LINE_METHODS, Line, ModalLine

__all__ = ["ComponentType", "COMPONENT_TYPES", "FLUID_PARAMETERS", "HOSE_PARAMETERS",
           "ACCUMULATOR_CONNECTION_PARAMETERS", "RIG_SETTINGS", "CONTEXT", "CircuitError",
           "QUANTITY_UNIT", "QUANTITY_PLAUSIBLE", "FASTEST_RAMP", "parameter_reference",
           "make_hose", "make_accumulator", "make_volume", "make_table_command"]


class CircuitError(ValueError):
    """A circuit that cannot be built: one line naming the component and port/parameter.

    Parameters
    ----------
    *args : str
        The message: one line naming the component and its port or parameter
    **kwargs : dict
        None taken (as ``ValueError``)
    """


#: Physical quantity of a command -> SI unit of its values.
QUANTITY_UNIT = {"current": "A", "position": "m", "pressure": "Pa", "velocity": "m/s",
                 "force": "N", "flow": "m^3/s"}

#: Physical quantity of a command -> the largest magnitude a real rig commands, [its SI unit]
#: (as the rig's own ranges: a valve current, a stroke, a supply pressure, an applied force,
#: a valve's rated flow): a command's levels are plausible within +-this, its ramp slope
#: within +-this per :data:`FASTEST_RAMP`.
QUANTITY_PLAUSIBLE = {"current": 5.0, "position": 5.0, "pressure": 1e8, "velocity": 10.0,
                      "force": 1e7, "flow": 0.1}

#: The shortest time a command ramps across its whole plausible range, [s] (steeper is a step).
FASTEST_RAMP = 1e-4

#: The rig's oil (``[fluid]``), used by every hose, volume default and accumulator passage.
FLUID_PARAMETERS = {
    "density": Parameter("kg/m^3", "rho of the oil (M2)", 0.0, exclusive_minimum=True,
                         plausible=(600.0, 1300.0)),
    "kinematic_viscosity": Parameter("m^2/s", "nu of the oil (M2)", 0.0, exclusive_minimum=True,
                                     plausible=(3e-7, 1e-2)),
    "bulk_modulus": Parameter("Pa", "beta of the oil (M2)", 0.0, exclusive_minimum=True,
                              plausible=(1e8, 5e9)),
    # entrained air (M40): Merritt (1967) 2.6; Gholizadeh, Burton & Schoenau (2011). Mineral
    # oil in service carries ~0.1-1 % free air at atmospheric pressure, up to ~10 % when foaming
    "air_content": Parameter("-", "free-air volume fraction at 1 atm; K_eff(p) of oil + air "
                             "in every chamber, volume and line (M40, M41, M43)", 0.0, 1.0,
                             default=0.0, plausible=(0.0, 0.2)),
    "air_polytropic_exponent": Parameter("-", "n of the entrained air: 1 isothermal ... 1.4 "
                                         "adiabatic (M40)", 1.0, 5.0 / 3.0, default=1.0,
                                         plausible=(1.0, 1.4)),
    # cavitation (M42, M45): vapour pressure of mineral oil ~1e1-1e3 Pa at 40 degC, gas
    # release (air saturation) up to 1 atm (Totten, Handbook of Hydraulic Fluid Technology,
    # 2000; Wylie & Streeter, Fluid Transients, 1993, ch. 8 for the cavity treatment). On by
    # default at 5 kPa, above the vapour pressures (Hopsan's lines clamp at 0 Pa): no rig
    # reads a negative absolute pressure; "off" (or "none") in a rig file: no cavity model
    "cavity_pressure": Parameter("Pa", "absolute pressure of a gas/vapour cavity; below it "
                                 "chambers, volumes (M42) and hose ends (M45) open a cavity; "
                                 "\"off\": none", 0.0, 1e7, optional=True, default=5e3,
                                 plausible=(0.0, 2e5)),
    "cavity_pressure_drop": Parameter("Pa", "regularisation: pressure fall per unit cavity "
                                      "volume fraction (M42), width of a hose end's (M45)", 0.0, exclusive_minimum=True,
                                      default=1e3, plausible=(1.0, 1e5)),
}

#: The rig-wide settings a component may take (``[rig]``, see :data:`CONTEXT`), with their
#: defaults: declared here once.
RIG_SETTINGS = {
    "modes_per_section": Parameter("-", "modes per hose section (M8)", 1.0, default=6,
                                   plausible=(1, 40)),
    "line_method": Parameter("str", "modal line of every hose: exact residues or the paper's "
                             "Yang-Tobler corrections", choices=LINE_METHODS,
                             default=DEFAULT_LINE_METHOD),
}

#: What a component may take from the rig around it: name -> what the circuit builder hands
#: it under that keyword (a type's ``context``, or its component class's ``context``).
CONTEXT = {
    "fluid": "the rig's oil, a hydroline.fluid.Fluid ([fluid]: density, kinematic viscosity, "
             "bulk modulus)",
    "modes_per_section": "[rig] modes_per_section, an int [-]",
    "line_method": "[rig] line_method, one of " + ", ".join(LINE_METHODS),
    "folder": "the folder of the rig file, a pathlib.Path (None for a rig shipped with the "
              "package): files a component names are read relative to it",
}

#: A hose section (docs/model.md 2): the line (M2-M4) and its modal model (M8-M15).
HOSE_PARAMETERS = {
    "length": Parameter("m", "L of the section (M2)", 0.0, exclusive_minimum=True,
                        plausible=(1e-2, 1e3)),
    "diameter": Parameter("m", "bore (M2)", 0.0, exclusive_minimum=True, plausible=(1e-3, 0.2)),
    "bulk_modulus": Parameter("Pa", "effective beta of oil + wall (M3); the fluid's when absent",
                              0.0, exclusive_minimum=True, optional=True, plausible=(1e7, 5e9)),
    "modes": Parameter("-", "modes of the modal line (M8); the rig's modes_per_section when absent",
                       1.0, optional=True, plausible=(1, 40)),
    "method": Parameter("str", "modal line: exact residues (default) or the paper's "
                        "Yang-Tobler corrections; the rig's line_method when absent",
                        choices=LINE_METHODS, optional=True),
    "form": Parameter("str", "causal form: inputs upstream/downstream (M8)",
                      choices=("PQ", "QP", "PP", "QQ"), default="PQ"),
    "nominal_pressure": Parameter("Pa", "mean pressure: state scale and steady-state guess",
                                  0.0, exclusive_minimum=True, default=1e7, plausible=(1e3, 1e8)),
    # (M44) Kelvin-Voigt wall: J_k of the line's volume, alpha d/e J_k' for a thin wall of
    # material compliance J_k' (Covas et al. 2004); hose data: dynamic vs static modulus
    # (Johnston et al. 2010): beta_e sum J_k of 0.01 ... 1, J ~ 1e-12 ... 5e-9 1/Pa
    "creep_compliances": Parameter("list:1/Pa", "viscoelastic wall (M44): creep compliances J_k "
                                   "of the Kelvin-Voigt elements (Covas et al. 2004); none: an "
                                   "elastic wall, bulk_modulus then the instantaneous one",
                                   0.0, exclusive_minimum=True, default=(),
                                   plausible=(1e-13, 1e-8)),
    "retardation_times": Parameter("list:s", "retardation times tau_k of those elements (M44), "
                                   "as many as creep_compliances", 0.0, exclusive_minimum=True,
                                   default=(), plausible=(1e-5, 100.0)),
}

#: The accumulator's connection passage (M18): a short line from the node to the oil side.
ACCUMULATOR_CONNECTION_PARAMETERS = {
    "connection_length": Parameter("m", "length of the passage node -> accumulator (M18)", 0.0,
                                   exclusive_minimum=True, plausible=(1e-3, 10.0)),
    "connection_diameter": Parameter("m", "bore of that passage (M18)", 0.0, exclusive_minimum=True,
                                     plausible=(1e-3, 0.1)),
    "model": Parameter("str", "version-II (R_a, I_a, M18) or a modal PP line",
                       choices=("version-II", "modal"), default="version-II"),
    "modes": Parameter("-", "modes of the modal connection line", 1.0, optional=True,
                       plausible=(1, 40)),
}

def _integer_modes(modes, modes_per_section) -> int:
    """A line's modes: its own, else the rig's; ValueError naming ``modes`` unless a whole
    number >= 1."""
    n = modes_per_section if modes is None else modes
    if int(n) != n or n < 1:
        raise ValueError(f"modes: must be an integer >= 1, got {n!r}")
    return int(n)


def line_bulk_modulus(fluid, bulk_modulus, pressure):
    """Bulk modulus of a line's oil at its mean pressure (M43): the given one (the fluid's when
    None) with the fluid's entrained air at ``pressure`` (M40); unchanged for air-free oil.

    Parameters
    ----------
    fluid : Fluid
        The rig's oil
    bulk_modulus : float
        The line's oil-and-wall modulus, [Pa]; None: the fluid's
    pressure : float
        The line's mean (nominal) absolute pressure, [Pa]

    Returns
    -------
    float or None
        [Pa]; ``bulk_modulus`` itself when the oil carries no air
    """
    if not fluid.air_content:
        return bulk_modulus
    base = fluid.bulk_modulus if bulk_modulus is None else bulk_modulus
    return float(entrained_air_bulk_modulus(pressure, base, fluid.air_content,
                                            fluid.air_polytropic_exponent))


def make_hose(*, name, length, diameter, form, nominal_pressure, bulk_modulus=None, modes=None,
              method=None, creep_compliances=(), retardation_times=(), fluid, modes_per_section,
              line_method):
    """A hose section from its dimensions: the modal line (M8-M15) of a
    :class:`~hydroline.lines.Line` of the rig's oil (the ``hose`` type's factory).

    Parameters
    ----------
    name : str
        Component name
    length : float
        L, [m]
    diameter : float
        Bore, [m]
    form : str
        Causal form ("PQ", "QP", "PP", "QQ")
    nominal_pressure : float
        Mean pressure: state scale and steady-state guess, [Pa]
    bulk_modulus : float
        Effective bulk modulus of oil and wall, [Pa]; the oil's when None;
        with entrained air (``fluid.air_content``), the mixture's at
        ``nominal_pressure`` (M40, M43)
    modes : int
        Modes of the line; ``modes_per_section`` when None
    method : str
        Modal line method; ``line_method`` when None
    creep_compliances : tuple
        Viscoelastic wall (M44): creep compliances J_k, [1/Pa]; empty:
        an elastic wall
    retardation_times : tuple
        Their retardation times tau_k, [s]
    fluid : Fluid
        The rig's oil
    modes_per_section : int
        The rig's modes per hose section
    line_method : str
        The rig's modal line method

    Returns
    -------
    HoseSection
        The hose section
    """
    beta = line_bulk_modulus(fluid, bulk_modulus, nominal_pressure)
    if creep_compliances or retardation_times:
        if len(creep_compliances) != len(retardation_times):
            raise ValueError(f"retardation_times [s]: as many as creep_compliances [1/Pa] "
                             f"({len(creep_compliances)}), got {len(retardation_times)}")
        line = Line(length, diameter, fluid, beta, tuple(creep_compliances),
                    tuple(retardation_times))
    else:
        line = Line(length, diameter, fluid, beta)
    model = ModalLine(line, _integer_modes(modes, modes_per_section), form,
                      method=line_method if method is None else method)
    return comp.HoseSection(name=name, model=model, nominal_pressure=nominal_pressure, fluid=fluid)


def make_accumulator(*, name, connection_length, connection_diameter, model, modes=None, fluid,
                     modes_per_section, **params):
    """A piston accumulator on its connection passage (M18): version II (the passage's R_a and
    I_a) or a modal PP line (the ``accumulator`` type's factory).

    Parameters
    ----------
    name : str
        Component name
    connection_length : float
        Length of the passage node -> accumulator, [m]
    connection_diameter : float
        Its bore, [m]
    model : str
        "version-II" or "modal"
    modes : int
        Modes of the modal passage; ``modes_per_section`` when None
    fluid : Fluid
        The rig's oil
    modes_per_section : int
        The rig's modes per hose section
    **params
        The accumulator's own parameters (capacity, ...)

    Returns
    -------
    PistonAccumulator
        The accumulator
    """
    conn = Line(connection_length, connection_diameter, fluid,
                line_bulk_modulus(fluid, None, params.get(
                    "nominal_pressure", comp.PistonAccumulator.parameters()["nominal_pressure"].default)))
    if model == "modal":
        line = ModalLine(conn, _integer_modes(modes, modes_per_section), "PP")
        return comp.PistonAccumulator(name=name, connection_model=line, **params)
    return comp.PistonAccumulator(name=name, resistance=conn.resistance, inertance=conn.inertance,
                                  **params)


def make_volume(*, name, bulk_modulus=None, fluid, **params):
    """A lumped oil volume whose bulk modulus is the rig's oil's unless given (the ``volume``
    type's factory).

    Parameters
    ----------
    name : str
        Component name
    bulk_modulus : float
        beta of the oil in it, [Pa]; the fluid's when None
    fluid : Fluid
        The rig's oil
    **params
        The volume's other parameters (volume, terms, ...)

    Returns
    -------
    HydraulicVolume
        The volume
    """
    return comp.HydraulicVolume(name=name, bulk_modulus=fluid.bulk_modulus if bulk_modulus is None
                                else bulk_modulus, fluid=fluid, **params)


def make_table_command(*, name, file, quantity, folder):
    """A command from a CSV table with units in its header (the ``table_command`` type's
    factory).

    Parameters
    ----------
    name : str
        Component name
    file : str
        CSV file, relative to ``folder`` unless absolute
    quantity : str
        What the command drives (its values in that quantity's SI unit)
    folder : Path
        The rig file's folder; None: ``file`` as given

    Returns
    -------
    TableCommand
        The command
    """
    path = Path(file)
    if folder is not None and not path.is_absolute():
        path = Path(folder) / path
    return comp.TableCommand.from_csv_with_units(path, QUANTITY_UNIT[quantity], name=name,
                                                 quantity=quantity)


@dataclass(frozen=True)
class ComponentType:
    """One component type of a circuit file.

    Parameters
    ----------
    name : str
        The ``type = "..."`` of the file
    component : type
        Component class built
    description : str
        One line for ``hydroline circuit`` and the docs
    parameters : dict
        Extra file parameters (name -> Parameter) a factory turns into the
        component's own ones, or declarations replacing the class's
    hidden : tuple
        Component fields not given in the file (set by the factory)
    factory : callable
        ``factory(name=..., **parameters, **context)`` -> the component,
        given every declared parameter (the declared default where the
        file gives none); None: the class itself, given the parameters the
        file gives. Either gets ``terms`` for a type with flow terms (a
        ``terms`` field)
    context : tuple
        What it takes from the rig around it (names of :data:`CONTEXT`),
        handed by keyword; None: the component class's ``context``
    levels : tuple
        A command's values, in the SI unit and plausible range of its
        ``quantity`` (:data:`QUANTITY_PLAUSIBLE`; ``slope`` per second)
    """

    name: str
    component: type
    description: str
    parameters: dict = field(default_factory=dict)
    hidden: tuple = ()
    factory: Callable | None = None
    context: tuple | None = None
    levels: tuple = ()

    def __post_init__(self):
        # what the declarations give, made once per type (a build asks for each component)
        object.__setattr__(self, "_declared", {})

    @property
    def needs(self) -> tuple:
        """What the type takes from the rig around it (names of :data:`CONTEXT`)."""
        return tuple(self.context if self.context is not None
                     else getattr(self.component, "context", ()))

    @property
    def takes_terms(self) -> bool:
        """True for a type summing signed flow terms (its component has a ``terms`` field)."""
        known = self._declared.get("terms")
        if known is None:
            known = self._declared["terms"] = any(f.name == "terms"
                                                  for f in dataclasses.fields(self.component))
        return known

    def make(self, name: str, **kwargs):
        """The component: its factory (or class) called with ``name`` and ``kwargs``.

        Parameters
        ----------
        name : str
            Component name
        **kwargs
            Its parameters, context and terms

        Returns
        -------
        Component
            The component, ready to join a network
        """
        return (self.factory or self.component)(name=name, **kwargs)

    def declarations(self, values: dict | None = None) -> dict:
        """Every parameter a file may give for this type, name -> Parameter (a read-only
        mapping); a command's levels (initial, final, offset, amplitude, slope) in the SI unit
        and plausible range of its ``quantity`` (:data:`QUANTITY_PLAUSIBLE`).

        Parameters
        ----------
        values : dict
            The component's values as given (its ``quantity``); None: the defaults

        Returns
        -------
        Mapping
            Parameter name -> :class:`~hydroline.rigs.parameters.Parameter`
        """
        q = (values or {}).get("quantity", "current") if self.levels else None
        known = self._declared.get(("parameters", q))
        if known is None:
            own = {k: v for k, v in self.component.parameters().items() if k not in self.hidden}
            known = {**own, **self.parameters}
            if q in QUANTITY_UNIT:
                unit, top = QUANTITY_UNIT[q], QUANTITY_PLAUSIBLE[q]
                for key in self.levels + ("slope",):
                    if key in known:
                        rate = key == "slope"
                        top_k = top / FASTEST_RAMP if rate else top
                        known[key] = dataclasses.replace(
                            known[key], unit=unit + "/s" if rate else unit,
                            plausible=(-top_k, top_k))
            known = MappingProxyType(known)
            if len(self._declared) < 64:     # (bounded: a quantity may be any text)
                self._declared[("parameters", q)] = known
        return known

    def unit_of(self, key: str, values: dict) -> str | None:
        """SI unit of a parameter (a command's values take its ``quantity``'s); None if unknown.

        Parameters
        ----------
        key : str
            Parameter name
        values : dict
            The component's other raw values (for a command's ``quantity``)

        Returns
        -------
        str or None
            The unit (``"Pa"``, ``"m^3/s"``, ``"-"``), None for a parameter the type lacks
        """
        decl = self.declarations(values).get(key)
        return None if decl is None else decl.unit


_FLUID = ("fluid",)
_LINES = ("fluid", "modes_per_section", "line_method")
#: A volume's bulk modulus: the oil's unless given.
_VOLUME_BULK_MODULUS = dataclasses.replace(
    comp.HydraulicVolume.parameters()["bulk_modulus"], optional=True, default=None,
    description="beta of the oil in it; the fluid's when absent")

COMPONENT_TYPES = {t.name: t for t in (
    ComponentType("pressure_source", comp.PressureSource,
                  "known pressure p(t): pump unit or tank (docs/model.md 1)", hidden=("step_time", "step_to")),
    ComponentType("pump", comp.Pump, "positive-displacement pump, fixed or pressure compensated"),
    ComponentType("relief_valve", comp.ReliefValve, "pressure-relief valve, cracking + linear override"),
    ComponentType("hose", comp.HoseSection, "hose section, modal transmission line (M8-M15)",
                  parameters=HOSE_PARAMETERS, hidden=("nominal_pressure",), factory=make_hose,
                  context=_LINES),
    ComponentType("resistance", comp.LinearResistance, "linear flow resistance dp = R q (M1)"),
    ComponentType("check_valve", comp.CheckValve, "check valve, small forward / large reverse R"),
    ComponentType("volume", comp.HydraulicVolume, "lumped oil volume, dp/dt = beta/V sum q",
                  parameters={"bulk_modulus": _VOLUME_BULK_MODULUS}, factory=make_volume,
                  context=_FLUID),
    ComponentType("junction", comp.FlowJunction, "volume-free node, flow = sum of signed flows"),
    ComponentType("accumulator", comp.PistonAccumulator, "gas-charged piston accumulator (M16-M18)",
                  parameters=ACCUMULATOR_CONNECTION_PARAMETERS,
                  hidden=("resistance", "inertance", "connection_model"),
                  factory=make_accumulator, context=("fluid", "modes_per_section")),
    ComponentType("servovalve", comp.Servovalve, "four-way two-stage servovalve (M19-M21)"),
    ComponentType("actuator", comp.Actuator, "double-ended actuator, compressible chambers (M22-M23)"),
    ComponentType("friction", comp.StribeckFriction, "piston friction, Stribeck or LuGre (M24)"),
    ComponentType("load", comp.Load, "specimen spring/damper and applied force on the rod"),
    ComponentType("position_controller", comp.PositionController, "P/PID position controller"),
    ComponentType("step_command", comp.StepCommand, "step command", levels=("initial", "final")),
    ComponentType("sine_command", comp.SineCommand, "sine command", levels=("offset", "amplitude")),
    ComponentType("ramp_command", comp.RampCommand, "ramp command", levels=("initial",)),
    ComponentType("table_command", comp.TableCommand, "command from a CSV table",
                  {"file": Parameter("str", "CSV with units in its header")},
                  hidden=("times", "values"), factory=make_table_command, context=("folder",)),
)}


def _fmt_default(decl) -> str:
    d = decl.default
    if d is None or d is dataclasses.MISSING:
        return "-"
    if isinstance(d, float):
        return f"{d:g}"
    return repr(d) if isinstance(d, str) else str(d)


def parameter_reference() -> str:
    """The component types and their parameters as Markdown, from the declarations alone
    (the reference the docs and ``hydroline circuit --types`` show).

    Returns
    -------
    str
        One section per type: description, ports, then a table of parameter, unit, bounds
        (physical, never overridable), plausible range (overridable with ``[rig]
        allow_implausible``), default and description
    """
    lines = []
    for name, t in COMPONENT_TYPES.items():
        lines += [f"### `{name}`", "", t.description + ".", ""]
        cls = t.component
        ins = [f"`{p}` ({s.quantity})" for p, s in cls.inputs.items()]
        outs = [f"`{p}` ({s.quantity})" for p, s in cls.outputs.items()]
        if ins or outs:   # static ports (others depend on form, causality or terms)
            lines += ["Ports: in " + (", ".join(ins) or "-") + "; out " + (", ".join(outs) or "-")
                      + ".", ""]
        lines += ["| parameter | unit | bounds | plausible | default | description |",
                  "|---|---|---|---|---|---|"]
        for key, d in t.declarations().items():
            unit = {"-": "-", "str": "text"}.get(d.unit, d.unit)
            plausible = "-" if d.plausible is None else " ... ".join(
                "" if v is None else f"{v:g}" for v in d.plausible)
            if key in t.levels + ("slope",) and t.levels:
                unit, plausible = "of quantity", "by quantity"
            lines.append(f"| `{key}` | {unit} | {d.rule()} | {plausible} | {_fmt_default(d)} "
                         f"| {d.description} |")
        lines.append("")
    return "\n".join(lines)
