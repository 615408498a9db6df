"""Build the electrohydraulic test system's network from a rig (docs/model.md sections 1, 6).

Every rig is built by the circuit builder (:mod:`hydroline.circuit`) and checked by it: a
circuit rig from its ``[circuit.<name>]`` tables, the 2005 paper's template rig (``[supply]``,
``[supply.section1]``, ..., ``[servovalve]``, ``[actuator]``) from the circuit it expands into
(:func:`hydroline.rigs.template.expand`, where its signal names are listed).
"""
from __future__ import annotations

from .fluid import Fluid
from .circuit import (Circuit, CircuitError, build_components, circuit_specs, has_circuit,
                      rig_fluid)
from .engine import Network
from .rigs import Rig, RigError, declarations
from .rigs.parameters import check_ranges
from .rigs.template import (bad_value, check_template, expand, make_line, pressure_profile,
                            section_present)

__all__ = ["build_network", "build_circuit", "make_fluid", "make_line", "hose_lines",
           "validate_rig", "pressure_profile"]


def make_fluid(rig: Rig) -> Fluid:
    """The rig's fluid (``[fluid]``: density, kinematic viscosity, bulk modulus).

    Parameters
    ----------
    rig : Rig
        Parameters (SI)

    Returns
    -------
    Fluid
        The oil of ``[fluid]`` (SI)

    Raises
    ------
    RigError
        One line naming the fluid parameter at fault
    """
    try:
        return rig_fluid(rig)
    except CircuitError as e:
        raise RigError(str(e)) from None


def hose_lines(rig: Rig) -> dict:
    """All hose sections of a template rig with a positive length, name -> Line.

    Parameters
    ----------
    rig : Rig
        Parameters (SI)

    Returns
    -------
    dict
        ``"supply.section1"``, ... -> :class:`Line`
    """
    fluid = make_fluid(rig)
    out = {}
    for side in ("supply", "return"):
        for sec in ("section1", "section2"):
            name = f"{side}.{sec}"
            if sec == "section2" and not section_present(rig, name):
                continue
            out[name] = make_line(rig, name, fluid)
    return out


def validate_rig(rig: Rig, position_guess: float | None = None) -> dict:
    """Refuse, with a RigError naming the parameter and its unit, values no physical rig has.

    Checked: every value against its component's declaration (bounds), then for a circuit rig
    the rig-wide ranges (its components' values: by the circuit builder), for a template rig
    its own checks (:func:`hydroline.rigs.template.check_template`): signs (positive sizes,
    moduli, masses, pressures absolute > 0, non-negative resistances, gains and friction
    coefficients), ``supply.pressure > return.pressure > 0`` (docs/model.md 1: the valve needs
    a supply above the tank), ``|initial_position| <= stroke/2`` (the piston inside the
    cylinder, M23), accumulator pre-charges below the pressure of their side (an accumulator
    pre-charged above it holds no oil, M16), laps shorter than the spool stroke (M20) and the
    polytropic exponent within [1, 5/3] (isothermal ... monatomic adiabatic, M16).

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    position_guess : float
        Initial piston position given by the scenario, [m]; checked
        like ``actuator.initial_position`` when not None

    Returns
    -------
    dict
        side -> its :func:`pressure_profile` (read once, for the template's expansion);
        {} for a circuit rig
    """
    declared = {}       # section -> its declarations, looked up once per section
    for path, v in rig.values.items():
        section, _, key = path.rpartition(".")
        if section not in declared:
            declared[section] = declarations(section)
        decl = declared[section].get(key)
        if decl is not None:
            rule = decl.violation(v)
            if rule is not None:
                raise bad_value(rig, path, rule)
    if has_circuit(rig.values):
        check_ranges(rig)      # the rig-wide settings, the oil, the scenarios (the components':
        return {}              # hydroline.circuit.builder, against their declarations)
    return check_template(rig, position_guess)


def build_network(rig: Rig, commands: list, position_guess: float | None = None) -> Network:
    """The full test-system network of a rig, driven by the given command components.

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    commands : list
        Components that output each axis's valve current (open loop) or
        position reference plus a controller (closed loop); see
        :attr:`Circuit.axes` for the signal names
    position_guess : float
        Initial piston position of the first axis for the steady-state
        solver, [m]

    Returns
    -------
    Network
        The network, ready for its steady state and integration
    """
    circuit = build_circuit(rig, position_guess)
    try:
        return circuit.network(commands)
    except CircuitError as e:
        raise RigError(str(e)) from None


def build_circuit(rig: Rig, position_guess: float | None = None) -> Circuit:
    """The components of a rig and their axis handles, before an experiment's commands.

    A rig with ``[circuit.<name>]`` tables is built from that description
    (:func:`hydroline.circuit.circuit_specs`); the 2005 paper's flat rig (sections
    ``supply``, ``supply.section1``, ..., ``servovalve``, ``actuator``) is a compact template
    that expands into the same kind of component list
    (:func:`hydroline.rigs.template.expand`). Both are made and checked by
    :func:`hydroline.circuit.build_components`.

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    position_guess : float
        Initial piston position of the first axis, [m]; None: the rig's

    Returns
    -------
    Circuit
        components, axes (handles), source
    """
    circuit_rig = has_circuit(rig.values)
    profiles = validate_rig(rig, None if circuit_rig else position_guess)
    overrides = _overrides(rig)
    try:
        if circuit_rig:
            circuit = build_components(rig, circuit_specs(rig), overrides)
        else:   # the template's four wirings (a section II or not, each side) are checked by
            # tests/test_wiring.py; with [connections] the circuit is checked like any other
            circuit = build_components(rig, expand(rig, profiles), overrides,
                                       wiring=bool(overrides), port_path="{component}.{port}",
                                       label="connections")
        circuit.place(position_guess)
    except CircuitError as e:
        raise RigError(str(e)) from None
    if circuit_rig:
        _check_controller_table(rig, circuit)
    return circuit


def _check_controller_table(rig: Rig, circuit: Circuit):
    """A circuit rig's ``[controller]`` closes the loop of an axis whose circuit has no
    position controller: refused by name where every axis has its own (it would not be used)."""
    key = next((k for k in rig.values if k.startswith("controller.")), None)
    if key is not None and circuit.axes and all(ax.controller for ax in circuit.axes.values()):
        own = ", ".join(ax.controller for ax in circuit.axes.values())
        raise RigError(f"{key}: every axis of the circuit has its own position controller "
                       f"({own}); the [controller] table, which closes the loop of an axis "
                       f"without one, would not be used: remove it, or set the gains there")


def _overrides(rig):
    """The rig's ``[connections]`` overrides, "component.port" -> signal."""
    return {path[len("connections."):]: signal for path, signal in rig.values.items()
            if path.startswith("connections.")}
