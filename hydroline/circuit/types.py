"""The component types a circuit file may use, with their parameters declared once.

Each type names a component class of :mod:`hydroline.components` (whose dataclass fields
declare unit, bounds, description and default, see :class:`hydroline.engine.Parameter`) or a
small factory over one (a hose from its length and bore, an accumulator from its connection
passage). Rig schemas, rig validation, circuit-file parsing and ``hydroline circuit`` read
these tables; nothing else repeats a unit or a bound.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from .. import components as comp
from ..engine.component import Parameter
from ..lines import LINE_METHODS

__all__ = ["ComponentType", "COMPONENT_TYPES", "FLUID_PARAMETERS", "HOSE_PARAMETERS",
           "ACCUMULATOR_CONNECTION_PARAMETERS", "CircuitError", "QUANTITY_UNIT",
           "QUANTITY_PLAUSIBLE", "FASTEST_RAMP", "parameter_reference"]


class CircuitError(ValueError):
    """A circuit that cannot be built: one line naming the component and port/parameter."""


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

_COMMAND_KEYS = {"step_command": ("initial", "final"), "sine_command": ("offset", "amplitude"),
                 "ramp_command": ("initial",), "table_command": ()}


@dataclass(frozen=True)
class ComponentType:
    """One component type of a circuit file.

    Parameters
    ----------
    name : str            The ``type = "..."`` of the file
    component : type      Component class built
    description : str     One line for ``hydroline circuit`` and the docs
    parameters : dict     Extra file parameters (name -> Parameter) a factory turns into the
                          component's own ones
    hidden : tuple        Component fields not given in the file (set by the builder)
    """

    name: str
    component: type
    description: str
    parameters: dict = field(default_factory=dict)
    hidden: tuple = ()

    def declarations(self, values: dict | None = None) -> dict:
        """Every parameter a file may give for this type, name -> Parameter; a command's
        levels (initial, final, offset, amplitude, slope) in the SI unit and plausible range
        of its ``quantity`` (:data:`QUANTITY_PLAUSIBLE`).

        Parameters
        ----------
        values : dict  The component's values as given (its ``quantity``); None: the defaults
        """
        own = {k: v for k, v in self.component.parameters().items() if k not in self.hidden}
        out = {**own, **self.parameters}
        q = (values or {}).get("quantity", "current")
        if self.name in _COMMAND_KEYS and q in QUANTITY_UNIT:
            unit, top = QUANTITY_UNIT[q], QUANTITY_PLAUSIBLE[q]
            for key in _COMMAND_KEYS[self.name] + ("slope",):
                if key in out:
                    rate = key == "slope"
                    top_k = top / FASTEST_RAMP if rate else top
                    out[key] = dataclasses.replace(out[key], unit=unit + "/s" if rate else unit,
                                                   plausible=(-top_k, top_k))
        return out

    def unit_of(self, key: str, values: dict) -> str | None:
        """SI unit of a parameter (a command's values take its ``quantity``'s); None if unknown.

        Parameters
        ----------
        key : str      Parameter name
        values : dict  The component's other raw values (for a command's ``quantity``)
        """
        decl = self.declarations(values).get(key)
        return None if decl is None else decl.unit


def _cmd(cls, **extra):
    return {"quantity": Parameter("str", "what the command drives", choices=tuple(QUANTITY_UNIT),
                                  default="current"), **extra}


COMPONENT_TYPES = {t.name: t for t in (
    ComponentType("pressure_source", comp.PressureSource,
                  "known pressure p(t): pump unit or tank (docs/model.md 1)", hidden=("step_time", "step_to")),
    ComponentType("pump", comp.Pump, "positive-displacement pump, fixed or pressure compensated"),
    ComponentType("relief_valve", comp.ReliefValve, "pressure-relief valve, cracking + linear override"),
    ComponentType("hose", comp.HoseSection, "hose section, modal transmission line (M8-M15)",
                  parameters=HOSE_PARAMETERS, hidden=("nominal_pressure",)),
    ComponentType("resistance", comp.LinearResistance, "linear flow resistance dp = R q (M1)"),
    ComponentType("check_valve", comp.CheckValve, "check valve, small forward / large reverse R"),
    ComponentType("volume", comp.HydraulicVolume, "lumped oil volume, dp/dt = beta/V sum q"),
    ComponentType("junction", comp.FlowJunction, "volume-free node, flow = sum of signed flows"),
    ComponentType("accumulator", comp.PistonAccumulator, "gas-charged piston accumulator (M16-M18)",
                  parameters=ACCUMULATOR_CONNECTION_PARAMETERS,
                  hidden=("resistance", "inertance", "connection_model")),
    ComponentType("servovalve", comp.Servovalve, "four-way two-stage servovalve (M19-M21)"),
    ComponentType("actuator", comp.Actuator, "double-ended actuator, compressible chambers (M22-M23)"),
    ComponentType("friction", comp.StribeckFriction, "piston friction, Stribeck or LuGre (M24)"),
    ComponentType("load", comp.Load, "specimen spring/damper and applied force on the rod"),
    ComponentType("position_controller", comp.PositionController, "P/PID position controller"),
    ComponentType("step_command", comp.StepCommand, "step command", _cmd(comp.StepCommand)),
    ComponentType("sine_command", comp.SineCommand, "sine command", _cmd(comp.SineCommand)),
    ComponentType("ramp_command", comp.RampCommand, "ramp command", _cmd(comp.RampCommand)),
    ComponentType("table_command", comp.TableCommand, "command from a CSV table",
                  _cmd(comp.TableCommand, file=Parameter("str", "CSV with units in its header")),
                  hidden=("times", "values")),
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
    str  One section per type: description, ports, then a table of parameter, unit, bounds
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
            if name in _COMMAND_KEYS and key in _COMMAND_KEYS[name] + ("slope",):
                unit, plausible = "of quantity", "by quantity"
            lines.append(f"| `{key}` | {unit} | {d.rule()} | {plausible} | {_fmt_default(d)} "
                         f"| {d.description} |")
        lines.append("")
    return "\n".join(lines)
