"""The component interface: ports (signals with causality), states and equations.

A component declares

* ``inputs`` / ``outputs``: local port names -> :class:`Port` (quantity and unit);
* ``states``: :class:`State` entries (local name, unit, typical magnitude);
* ``outputs_of(t, x, u, p)``: the outputs from states x, inputs u and runtime parameters p
  (dicts keyed by local names);
* ``derivatives(t, x, u, p)``: the time derivatives of the states.

Both receive numbers (reference path) or CasADi symbols (compiled path) and must only use
:mod:`hydroline.engine.ops` and arithmetic. A component whose outputs do not depend on its
inputs sets ``feedthrough = False``; the network uses it to order the evaluation and to find
algebraic loops.

Optional parts of the contract: ``runtime_parameters()`` (values that may change between runs
without recompiling), ``initial_guess()`` and ``settle()`` (the steady-state solve),
``breakpoints()`` (times where an input jumps), ``internal_signals`` with
``internal_values()`` (values of its own states it reads back through one number, which the
compiled core's bordered Jacobian cuts open as a connection), and for a *sampled* component
(a digital controller) ``sample_time`` [s] with ``sample(x, u)``: at every multiple of the
sample time the integrator stops, calls ``sample`` with the states and inputs there, and holds
the runtime parameters it returns until the next instant (zero-order hold).
"""
from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

__all__ = ["Port", "State", "Component", "QUANTITY_UNITS", "Parameter", "parameter", "range_text",
           "HydraulicEnd", "is_number", "NUMBER_MARK"]

#: Physical quantity kinds of signals and their SI units.
QUANTITY_UNITS = {
    "pressure": "Pa",
    "flow": "m^3/s",
    "current": "A",
    "position": "m",
    "velocity": "m/s",
    "force": "N",
    "volume": "m^3",
    "dimensionless": "-",
}


@dataclass(frozen=True)
class Port:
    """One input or output signal of a component.

    Parameters
    ----------
    quantity : str
        Kind of signal (a key of QUANTITY_UNITS); connecting ports of
        different kinds is a causality/quantity mismatch
    description : str
        What the signal is, with its sign convention
    """

    quantity: str
    description: str = ""

    @property
    def unit(self) -> str:
        """The signal's SI unit (from :data:`QUANTITY_UNITS`)."""
        return QUANTITY_UNITS[self.quantity]


@dataclass(frozen=True)
class State:
    """One state of a component: local name, SI unit, typical magnitude (for tolerances).

    Parameters
    ----------
    name : str
        Local name, e.g. ``"gas_volume"`` (the network prefixes the component)
    unit : str
        Its SI unit, e.g. ``"m^3"``
    scale : float
        Typical magnitude (absolute tolerance and steady-state scaling), [unit]
    description : str
        What it is
    atol_ceiling : float
        The loosest absolute tolerance the integrator may take on it, [unit]
        (None: none): the resolution its dynamics needs, e.g. a fraction of a
        regularisation velocity; looser tolerances (``after_stop_rtol``) leave
        it there. A component may set it on another's state through an input
        (:meth:`Component.input_resolutions`)
    """

    name: str
    unit: str
    scale: float = 1.0
    description: str = ""
    atol_ceiling: float | None = None


@dataclass(frozen=True)
class HydraulicEnd:
    """One place where a component meets the oil: the pressure there and the flows crossing it.

    The circuit's wiring checks (:mod:`hydroline.circuit.wiring`) derive its nodes and sides
    from these declarations (:meth:`Component.hydraulic_ends`).

    Parameters
    ----------
    pressure : str
        Port of the pressure at that place; None for a flow junction (a node
        whose pressure another component gives)
    flows : tuple
        Ports of the flows crossing it; a flow port listed at two ends of one
        component passes through it from one to the other (a resistance, a pump)
    compliant : bool
        True where the component holds oil: its pressure follows from a volume
        of oil (a hose end, a chamber, an accumulator, a lumped volume)
    """

    pressure: str | None
    flows: tuple = ()
    compliant: bool = False


