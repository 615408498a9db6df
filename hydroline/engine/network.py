"""Wire components by named signals and assemble one explicit ODE ``dx/dt = f(t, x, p)``.

States are named ``<component>.<state>`` (e.g. ``supply.section2.mode3.flow``); signals keep
their network names (e.g. ``supply_port_pressure``). Runtime parameters (``<component>.<name>``)
can change between runs without recompiling. CasADi is imported by :class:`CompiledModel`
only: a model loaded from the cache runs without it.
"""
from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass

import numpy as np

from .component import Component
from .fingerprint import definition_fingerprint

__all__ = ["Network", "NetworkError", "CompiledModel", "UnusedSignalWarning", "connection_table"]


class NetworkError(ValueError):
    """A network that cannot be assembled: the message names components and signals.

    Parameters
    ----------
    *args : str
        The message: one line naming the components and signals.
    **kwargs : dict
        None taken (as ``ValueError``).
    """


class UnusedSignalWarning(UserWarning):
    """A flow that no component reads: the fluid leaves the circuit there (a wiring mistake,
    unless it flows into a prescribed-pressure boundary, which absorbs it).

    Parameters
    ----------
    *args : str
        The message: the lost flows.
    **kwargs : dict
        None taken (as ``UserWarning``).
    """


def connection_table(components) -> list[dict]:
    """One row per signal: who outputs it and who reads it.

    Parameters
    ----------
    components : list[Component]
        The components (commands of an experiment included or not)

    Returns
    -------
    list of dict
        keys ``signal``; ``producer`` ("component.port", None when no component
        outputs it); ``consumers`` (list of "component.port"); ``quantity``; ``unit``
    """
    by_signal = {}
    for c in components:
        for port, spec in c.outputs.items():
            row = by_signal.setdefault(c.signal(port), {"producer": None, "consumers": [],
                                                        "quantity": spec.quantity, "unit": spec.unit})
            row["producer"] = f"{c.name}.{port}"
    for c in components:
        for port, spec in c.inputs.items():
            row = by_signal.setdefault(c.signal(port), {"producer": None, "consumers": [],
                                                        "quantity": spec.quantity, "unit": spec.unit})
            row["consumers"].append(f"{c.name}.{port}")
    return [{"signal": sig, **row} for sig, row in by_signal.items()]


