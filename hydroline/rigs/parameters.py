"""Every rig parameter in one declarative table: SI unit, plausible range, default, meaning.

:data:`PARAMETERS` maps a parameter's dotted path to a :class:`Parameter`. It is the one place
that says what a value of a rig may be; :func:`check_ranges` refuses a value outside its
plausible range with one line naming the parameter, its range and its unit, and
:func:`defaults_used` lists the parameters a run takes from a default because the rig file does
not give them (``hydroline simulate`` prints that list once on stderr).

Plausible is wider than typical: the bounds catch slips of unit or exponent (an actuator area
of 1e-30 cm^2, a dead volume of 1e30 cm^3, a 1e30 L accumulator), not unusual designs. A rig
that really is outside a range names the parameter in ``[rig] allow_implausible``::

    [rig]
    allow_implausible = ["actuator.moving_mass", "rig.modes_per_section"]

Consistency checks between parameters (:func:`check_consistency`) follow the same rule: a
weight the actuator cannot lift, a step current above the valve's rating (the valve would
clip it), a sine reference that leaves the stroke. Signs and orderings that no physical rig
can violate (pressures absolute and positive, pre-charge below the line pressure, the piston
inside the cylinder) are checked by :func:`hydroline.system.validate_rig` and cannot be
overridden.

Units, descriptions, plausible ranges and defaults of parameters that belong to a component
live on the component's declaration (``parameter(default, ..., plausible=(low, high))``,
:class:`hydroline.engine.Parameter`); this table only adds how the template rig uses them
(scope; whether a rig must give one, or a default taken from another path) and declares the
template's own parameters (supply and tank pressure, dead volume, scenarios). Circuit files and
the circuit the template expands into (:mod:`hydroline.rigs.template`) are checked against the
same declarations (:func:`hydroline.circuit.build_components`).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["Parameter", "Declared", "DerivedTable", "PARAMETERS", "REQUIRED", "COMPONENT_DEFAULT",
           "ATMOSPHERIC_PRESSURE",
           "check_ranges", "check_consistency", "defaults_used", "allowed_implausible",
           "steady_state_hint", "MIN_GAS_FRACTION"]

#: Smallest gas volume of an accumulator model as a fraction of its capacity (the piston at
#: its gas-side end, hydroline.components.PistonAccumulator), [-].
MIN_GAS_FRACTION = 1e-3

#: Marks a parameter without a default: a rig must give it.
REQUIRED = "required"

#: Marks a :class:`Declared` parameter whose default is its component's declared one (a rig
#: that does not give it leaves the component's default in place: declared there, once).
COMPONENT_DEFAULT = "component default"

#: Standard atmosphere, [Pa]: the default gas-release pressure (oil that stood in a vented
#: tank holds air dissolved at this pressure and starts releasing it below, Henry's law).
ATMOSPHERIC_PRESSURE = 101325.0


@dataclass(frozen=True)
class Parameter:
    """One rig parameter.

    Attributes
    ----------
    unit : str
        SI unit (``"-"`` dimensionless, ``"str"`` text)
    low, high : float
        Plausible range, inclusive, [unit]; None: no bound on that side
    description : str
        What it is (said in messages)
    default : object
        Value used when the rig does not give it: a number [unit], the dotted
        path of another parameter whose value is taken, None (the feature is
        off), or :data:`REQUIRED`
    scope : str
        When the parameter changes a run: "always", a scenario name,
        "close-coupled" (section II of zero length), "lugre" (friction model),
        "modal-accumulator", "load-spring" (a load stiffness given),
        "entrained-air" (a fluid.air_content given), "cavity" (the cavity model
        on: fluid.cavity_pressure not "off"), "viscoelastic" (a hose wall given)
    zero_allowed : bool
        0 is accepted below ``low`` (a length of 0 removes a hose section)
    integer : bool
        The value must be a whole number
    inherited : bool
        The default is a rig-wide setting by design (the modes of a section
        are ``rig.modes_per_section``): not reported as a default
    """

    unit: str
    low: float | None
    high: float | None
    description: str
    default: object = REQUIRED
    scope: str = "always"
    zero_allowed: bool = False
    integer: bool = False
    inherited: bool = False


def _sides(template: dict) -> dict:
    out = {}
    for side in ("supply", "return"):
        for key, p in template.items():
            out[key.format(side=side)] = p
    return out


_STEP, _SINE = "open-loop-step", "closed-loop-sine"

@dataclass(frozen=True)
class Declared:
    """A parameter of the template rig that a component (or the hose, fluid, accumulator
    passage tables of :mod:`hydroline.circuit.types`) declares: its unit, description and
    plausible range are read from that declaration (:class:`hydroline.engine.Parameter`);
    only how the template uses it is said here.

    Attributes
    ----------
    default : object
        As for :class:`Parameter`: a number [unit], a dotted path, None or
        :data:`REQUIRED`; :data:`COMPONENT_DEFAULT`: the declaration's
    scope : str
        As for :class:`Parameter`: when the parameter changes a run
    zero_allowed : bool
        As for :class:`Parameter`: 0 is accepted below the range
    integer : bool
        As for :class:`Parameter`: the value must be a whole number
    inherited : bool
        As for :class:`Parameter`: a rig-wide default by design
    """

    default: object = REQUIRED
    scope: str = "always"
    zero_allowed: bool = False
    integer: bool = False
    inherited: bool = False


def _declaration(path: str):
    """The component-side declaration behind a template path (None: template-only)."""
    from ..circuit.types import HOSE_PARAMETERS
    from . import declarations   # the package imports this module; declarations lives there

    section, key = path.rsplit(".", 1)
    if section.endswith((".section1", ".section2")):
        return HOSE_PARAMETERS.get(key)
    return declarations(section).get(key)


def _resolve(path: str, entry) -> Parameter:
    if isinstance(entry, Parameter):
        return entry
    decl = _declaration(path)
    if decl is None or decl.plausible is None:
        raise AssertionError(f"{path}: no declaration with a plausible range on its component")
    low, high = decl.plausible
    default = decl.default if entry.default == COMPONENT_DEFAULT else entry.default
    return Parameter(decl.unit.replace("list:", ""), low, high, decl.description,
                     default, entry.scope, entry.zero_allowed, entry.integer, entry.inherited)


class DerivedTable(Mapping):
    """A table whose keys are known up front and whose values are derived on first use,
    ``derive(key, entry)`` for every entry (the declarations behind them live on the
    components, whose import a module that only names the table does not pay for).

    Parameters
    ----------
    entries : dict
        key -> what the value is derived from
    derive : callable
        ``(key, entry) -> value``
    """

    def __init__(self, entries, derive):
        self.entries, self._derive, self._table = entries, derive, None

    def _build(self):
        if self._table is None:
            self._table = {key: self._derive(key, e) for key, e in self.entries.items()}
        return self._table

    def __getitem__(self, key):
        return self._build()[key]

    def __iter__(self):
        return iter(self.entries)

    def __len__(self):
        return len(self.entries)

    def items(self):
        """(key, value) pairs of the derived table (its dict's view: no lookup per key).

        Returns
        -------
        ItemsView
            The derived table's items
        """
        return self._build().items()

    def values(self):
        return self._build().values()

    def __contains__(self, key):
        return key in self.entries


#: path -> Parameter, for every numeric parameter of a rig (text parameters and the optional
#: pressure profiles are checked where they are read, hydroline.rigs.template). Entries marked
#: :class:`Declared` take unit, description, plausible range and (with
#: :data:`COMPONENT_DEFAULT`) default from the component's own declaration; the others exist
#: only in the template rig (pressures, dead volume, scenarios).
PARAMETERS: Mapping = DerivedTable({
    "rig.allow_implausible": Parameter("str", None, None, "parameters allowed outside their "
                                       "plausible range", None),
    "rig.modes_per_section": Declared(COMPONENT_DEFAULT, integer=True),
    "fluid.density": Declared(),
    "fluid.kinematic_viscosity": Declared(),
    "fluid.bulk_modulus": Declared(),
    # entrained air and viscoelastic walls: off unless the rig turns them on (their defaults
    # are not reported as used by a rig without them); cavities: on unless the rig says
    # cavity_pressure = "off" (issue 30: no negative absolute pressure)
    "fluid.air_content": Declared(COMPONENT_DEFAULT, scope="entrained-air"),
    "fluid.air_polytropic_exponent": Declared(COMPONENT_DEFAULT, scope="entrained-air"),
    "fluid.cavity_pressure": Declared(COMPONENT_DEFAULT),
    "fluid.cavity_pressure_drop": Declared(COMPONENT_DEFAULT, scope="cavity"),
    "fluid.gas_release_pressure": Parameter(
        "Pa", 0.0, 1e6, "absolute pressure below which dissolved air leaves the oil (the line "
        "model no longer holds)", ATMOSPHERIC_PRESSURE),
    "supply.pressure": Parameter("Pa", 1e5, 1e8, "supply (pump) pressure, absolute"),
    "return.pressure": Parameter("Pa", 1e4, 5e7, "tank (return) pressure, absolute"),
    **_sides({
        "{side}.section1.length": Declared(),
        "{side}.section2.length": Declared(zero_allowed=True),
        "{side}.section1.diameter": Declared(),
        "{side}.section2.diameter": Declared(),
        "{side}.section1.bulk_modulus": Declared(default="fluid.bulk_modulus"),
        "{side}.section2.bulk_modulus": Declared(default="fluid.bulk_modulus"),
        "{side}.section1.modes": Declared(default="rig.modes_per_section", integer=True,
                                          inherited=True),
        "{side}.section2.modes": Declared(default="rig.modes_per_section", integer=True,
                                          inherited=True),
        "{side}.section1.creep_compliances": Declared(COMPONENT_DEFAULT, scope="viscoelastic"),
        "{side}.section2.creep_compliances": Declared(COMPONENT_DEFAULT, scope="viscoelastic"),
        "{side}.section1.retardation_times": Declared(COMPONENT_DEFAULT, scope="viscoelastic"),
        "{side}.section2.retardation_times": Declared(COMPONENT_DEFAULT, scope="viscoelastic"),
        "{side}.manifold.resistance": Declared(),
        "{side}.manifold.volume": Parameter("m^3", 1e-7, 1e-2, "manifold block oil volume, the "
                                            "node when section II is removed", 50e-6,
                                            scope="close-coupled"),
        "{side}.accumulator.capacity": Declared(),
        "{side}.accumulator.precharge_pressure": Declared(),
        "{side}.accumulator.polytropic_exponent": Declared(),
        "{side}.accumulator.connection_length": Declared(),
        "{side}.accumulator.connection_diameter": Declared(),
        "{side}.accumulator.modes": Declared(default="rig.modes_per_section",
                                             scope="modal-accumulator", integer=True,
                                             inherited=True),
    }),
    "return.check_valve.reverse_resistance": Declared(COMPONENT_DEFAULT),
    "return.check_valve.forward_resistance": Declared(COMPONENT_DEFAULT),
    "servovalve.rated_current": Declared(),
    "servovalve.rated_flow": Declared(),
    "servovalve.rated_pressure_drop": Declared(),
    "servovalve.max_opening": Declared(),
    "servovalve.natural_frequency": Declared(),
    "servovalve.damping_ratio": Declared(),
    "servovalve.laps": Declared(COMPONENT_DEFAULT),
    "servovalve.laminar_pressure": Declared(COMPONENT_DEFAULT),
    "actuator.area": Parameter("m^2", 1e-6, 1.0, "piston area, both sides", None),
    "actuator.bottom_area": Declared(default=None),
    "actuator.top_area": Declared(default=None),
    "actuator.stroke": Declared(),
    "actuator.dead_volume": Parameter("m^3", 1e-8, 1e-2, "dead volume per chamber"),
    "actuator.bulk_modulus": Declared(),
    "actuator.moving_mass": Declared(),
    "actuator.initial_position": Declared(COMPONENT_DEFAULT),
    "actuator.gravity": Declared(COMPONENT_DEFAULT),
    "actuator.internal_leakage": Declared(COMPONENT_DEFAULT),
    "actuator.external_leakage": Declared(COMPONENT_DEFAULT),
    "friction.viscous_up": Declared(COMPONENT_DEFAULT),
    "friction.viscous_down": Declared(COMPONENT_DEFAULT),
    "friction.coulomb_up": Declared(COMPONENT_DEFAULT),
    "friction.coulomb_down": Declared(COMPONENT_DEFAULT),
    "friction.static_up": Declared(COMPONENT_DEFAULT),
    "friction.static_down": Declared(COMPONENT_DEFAULT),
    "friction.stribeck_velocity": Declared(COMPONENT_DEFAULT),
    "friction.stribeck_exponent": Declared(COMPONENT_DEFAULT),
    "friction.regularization_velocity": Declared(COMPONENT_DEFAULT),
    "friction.bristle_stiffness": Declared(COMPONENT_DEFAULT, scope="lugre"),
    "friction.bristle_damping": Declared(COMPONENT_DEFAULT, scope="lugre"),
    "load.mass": Declared(COMPONENT_DEFAULT),
    "load.stiffness": Declared(COMPONENT_DEFAULT),
    "load.damping": Declared(COMPONENT_DEFAULT),
    "load.applied_force": Declared(COMPONENT_DEFAULT),
    "load.free_position": Declared(COMPONENT_DEFAULT, scope="load-spring"),
    "controller.proportional_gain": Declared(scope=_SINE),
    "controller.integral_gain": Declared(COMPONENT_DEFAULT, scope=_SINE),
    "controller.derivative_gain": Declared(COMPONENT_DEFAULT, scope=_SINE),
    "controller.current_limit": Declared(default="servovalve.rated_current", scope=_SINE),
    "controller.sample_time": Declared(default=None, scope=_SINE),
    f"scenario.{_STEP}.current": Parameter("A", -5.0, 5.0, "step current",
                                           "servovalve.rated_current", scope=_STEP),
    f"scenario.{_STEP}.initial_current": Parameter("A", -5.0, 5.0, "current before the step",
                                                   0.0, scope=_STEP),
    f"scenario.{_STEP}.time": Parameter("s", 0.0, 100.0, "time of the step", 0.01, scope=_STEP),
    f"scenario.{_STEP}.t_end": Parameter("s", 1e-4, 100.0, "simulated time", 0.25, scope=_STEP),
    "scenario.position-step.step": Parameter("m", -5.0, 5.0, "position reference step",
                                             scope="position-step"),
    "scenario.position-step.time": Parameter("s", 0.0, 100.0, "time of the step", 0.01,
                                             scope="position-step"),
    "scenario.position-step.t_end": Parameter("s", 1e-4, 100.0, "simulated time", 0.15,
                                              scope="position-step"),
    f"scenario.{_SINE}.amplitude": Parameter("m", 0.0, 5.0, "sine reference amplitude",
                                             scope=_SINE),
    f"scenario.{_SINE}.frequency": Parameter("Hz", 1e-3, 1e3, "sine reference frequency",
                                             scope=_SINE),
    f"scenario.{_SINE}.offset": Parameter("m", -5.0, 5.0, "sine reference offset", 0.0,
                                          scope=_SINE),
    f"scenario.{_SINE}.t_end": Parameter("s", 1e-4, 100.0, "simulated time", 1.0, scope=_SINE),
    f"scenario.{_SINE}.initial_position": Parameter("m", -5.0, 5.0, "initial piston position",
                                                    0.0, scope=_SINE),
}, _resolve)


def _value(rig, path: str):
    """A rig's value at ``path``, else its default (:data:`PARAMETERS`), [SI]."""
    return rig.get(path, PARAMETERS[path].default)


def _error(message):
    from . import RigError   # the package imports this module; RigError lives there

    return RigError(message)


def allowed_implausible(rig) -> set:
    """The paths a rig lists in ``rig.allow_implausible`` (checked: each one a parameter).

    Parameters
    ----------
    rig : Rig
        Parameters (SI)

    Returns
    -------
    set
        Dotted parameter paths whose plausible range (or consistency check) is overridden

    Raises
    ------
    RigError
        One line naming a listed path that is not a rig parameter with a range
    """
    listed = rig.get("rig.allow_implausible") or []
    for path in listed:
        if path.startswith("circuit."):   # a circuit component's parameter (its range is
            if not _circuit_parameter(rig, path):   # checked where the circuit is built)
                raise _error(f"rig.allow_implausible: {path!r} is not a parameter of a circuit "
                             f"component of the rig (e.g. 'circuit.<name>.<parameter>')")
            continue
        if path not in PARAMETERS:
            raise _error(f"rig.allow_implausible: {path!r} is not a rig parameter with a "
                         f"plausible range (e.g. 'actuator.moving_mass')")
    return set(listed)


def _circuit_parameter(rig, path: str) -> bool:
    """True when ``path`` is ``circuit.<name>.<key>`` of a component of the rig whose type
    declares the parameter ``key``."""
    from ..circuit.types import COMPONENT_TYPES

    for key, ctype in rig.values.items():
        head = key[:-len("type")]
        if key.startswith("circuit.") and key.endswith(".type") and path.startswith(head) \
                and ctype in COMPONENT_TYPES \
                and path[len(head):] in COMPONENT_TYPES[ctype].declarations():
            return True
    return False


def _shown(rig, path, value):
    raw = rig.raw.get(path)
    return repr(raw) if raw is not None else f"{value:g}"


def _fmt(x):
    return f"{x:g}"


def check_ranges(rig):
    """Refuse a value outside its plausible range (:data:`PARAMETERS`) or a fractional count.

    Parameters
    ----------
    rig : Rig
        Parameters (SI)

    Raises
    ------
    RigError
        One line: the path, the value as written, the range with its SI unit, and how to
        override (``[rig] allow_implausible``)
    """
    from ..engine.component import range_text   # the wording the circuit files use too

    allowed = allowed_implausible(rig)
    for path, p in PARAMETERS.items():
        value = rig.get(path)
        if value is None or p.unit == "str":
            continue
        values = value if isinstance(value, list) else (value,)
        unit = "" if p.unit == "-" else " [" + p.unit + "]"
        for v in values:
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise _error(f"{path}: must be a finite number{unit}, got {_shown(rig, path, v)}")
            if p.integer and v != int(v):
                raise _error(f"{path}: must be a whole number ({p.description}), got "
                             f"{_shown(rig, path, v)}")
            if p.zero_allowed and v == 0:
                continue
            if p.low is not None and p.low >= 0 and v < 0:   # no override makes a size negative
                rule = "positive" if p.low > 0 else ">= 0"
                raise _error(f"{path}: must be {rule}{unit} ({p.description}), got "
                             f"{_shown(rig, path, v)}")
            low_ok = p.low is None or v >= p.low
            high_ok = p.high is None or v <= p.high
            if low_ok and high_ok or path in allowed:
                continue
            rule = range_text(p.low, p.high)
            zero = " (or 0)" if p.zero_allowed else ""
            raise _error(f"{path}: {_shown(rig, path, v)} is outside its plausible range, "
                         f"{rule}{zero}{unit} ({p.description}); if it is meant, add "
                         f"\"{path}\" to [rig] allow_implausible")


def check_consistency(rig, scenario: str | None = None):
    """Refuse parameter combinations no test can mean (overridable like a range).

    * the static load -- weight of the moving mass and the load, ``(m + m_L) g``, plus the
      applied force -- beyond the actuator's force capacity ``p_s A_b - p_t A_t`` (M23):
      the piston could never lift off its stop;
    * a step current (open-loop-step) beyond the servovalve's rated current: the valve would
      saturate at ``max_opening`` and the step be clipped silently;
    * a sine reference (closed-loop-sine) whose ``|offset| + amplitude`` leaves +-stroke/2.

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    scenario : str
        The scenario run: only its checks are made (the command against
        the rating and stroke); None: the rig's own (weight, pre-charge)

    Raises
    ------
    RigError
        One line naming the parameter to look at, its unit and the override
    """
    allowed = allowed_implausible(rig)

    def refuse(path, text):
        if path not in allowed:
            raise _error(f"{path}: {text}; if it is meant, add \"{path}\" to [rig] "
                         f"allow_implausible")

    if scenario is not None:
        _check_scenario_consistency(rig, scenario, refuse)
        return
    area = rig.get("actuator.area")
    a_b = rig.get("actuator.bottom_area", area)
    a_t = rig.get("actuator.top_area", area)
    p_s, p_t = rig.get("supply.pressure"), rig.get("return.pressure")
    mass = rig.get("actuator.moving_mass")
    if None not in (a_b, a_t, p_s, p_t, mass):
        g = _value(rig, "actuator.gravity")
        load = _value(rig, "load.mass")
        weight = (mass + load) * g - _value(rig, "load.applied_force")
        capacity = p_s * a_b - p_t * a_t
        if weight > capacity > 0:
            path = "load.mass" if load > 0 else "actuator.moving_mass"
            refuse(path, f"the weight of the moving mass and load, {weight / 1e3:.3g} kN "
                   f"[(m + m_L) g - applied force], exceeds the actuator's force capacity "
                   f"p_s A_b - p_t A_t = {capacity / 1e3:.3g} kN: the piston cannot lift off")
    for side in ("supply", "return"):     # a model limit, not overridable
        path = f"{side}.accumulator.precharge_pressure"
        p0, p_line = rig.get(path), rig.get(f"{side}.pressure")
        if p0 is not None and p_line and p0 > 0 and p0 < 1.05 * MIN_GAS_FRACTION * p_line:
            raise _error(f"{path}: {_shown(rig, path, p0)} is {100 * p0 / p_line:.2g} % of "
                         f"{side}.pressure: charged to it (isothermally, M16) the gas would "
                         f"shrink below {100 * MIN_GAS_FRACTION:g} % of the capacity, where "
                         f"the accumulator's piston reaches its gas-side end and no rest state "
                         f"exists; pre-charge to at least {100 * 1.05 * MIN_GAS_FRACTION:.2g} % "
                         f"(usually 25-90 %) of the line pressure [Pa, absolute]")


def _plausible(path, value) -> bool:
    """True for a number within the path's plausible range (else its own check names it)."""
    p = PARAMETERS[path]
    return (isinstance(value, (int, float)) and math.isfinite(value)
            and (p.low is None or value >= p.low) and (p.high is None or value <= p.high))


def _check_scenario_consistency(rig, scenario, refuse):
    """The scenario's command against the valve's rating and the stroke (values of the wrong
    sign are left to :func:`hydroline.system.validate_rig`, which names them)."""
    rated = rig.get("servovalve.rated_current")
    if scenario == _STEP and _plausible("servovalve.rated_current", rated):
        for key in ("current", "initial_current"):
            path = f"scenario.{_STEP}.{key}"
            i = rig.get(path)
            if i is not None and abs(i) > rated * (1 + 1e-9):
                refuse(path, f"{_shown(rig, path, i)} exceeds the servovalve's rated current "
                       f"{rated * 1e3:g} mA [A] (the valve would clip it to its full opening)")
    stroke = rig.get("actuator.stroke")
    if scenario == _SINE and _plausible("actuator.stroke", stroke):
        amp = rig.get(f"scenario.{_SINE}.amplitude")
        offset = rig.get(f"scenario.{_SINE}.offset", 0.0)
        if amp is not None and abs(offset) + abs(amp) > stroke / 2 * (1 + 1e-9):
            path = f"scenario.{_SINE}.amplitude"
            refuse(path, f"|offset| + amplitude = {(abs(offset) + abs(amp)) * 1e3:g} mm [m] "
                   f"leaves the stroke (+-{stroke / 2 * 1e3:g} mm): the piston would hit its stops")


def _in_scope(rig, p: Parameter, path: str, scenario: str | None) -> bool:
    if p.scope == "always":
        return True
    if p.scope in (_STEP, _SINE, "position-step"):
        return scenario == p.scope
    side = path.split(".")[0]
    if p.scope == "close-coupled":
        return rig.get(f"{side}.section2.length", 0.0) == 0
    if p.scope == "lugre":
        return rig.get("friction.model") == "lugre"
    if p.scope == "load-spring":
        return _value(rig, "load.stiffness") != 0
    if p.scope == "modal-accumulator":
        return rig.get(f"{side}.accumulator.model") == "modal"
    if p.scope == "entrained-air":
        return bool(rig.get("fluid.air_content"))
    if p.scope == "cavity":
        return _value(rig, "fluid.cavity_pressure") is not None
    if p.scope == "viscoelastic":
        section = path.rpartition(".")[0]
        return bool(rig.get(f"{section}.creep_compliances") or
                    rig.get(f"{section}.retardation_times"))
    return True


def defaults_used(rig, scenario: str | None = None) -> list[tuple[str, str]]:
    """The parameters a run of ``scenario`` takes from a default, not from the rig.

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    scenario : str
        The scenario run (only the parameters it uses); None: every parameter

    Returns
    -------
    list of tuple of str
        (path, what is used) -- e.g. ``("supply.section1.bulk_modulus",
        "fluid.bulk_modulus = 1.5e+09 Pa")``, in table order; parameters whose default turns a
        feature off (no sample time, no area when both side areas are given) are left out
    """
    from ..circuit import has_circuit

    if has_circuit(rig.values):   # the table describes the flat (template) rig; a circuit's
        return []                 # components declare their own parameters and defaults
    out = []
    for path, p in PARAMETERS.items():
        if path in rig or p.default is None or p.default == REQUIRED or p.inherited:
            continue
        if not _in_scope(rig, p, path, scenario):
            continue
        unit = "" if p.unit == "-" else f" {p.unit}"
        if isinstance(p.default, str):
            value = rig.get(p.default, PARAMETERS[p.default].default)
            if value is None or value == REQUIRED:
                continue
            out.append((path, f"{p.default} = {_fmt_value(value)}{unit}"))
        else:
            out.append((path, f"{_fmt_value(p.default)}{unit}"))
    return out


def _fmt_value(v):
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return _fmt(v)


#: Where a steady-state solve that fails at a state points: a state-name prefix -> the
#: balance that does not close and the parameters to look at (first match wins).
_STATE_HINTS = (
    ("accumulator", "the {side} accumulator's gas cannot balance the line pressure",
     "{side}.accumulator.precharge_pressure, {side}.accumulator.capacity, {side}.pressure"),
    ("section", "the flow along {section} does not settle",
     "{section}.diameter, {section}.length, {section}.bulk_modulus, servovalve.laps "
     "(the null leakage it carries), return.check_valve"),
    ("servovalve", "the spool does not find its rest position",
     "servovalve.laps, servovalve.max_opening, scenario current"),
    ("actuator", "the forces on the piston or the chamber flows do not balance",
     "actuator.initial_position, actuator.area, load.mass, load.applied_force, "
     "servovalve.laps, actuator.internal_leakage"),
    ("friction", "the friction state does not settle", "friction.*"),
    ("controller", "the position loop does not hold the piston",
     "controller.proportional_gain, scenario initial_position"),
)


def steady_state_hint(state: str) -> str:
    """The balance behind a state that keeps a steady-state solve from converging and the rig
    parameters to look at, e.g. ``"the flow along return.section2 does not settle (look at
    return.section2.diameter, ...)"``.

    Parameters
    ----------
    state : str
        Dotted state name, e.g. ``"return.section2.mode1.flow"``

    Returns
    -------
    str
        One phrase for an error message
    """
    parts = state.split(".")
    side = parts[0] if parts[0] in ("supply", "return") else "supply"
    section = ".".join(parts[:2]) if len(parts) > 1 else state
    for key, balance, params in _STATE_HINTS:
        if key in state:
            text = balance.format(side=side, section=section)
            return f"{text} (look at {params.format(side=side, section=section)})"
    if state.endswith(".pressure"):   # a volume of a circuit: what flows in never flows out
        return (f"the flows into '{state[:-len('.pressure')]}' do not balance, its pressure "
                f"rises or falls for ever (look at what feeds and what drains it: a pump "
                f"needs a way out, e.g. a relief valve)")
    return f"state '{state}' does not settle"