@dataclass(frozen=True)
class Parameter:
    """One parameter of a component, declared once: unit, bounds, description, default.

    Rig schemas, validation messages, circuit files and the docs all read these declarations
    (:meth:`Component.parameters`).

    Parameters
    ----------
    unit : str
        SI unit ("-" dimensionless, "str" text, "list:<unit>" a list of
        quantities, e.g. "list:m")
    description : str
        What it is, with its symbol and equation (M#) where it has one
    minimum : float
        Lower bound, [unit]; None for none
    maximum : float
        Upper bound, [unit]; None for none
    exclusive_minimum : bool
        True: the value must be above ``minimum`` (> rather than >=)
    optional : bool
        True: None is allowed (the parameter is then not used)
    choices : tuple
        Allowed texts of a "str" parameter (empty: any text)
    default : object
        Default value [unit] (filled in from the component's field)
    plausible : tuple
        (low, high), [unit]: where a real rig's value lies (either None:
        open on that side). Wider than typical: it catches slips of unit or
        exponent (an area of 1e-30 m^2), not unusual designs. A value
        outside is refused unless the rig names the parameter in
        ``[rig] allow_implausible``; ``minimum``/``maximum`` are physical
        and cannot be overridden. None: no plausible range.
    """

    unit: str
    description: str = ""
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False
    optional: bool = False
    choices: tuple = ()
    default: object = None
    plausible: tuple | None = None

    def rule(self) -> str:
        """The bound as text, e.g. "> 0" or "within [1, 1.66667]".

        Returns
        -------
        str
            The bound, e.g. ``"> 0"``, ``"one of 'a', 'b'"`` or ``"finite"``.
        """
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.minimum is not None and self.maximum is not None:
            return f"within {'(' if self.exclusive_minimum else '['}{self.minimum:g}, {self.maximum:g}]"
        if self.minimum is not None:
            return f"{'>' if self.exclusive_minimum else '>='} {self.minimum:g}"
        if self.maximum is not None:
            return f"<= {self.maximum:g}"
        return "finite"

    def violation(self, value) -> str | None:
        """None when ``value`` meets the declaration, else the rule it breaks.

        Parameters
        ----------
        value : object
            The value, [unit] (a list for "list:" units, text for "str")

        Returns
        -------
        str or None
        """
        if value is None:
            return None if self.optional else "given"
        if self.unit == "str":
            return None if not self.choices or value in self.choices else self.rule()
        values = value if self.unit.startswith("list:") else [value]
        for v in values:
            try:
                v = float(v)
            except (TypeError, ValueError):
                return "a number"
            if math.isnan(v):
                return self.rule()
            if self.minimum is not None and (v < self.minimum or (self.exclusive_minimum and v == self.minimum)):
                return self.rule()
            if self.maximum is not None and v > self.maximum:
                return self.rule()
            if (self.minimum is None or self.maximum is None) and math.isinf(v):
                return self.rule() if self.rule() != "finite" else "finite"
        return None

    def implausible(self, value) -> str | None:
        """None when ``value`` (a number or a list for "list:" units) lies in the plausible
        range, else the range as text ("within 1e-06 ... 1").

        Parameters
        ----------
        value : object
            The value, [unit]

        Returns
        -------
        str or None
            The plausible range as text, or None when the value is plausible.
        """
        if self.plausible is None or value is None or self.unit == "str":
            return None
        low, high = self.plausible
        for v in (value if isinstance(value, (list, tuple)) else [value]):
            if (low is not None and v < low) or (high is not None and v > high):
                return range_text(low, high)
        return None

    @property
    def unit_text(self) -> str:
        """The unit as shown in messages: "" for dimensionless and text."""
        return {"-": "", "str": ""}.get(self.unit, self.unit.replace("list:", ""))


def is_number(value) -> bool:
    """True for a plain real number that the compiled model takes at run time (a Python or
    NumPy float, or a tuple or list of them), False for anything else (an int or a bool is a
    count or a switch: structure; text, None, arrays, objects).

    Parameters
    ----------
    value : object
        An attribute's value

    Returns
    -------
    bool
        True for a run-time number.
    """
    if type(value) is float or isinstance(value, np.floating):
        return True
    if type(value) in (tuple, list) and value:
        return all(type(v) is float or isinstance(v, np.floating) for v in value)
    return False