class Network:
    """A set of components connected by signal names.

    Parameters
    ----------
    components : list[Component]
        The components; names must be unique
    warn_lost_flows : bool
        Warn (:class:`UnusedSignalWarning`) of flows no component
        reads (:meth:`lost_flows`); False for a network cut open on
        purpose (e.g. the line-free part of a linearisation)
    """

    def __init__(self, components: list[Component], warn_lost_flows: bool = True):
        self.components = list(components)
        self._check()
        self._order = self._evaluation_order()
        self.state_names, self.state_scales, self._state_slices = [], [], {}
        for c in self.components:
            start = len(self.state_names)
            for s in c.states:
                self.state_names.append(f"{c.name}.{s.name}")
                self.state_scales.append(s.scale)
            self._state_slices[c.name] = slice(start, len(self.state_names))
        self.state_scales = np.array(self.state_scales, dtype=float)
        self.state_atol_ceilings = self._atol_ceilings()
        self.parameter_names, self.parameter_values = [], []
        for c in self.components:
            for k, v in c.runtime_parameters().items():
                self.parameter_names.append(f"{c.name}.{k}")
                self.parameter_values.append(float(v))
        self.parameter_values = np.array(self.parameter_values, dtype=float)
        self._parameter_index = {k: i for i, k in enumerate(self.parameter_names)}
        self.signal_names = [c.signal(o) for c in self._order for o in c.outputs]
        self._compiled = None
        lost = self.lost_flows() if warn_lost_flows else []
        if lost:
            warnings.warn("flow read by no component (the fluid leaves the circuit there; connect "
                          "it to a node or a pressure boundary): " + "; ".join(lost),
                          UnusedSignalWarning, stacklevel=2)

    def _atol_ceilings(self) -> np.ndarray:
        """Each state's ceiling on its absolute tolerance, [SI] (inf: none): its own
        (:attr:`State.atol_ceiling`) and the resolutions the inputs reading it ask for
        (:meth:`Component.input_resolutions`), the smallest."""
        ceilings = np.array([np.inf if s.atol_ceiling is None else float(s.atol_ceiling)
                             for c in self.components for s in c.states], dtype=float)
        for c in self.components:
            for port, resolution in c.input_resolutions().items():
                src, sport = self.producer[c.signal(port)]
                state = src.output_states().get(sport)
                if state is not None:
                    names = [s.name for s in src.states]
                    i = self._state_slices[src.name].start + names.index(state)
                    ceilings[i] = min(ceilings[i], float(resolution))
        return ceilings

    # ---- checks ----------------------------------------------------------------------
    def _check(self):
        names = [c.name for c in self.components]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise NetworkError(f"duplicate component name(s): {', '.join(sorted(dup))}")
        self.producer = {}
        for c in self.components:
            for port in c.connections:
                if port not in c.inputs and port not in c.outputs:
                    raise NetworkError(f"component '{c.name}' has no port '{port}' "
                                       f"(ports: {', '.join(list(c.inputs) + list(c.outputs))})")
            for port, spec in c.outputs.items():
                sig = c.signal(port)
                if sig in self.producer:
                    other, oport = self.producer[sig]
                    raise NetworkError(
                        f"signal '{sig}' has two outputs: '{other.name}.{oport}' and '{c.name}.{port}'")
                self.producer[sig] = (c, port)
        for c in self.components:
            for port, spec in c.inputs.items():
                sig = c.signal(port)
                if sig not in self.producer:
                    raise NetworkError(f"input '{c.name}.{port}' ({spec.quantity}) is unconnected: "
                                       f"no component outputs signal '{sig}'")
                src, sport = self.producer[sig]
                sspec = src.outputs[sport]
                if sspec.quantity != spec.quantity:
                    raise NetworkError(
                        f"causality mismatch on signal '{sig}': '{src.name}.{sport}' outputs a "
                        f"{sspec.quantity} [{sspec.unit}] but '{c.name}.{port}' expects a "
                        f"{spec.quantity} [{spec.unit}] (a port that takes a {spec.quantity} must "
                        f"face one that gives it)")

    def _evaluation_order(self):
        deps = {}
        for c in self.components:
            if c.feedthrough:
                deps[c.name] = {self.producer[c.signal(p)][0].name for p in c.inputs}
                if c.name in deps[c.name]:     # its outputs would need themselves
                    port = next(p for p in c.inputs if self.producer[c.signal(p)][0] is c)
                    raise NetworkError(
                        f"algebraic loop through one component: '{c.name}.{port}' reads "
                        f"'{c.signal(port)}', which its own port '{c.name}."
                        f"{self.producer[c.signal(port)][1]}' outputs (a self-loop)")
            else:
                deps[c.name] = set()
        by_name = {c.name: c for c in self.components}
        order, done, visiting = [], set(), []

        def visit(n):
            if n in done:
                return
            if n in visiting:
                loop = visiting[visiting.index(n):] + [n]
                raise NetworkError("algebraic loop through feed-through components: "
                                   + " -> ".join(loop) + " (" + "; ".join(
                                       self._reads(by_name[a], b) for a, b in zip(loop, loop[1:]))
                                   + ")")
            visiting.append(n)
            for d in sorted(deps[n]):
                visit(d)
            visiting.pop()
            done.add(n)
            order.append(by_name[n])

        for c in self.components:
            visit(c.name)
        return order

    def _reads(self, c, source: str) -> str:
        """Which ports of component c read a signal that component ``source`` outputs."""
        ports = [f"{c.name}.{p} reads '{c.signal(p)}' from {source}.{self.producer[c.signal(p)][1]}"
                 for p in c.inputs if self.producer[c.signal(p)][0].name == source]
        return ", ".join(ports)

    # ---- connections -------------------------------------------------------------------
    def connection_table(self) -> list[dict]:
        """One row per signal: producer, consumers, quantity, unit (see :func:`connection_table`).

        Returns
        -------
        list of dict
            As :func:`connection_table`.
        """
        return connection_table(self.components)

    def unused_signals(self) -> list[str]:
        """Signals that some component outputs and no component reads (most are observations:
        a port pressure, a chamber pressure; see :meth:`lost_flows` for the ones that matter).

        Returns
        -------
        list of str
            Signal names.
        """
        read = {c.signal(p) for c in self.components for p in c.inputs}
        return [s for s in self.producer if s not in read]

    def lost_flows(self) -> list[str]:
        """Unread flow outputs that do not go into a prescribed-pressure boundary, as
        ``"signal (component.port)"``.

        A component that outputs the flow at one of its ends (port ``<end>flow``) reads the
        pressure there (port ``<end>pressure``); a through-flow (an orifice computing ``flow``)
        reads the pressures of both ends. When every such pressure comes from a boundary (a
        component with no inputs, e.g. a pressure source or the tank) the boundaries absorb
        the flow. Any other unread flow leaves the circuit: mass is not conserved.

        Returns
        -------
        list of str
            ``"signal (component.port)"`` per lost flow.
        """
        out = []
        for sig in self.unused_signals():
            c, port = self.producer[sig]
            if c.outputs[port].quantity != "flow":
                continue
            partner = port[:-len("flow")] + "pressure" if port.endswith("flow") else None
            ends = [partner] if partner in c.inputs else \
                [q for q, spec in c.inputs.items() if spec.quantity == "pressure"]
            if ends and all(not self.producer[c.signal(q)][0].inputs for q in ends):
                continue   # every end it flows to is a prescribed-pressure boundary
            out.append(f"'{sig}' ({c.name}.{port})")
        return out

    # ---- evaluation ------------------------------------------------------------------
    def component(self, name: str) -> Component:
        """The component called ``name`` (KeyError if none).

        Parameters
        ----------
        name : str
            Component name

        Returns
        -------
        Component
            The component.

        Raises
        ------
        KeyError
            No component of that name.
        """
        for c in self.components:
            if c.name == name:
                return c
        raise KeyError(name)

    def state_slice(self, name: str) -> slice:
        """Where a component's states sit in the state vector.

        Parameters
        ----------
        name : str
            Component name

        Returns
        -------
        slice
            Its indices in the state vector.
        """
        return self._state_slices[name]

    def component_values(self, c: Component, x, p) -> tuple[dict, dict]:
        """A component's states and runtime parameters, keyed by their local names.

        Parameters
        ----------
        c : Component
            One of the network's components
        x : sequence
            All states, [SI] (numbers or symbols)
        p : sequence
            All runtime parameters, [SI]

        Returns
        -------
        (dict, dict)
            states name -> value, parameters name -> value [SI]
        """
        sl = self._state_slices[c.name]
        xs = {s.name: x[sl.start + i] for i, s in enumerate(c.states)}
        ps = {k: p[self._parameter_index[f"{c.name}.{k}"]] for k in c.runtime_parameters()}
        return xs, ps

    def evaluate(self, t, x, p=None, equations=None, given=None):
        """Derivatives and all signals at (t, x), with numbers or CasADi symbols.

        Parameters
        ----------
        t : float
            Time, [s]
        x : sequence
            States, [SI] (numbers or symbols)
        p : sequence
            Runtime parameters, [SI]; the network's values when None
        equations : dict
            Component name -> the object whose equations stand for it (a copy
            holding symbols for its numbers, :meth:`Component.with_numbers`);
            None: the components' own
        given : dict
            Signal name -> value [SI] that the components reading that signal
            take instead of its producer's output (the network cut open at
            those connections, e.g. to differentiate each component apart from
            its neighbours); the producer's own output is still returned in
            ``signals``. A key ``(component name, internal signal name)`` cuts a
            component open at one of its
            :attr:`~hydroline.engine.component.Component.internal_signals`: it
            reads the value given, and its own value is returned in ``signals``
            under that key. None: no connection cut

        Returns
        -------
        dx : list
            Derivatives in state order, [SI/s] (numbers or symbols)
        signals : dict
            Signal name -> value, [SI]
        """
        p = self.parameter_values if p is None else p
        equations = equations or {}
        given = given or {}
        signals = {}
        split = {}

        internal = {}       # component -> its internal signals as it reads them

        def read(c, ports=True):
            u = {port: given[c.signal(port)] if c.signal(port) in given
                 else signals[c.signal(port)] for port in c.inputs} if ports else {}
            u.update(internal.get(c.name, {}))
            return u

        for c in self._order:
            xs, ps = self.component_values(c, x, p)
            split[c.name] = (xs, ps)
            eq = equations.get(c.name, c)
            if c.internal_signals:       # once per evaluation; given: the component cut open
                values = eq.internal_values(t, xs, ps)
                internal[c.name] = {name: given.get((c.name, name), values[name])
                                    for name in c.internal_signals}
                signals.update({(c.name, name): values[name] for name in c.internal_signals
                                if (c.name, name) in given})
            y = eq.outputs_of(t, xs, read(c, c.feedthrough), ps)
            for port in c.outputs:
                signals[c.signal(port)] = y[port]
        dx = [None] * len(self.state_names)
        for c in self.components:
            xs, ps = split[c.name]
            u = read(c)
            d = equations.get(c.name, c).derivatives(t, xs, u, ps)
            sl = self._state_slices[c.name]
            for i, s in enumerate(c.states):
                if s.name not in d:
                    raise NetworkError(f"component '{c.name}' gives no derivative for state '{s.name}'")
                dx[sl.start + i] = d[s.name]
        return dx, signals

    def rhs(self, t, x, p=None):
        """Reference (NumPy, per-component Python) right-hand side, [state units/s].

        Parameters
        ----------
        t : float
            Time, [s]
        x : ndarray
            States, [SI]
        p : ndarray
            Runtime parameters, [SI]; the network's values when None

        Returns
        -------
        ndarray
            dx/dt, [SI/s].
        """
        dx, _ = self.evaluate(t, np.asarray(x, dtype=float), p)
        return np.array([float(v) for v in dx])

    def signals_at(self, t, x, p=None) -> dict:
        """All signals at one (t, x), name -> value [SI].

        Parameters
        ----------
        t : float
            Time, [s]
        x : ndarray
            States, [SI]
        p : ndarray
            Runtime parameters, [SI]; the network's values when None

        Returns
        -------
        dict
            Signal name -> value, [SI].
        """
        _, sig = self.evaluate(t, np.asarray(x, dtype=float), p)
        return {k: float(v) for k, v in sig.items()}

    def compiled_numbers(self) -> tuple:
        """The components' numbers that the compiled model takes at run time
        (:meth:`Component.compiled_numbers`), in component order, a tuple's items one by one.

        Returns
        -------
        (list, ndarray)
            names ``<component>.<attribute>`` (``...[k]`` for a tuple's item) and
            values, [SI]
        """
        names, values = [], []
        for c in self.components:
            for k, v in c.compiled_numbers().items():
                if isinstance(v, (tuple, list)):
                    names += [f"{c.name}.{k}[{i}]" for i in range(len(v))]
                    values += [float(a) for a in v]
                else:
                    names.append(f"{c.name}.{k}")
                    values.append(float(v))
        return names, np.array(values, dtype=float)

    def compile(self):
        """The assembled model as CasADi functions (built once per network).

        Returns
        -------
        CompiledModel
            The CasADi functions of the right-hand side, its Jacobian and the signals.
        """
        if self._compiled is None:
            self._compiled = CompiledModel(self)
        return self._compiled

    @property
    def has_graph(self) -> bool:
        """True once :meth:`compile` has built the CasADi graph (of the components as they
        were then)."""
        return self._compiled is not None

    def definition_fingerprint(self, structure: bool = False) -> str | None:
        """SHA-256 (hex) of everything :meth:`compile`'s graph is a function of, without
        building it: the components (classes, attributes, wiring, order), the state scales
        and names, and the source of the code involved; None where a part cannot be
        described by value (:func:`hydroline.engine.fingerprint.definition_fingerprint`).
        Equal fingerprints mean equal graphs: a compiled model recorded under one can be
        loaded for the other.

        Parameters
        ----------
        structure : bool
            Leave out the numbers the compiled model takes at run time (the
            components' own numbers, the state scales): networks that differ
            only in them share this fingerprint

        Returns
        -------
        str or None
            Hex digest, or None.
        """
        return definition_fingerprint(self, structure)

    def guess(self) -> np.ndarray:
        """Initial guess of all states from the components, [SI].

        Returns
        -------
        ndarray
            States, [SI].
        """
        x = np.zeros(len(self.state_names))
        for c in self.components:
            g = c.initial_guess()
            sl = self._state_slices[c.name]
            for i, s in enumerate(c.states):
                x[sl.start + i] = g.get(s.name, 0.0)
        return x

    def breakpoints(self, t_end: float) -> list[float]:
        """Times in (0, t_end) where some component's input jumps, sorted, [s].

        Parameters
        ----------
        t_end : float
            End of the run, [s]

        Returns
        -------
        list of float
            The times, [s].
        """
        pts = set()
        for c in self.components:
            pts.update(b for b in c.breakpoints(t_end) if 0 < b < t_end)
        return sorted(pts)


@dataclass
class CompiledModel:
    """One CasADi graph of the whole network: f(t, x, p), its Jacobian, all signals.

    Parameters
    ----------
    network : Network
        The assembled network (states, parameters and signals in its order)
    """

    network: Network

    def __post_init__(self):
        import casadi as ca

        net = self.network
        n, m = len(net.state_names), len(net.parameter_names)
        t = ca.SX.sym("t")
        x = ca.SX.sym("x", n)
        p = ca.SX.sym("p", m)
        self.t, self.x, self.p = t, x, p
        #: The components' numbers (:meth:`Network.compiled_numbers`) as symbols, and the
        #: graph in them: ``dx_general``, ``y_general`` are functions of (t, x, p, k), the same
        #: for every value of the numbers (None where a component's equations cannot take its
        #: numbers as symbols: a Python branch on one; its numbers are then in the graph)
        self.k = self.dx_general = self.y_general = None
        #: Component name -> the copy of it whose numbers are the symbols k
        #: (:meth:`Component.with_numbers`), for other graphs in them (the bordered
        #: Jacobian's, :mod:`hydroline.compiled.codegen`); None with ``k``
        self.number_equations = None
        _, self.numbers = net.compiled_numbers()
        general = self._general_graph(ca)
        if general is not None:
            self.k, self.dx_general, self.y_general, self.number_equations = general
            self.dx, self.y = ca.substitute([self.dx_general, self.y_general], [self.k],
                                            [ca.DM(self.numbers)])
        else:
            self.dx, self.y = self._graph(ca, net.evaluate(t, self._xs(), self._ps()))
        self.f = ca.Function("f", [t, x, p], [self.dx], ["t", "x", "p"], ["dx"])
        self.signals = ca.Function("signals", [t, x, p], [self.y], ["t", "x", "p"], ["y"])

    def _xs(self):
        return [self.x[i] for i in range(self.x.numel())]

    def _ps(self):
        return [self.p[i] for i in range(self.p.numel())]

    def _graph(self, ca, evaluated):
        """(dx, y) as column expressions from :meth:`Network.evaluate`'s lists."""
        dx, sig = evaluated
        return (ca.vertcat(*[ca.SX(v) if not isinstance(v, ca.SX) else v for v in dx]),
                ca.vertcat(*[ca.SX(sig[k]) if not isinstance(sig[k], ca.SX) else sig[k]
                             for k in self.network.signal_names]))

    def _general_graph(self, ca):
        """(k, dx, y, equations): the graph with every component's numbers as the symbols k
        (and the component copies holding them, :attr:`number_equations`), checked
        against the components' own Python equations at their initial guess; None where a
        component's equations do not take its numbers as symbols (a Python ``if`` on one
        raises, a NumPy function warns) or give other values (e.g. ``float()`` of one)."""
        net = self.network
        k = ca.SX.sym("k", len(self.numbers))
        views, pos = {}, 0
        for c in net.components:
            symbols = {}
            for name, v in c.compiled_numbers().items():
                if isinstance(v, (tuple, list)):
                    symbols[name] = type(v)(k[pos + i] for i in range(len(v)))
                    pos += len(v)
                else:
                    symbols[name] = k[pos]
                    pos += 1
            if symbols:
                views[c.name] = c.with_numbers(symbols)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")   # (a NumPy function on a symbol: legacy)
                dx, y = self._graph(ca, net.evaluate(self.t, self._xs(), self._ps(), views))
            x0 = net.guess()
            dx_ref, sig_ref = net.evaluate(0.0, x0, net.parameter_values)
            ref = np.array([float(v) for v in dx_ref]
                           + [float(sig_ref[s]) for s in net.signal_names])
        except Exception:   # noqa: BLE001  (any failure: the numbers stay in the graph)
            return None
        got = np.asarray(ca.Function("general", [self.t, self.x, self.p, k], [ca.vertcat(dx, y)])(
            0.0, x0, net.parameter_values, self.numbers), dtype=float).ravel()
        scale = np.maximum(np.abs(ref), np.abs(got))
        if got.shape != ref.shape or not np.all(
                (np.abs(got - ref) <= 1e-9 * scale + 1e-300) | (np.isnan(got) & np.isnan(ref))):
            return None
        return k, dx, y, views

    @functools.cached_property
    def jac(self):
        """d(dx/dt)/dx as a CasADi function, made on first use (the compiled core writes its
        own sparse Jacobian; building this one costs ~10 ms per network)."""
        import casadi as ca

        return ca.Function("jacobian_f", [self.t, self.x, self.p], [ca.jacobian(self.dx, self.x)],
                           ["t", "x", "p"], ["J"])

    def rhs(self, t, x, p):
        """dx/dt from the CasADi graph, [state units/s].

        Parameters
        ----------
        t : float
            Time, [s]
        x : ndarray
            States, [SI]
        p : ndarray
            Runtime parameters, [SI]

        Returns
        -------
        ndarray
            dx/dt, [SI/s].
        """
        return np.asarray(self.f(t, x, p)).ravel()

    def jacobian(self, t, x, p):
        """d(dx/dt)/dx, dense, [1/s in state units].

        Parameters
        ----------
        t : float
            Time, [s]
        x : ndarray
            States, [SI]
        p : ndarray
            Runtime parameters, [SI]

        Returns
        -------
        ndarray
            d(dx/dt)/dx, n x n, [1/s in state units].
        """
        import casadi as ca

        return np.asarray(ca.densify(self.jac(t, x, p)))