class _NumberMark:
    """What stands for a number in a description of a structure (no value compares equal)."""

    __slots__ = ()

    def __repr__(self):
        return "<number>"


#: What stands for a component's number in a description of its structure (a number's value
#: is not structure: :meth:`Component.structure_attributes`).
NUMBER_MARK = _NumberMark()


def range_text(low, high) -> str:
    """A plausible range as the messages say it: "within 1e-06 ... 1", "at least 1",
    "at most 5".

    Parameters
    ----------
    low : float
        Lower end, [unit]; None: open
    high : float
        Upper end, [unit]; None: open

    Returns
    -------
    str
        The range as text.
    """
    if low is None:
        return f"at most {high:g}"
    if high is None:
        return f"at least {low:g}"
    return f"within {low:g} ... {high:g}"


def parameter(default, unit: str, description: str = "", *, minimum=None, maximum=None,
              positive: bool = False, optional: bool = False, choices: tuple = (),
              plausible: tuple | None = None):
    """A dataclass field declaring a component parameter (see :class:`Parameter`).

    Parameters
    ----------
    default : object
        Default value, [unit]
    unit : str
        SI unit ("-", "str", "list:<unit>")
    description : str
        What it is
    minimum : float
        Lower bound (inclusive unless ``positive``), [unit]
    maximum : float
        Upper bound (inclusive), [unit]
    positive : bool
        Shorthand for "> 0" (``minimum`` 0, exclusive)
    optional : bool
        None allowed
    choices : tuple
        Allowed texts of a "str" parameter
    plausible : tuple
        (low, high) where a real rig's value lies, [unit] (see
        :class:`Parameter`); None: none

    Returns
    -------
    dataclasses.Field
    """
    if positive:
        minimum = 0.0 if minimum is None else minimum
    decl = Parameter(unit, description, minimum, maximum, bool(positive), optional, tuple(choices),
                     plausible=None if plausible is None else tuple(plausible))
    return field(default=default, metadata={"parameter": decl})


@dataclass
class Component:
    """Base class. Subclasses set ``inputs``, ``outputs``, ``states`` and the equations.

    Parameters
    ----------
    name : str
        Unique name in the network (dots allowed: ``supply.section2``)
    connections : dict
        Local port name -> network signal name. Unlisted ports connect to
        a signal of the same name prefixed by nothing (the port name itself)
    """

    name: str
    connections: dict = field(default_factory=dict)

    inputs = {}
    outputs = {}
    feedthrough = True
    #: True where oil passes between the component's ends without a metering edge, a piston or
    #: a pump between them (a hose, a resistance, a node): its ends lie on one side of the
    #: circuit (see :meth:`hydraulic_ends`)
    conducts = False
    #: Pairs (high, low) of ends the circuit must hold apart, ``high`` reaching a higher
    #: prescribed pressure than ``low`` (a servovalve's P above its T)
    pressure_order = ()
    #: Ends where the component delivers oil under pressure into the circuit (a pump's outlet)
    source_ends = ()
    #: Zero-order-hold period of a sampled component, [s]; None for a continuous one
    sample_time = None
    #: What the component takes from the rig around it besides its parameters, by name
    #: (``hydroline.circuit.types.CONTEXT``: "fluid", "modes_per_section", "line_method",
    #: "folder"): the circuit builder passes each as the keyword argument of that name (a
    #: component that needs the oil declares ``context = ("fluid",)`` and a ``fluid`` field)
    context = ()
    #: Values the component adds to another component's parameter before either is made:
    #: ``(own parameter, own input port, the other's parameter)``, the other being the one
    #: that outputs the signal of that port (a load's mass rides on the actuator whose
    #: position it reads)
    adds_to = ()
    #: Names of values the component computes from its own states and parameters
    #: (:meth:`internal_values`) and reads back in its outputs and derivatives through that one
    #: number (a hose end's cavity-free pressure, M45). The compiled core's bordered Jacobian
    #: cuts the component open there as at a connection (:mod:`hydroline.compiled.codegen`): a
    #: value that moves every state stays one row and one column instead of a dense block.
    #: ``outputs_of`` and ``derivatives`` find such a value in ``u`` under its name where the
    #: network is cut open there (:meth:`~hydroline.engine.Network.evaluate` with ``given``)
    #: and compute it themselves otherwise
    internal_signals = ()

    # ---- parameters ----------------------------------------------------------------------
    @classmethod
    def parameters(cls) -> dict:
        """The declared parameters of this component type, name -> :class:`Parameter`
        (with its default filled in).

        Returns
        -------
        dict
            Parameter name -> :class:`Parameter`.
        """
        known = cls.__dict__.get("_declared_parameters")   # per class (not inherited)
        if known is None:
            known = {}
            for f in dataclasses.fields(cls):
                decl = f.metadata.get("parameter")
                if decl is not None:
                    known[f.name] = dataclasses.replace(decl, default=f.default)
            cls._declared_parameters = known
        return dict(known)

    def check_parameters(self):
        """Raise ValueError ``"<name>: <parameter> must be <rule> [unit], got <value>"`` for
        the first declared parameter outside its bounds."""
        for key, decl in self.parameters().items():
            value = getattr(self, key)
            rule = decl.violation(value)
            if rule is not None:
                unit = f" [{decl.unit_text}]" if decl.unit_text else ""
                raise ValueError(f"{self.name}: {key} must be {rule}{unit}, got {value!r}")

    # ---- numbers of the compiled model ---------------------------------------------------
    def compiled_numbers(self) -> dict:
        """The component's own numbers, which the compiled model takes at run time instead of
        folding them into its code: every attribute holding a real number or a tuple of them
        (:func:`is_number`: areas, masses, lengths, gains, laps; not counts, switches, text
        or nested objects), name -> value [SI]. A rig that differs only in these numbers
        runs on the same compiled library.

        Returns
        -------
        dict
            attribute name -> float or tuple of floats, [SI]
        """
        return {k: v for k, v in vars(self).items() if k != "name" and is_number(v)}

    def with_numbers(self, numbers: dict):
        """A copy of the component whose attributes ``numbers`` hold other values (the
        compiled model's symbols for them), for writing its equations once for all values;
        values cached from the old numbers (cached properties) are dropped.

        Parameters
        ----------
        numbers : dict
            attribute name -> value (a symbol, or a tuple of symbols); a name
            ``"<attribute>.<field>"`` stands for a field of an object the component holds
            (the oil's cavity pressure, ``"fluid.cavity_pressure"``): the copy holds a copy
            of that object with the field replaced

        Returns
        -------
        Component
            The copy (the component itself is not changed)
        """
        view = copy.copy(self)
        for c in type(self).__mro__:
            for name, attr in vars(c).items():
                if isinstance(attr, cached_property):
                    view.__dict__.pop(name, None)
        held = {}
        for name, value in numbers.items():
            owner, dot, item = name.partition(".")
            if not dot:
                view.__dict__[name] = value
                continue
            if owner not in held:
                held[owner] = view.__dict__[owner] = copy.copy(getattr(self, owner))
            object.__setattr__(held[owner], item, value)    # (frozen dataclasses too)
        return view

    def structure_attributes(self, attributes: dict) -> dict:
        """What describes the component's structure, from its attributes: the numbers
        (:meth:`compiled_numbers`) stand as :data:`NUMBER_MARK` (their count for a tuple).
        A component that holds more numbers the compiled model takes at run time (a hose's
        line matrices) replaces those too.

        Parameters
        ----------
        attributes : dict
            The component's attributes, name -> value

        Returns
        -------
        dict
            name -> value or mark
        """
        return {k: ((NUMBER_MARK if not isinstance(v, (tuple, list)) else (NUMBER_MARK, len(v)))
                    if k != "name" and is_number(v) else v) for k, v in attributes.items()}

    # ---- to be provided by subclasses --------------------------------------------------
    @property
    def states(self) -> list[State]:
        """The component's states, :class:`State` entries (none by default)."""
        return []

    def input_resolutions(self) -> dict:
        """The resolution each input needs, input port -> the loosest absolute tolerance
        [SI unit of the port] on the state that input reads (none by default).

        The network takes it as that state's :attr:`State.atol_ceiling` where the input is
        wired to an output that passes a state through (:meth:`output_states`).

        Returns
        -------
        dict
            Input port -> tolerance ceiling, [SI unit of the port].
        """
        return {}

    def output_states(self) -> dict:
        """The outputs that are one of the component's states unchanged, output port ->
        local state name (none by default).

        Returns
        -------
        dict
            Output port -> state name.
        """
        return {}

    def outputs_of(self, t, x, u, p):
        """The outputs, local port name -> value [SI unit of the port].

        Parameters
        ----------
        t : float
            Time, [s]
        x : dict
            States, local name -> value [SI]
        u : dict
            Inputs, local port name -> value [SI] (empty when not ``feedthrough``)
        p : dict
            Runtime parameters, name -> value [SI]
        """
        raise NotImplementedError

    def derivatives(self, t, x, u, p):
        """The time derivatives of the states, local name -> value [SI unit/s].

        Parameters
        ----------
        t : float
            Time, [s]
        x : dict
            States, local name -> value [SI]
        u : dict
            Inputs, local port name -> value [SI]
        p : dict
            Runtime parameters, name -> value [SI]

        Returns
        -------
        dict
            State local name -> time derivative, [SI unit/s].
        """
        return {}

    # ---- optional hooks ------------------------------------------------------------------
    def internal_values(self, t, x, p) -> dict:
        """The values of :attr:`internal_signals` at (t, x), name -> value [SI].

        Parameters
        ----------
        t : float
            Time, [s]
        x : dict
            States, local name -> value [SI]
        p : dict
            Runtime parameters, name -> value [SI]

        Returns
        -------
        dict
            Internal signal name -> value [SI]; empty without internal signals.
        """
        return {}

    def runtime_parameters(self) -> dict:
        """Parameters that may change without rebuilding the compiled model, name -> value.

        Returns
        -------
        dict
            Parameter name -> value, [SI].
        """
        return {}

    def initial_guess(self) -> dict:
        """Guess of every state for the steady-state solver, local name -> value [SI].

        Returns
        -------
        dict
            State local name -> guess, [SI].
        """
        return {s.name: 0.0 for s in self.states}

    def settle(self, x: dict, u: dict, p: dict):
        """Called with the solved steady state; may return ``(new_x, new_p)`` dicts to adopt
        (e.g. an accumulator takes its pre-charge reference from the steady pressure).

        Parameters
        ----------
        x : dict
            States at the steady state, local name -> value [SI]
        u : dict
            Inputs there, local port name -> value [SI]
        p : dict
            Runtime parameters, name -> value [SI]
        """
        return None

    def sample(self, x: dict, u: dict) -> dict:
        """At a sampling instant (components with a ``sample_time``): the runtime parameters
        to hold until the next one, name -> value [SI] (numbers, not symbols).

        Parameters
        ----------
        x : dict
            States at the instant, local name -> value [SI]
        u : dict
            Inputs there, local port name -> value [SI]

        Returns
        -------
        dict
            Runtime parameter name -> value to hold, [SI].
        """
        return {}

    def breakpoints(self, t_end: float) -> list[float]:
        """Times in (0, t_end) where the component's inputs to the ODE jump, [s].

        Parameters
        ----------
        t_end : float
            End of the run, [s]

        Returns
        -------
        list of float
            The times, [s].
        """
        return []

    def hydraulic_ends(self) -> dict:
        """Where the component meets the oil, end name -> :class:`HydraulicEnd`; empty for a
        component of signals only (a command, a controller, friction).

        Returns
        -------
        dict
            End name -> :class:`HydraulicEnd`.
        """
        return {}

    def signal(self, port: str) -> str:
        """Network signal connected to a local port.

        Parameters
        ----------
        port : str
            Local port name

        Returns
        -------
        str
            The network signal's name (the port's own name when not connected elsewhere).
        """
        return self.connections.get(port, port)
