"""Solver backends: one class per way of integrating ``dx/dt = f(t, x, p)`` between two
breakpoints (docs/model.md section 6).

Every backend has the same small interface, which :func:`hydroline.engine.integrate` drives:

* ``start(a, x, b, p)``: begin a segment at time ``a`` [s] from states ``x`` [SI], to end at
  ``b`` [s] (a breakpoint or a sampling instant), with runtime parameters ``p`` [SI];
* ``advance(grid, out=None)``: the states at the output times ``grid`` [s] (increasing,
  within the segment), as ``(X, table)``: ``X`` the states, one row per time; ``table`` the
  signals and states side by side when the backend computes them (else None: the sink
  evaluates the signals from the states). ``out`` is where the rows may be written (the
  run's own table, so that they are not copied there afterwards): the compiled core writes
  its table into it; the other backends ignore it;
* ``stats()``: solver statistics (function and Jacobian evaluations, steps);
* ``signals_at(t, x, p)``: every signal at one (t, x) where the backend computes them
  (the compiled core), else None (they are then evaluated on the CasADi graph);
* ``relax(rtol, atol_scale)``: looser tolerances from the next step on, keeping the run's
  history (the compiled core; the others ignore it: they restart at every call);
* ``chunked``: True when output in chunks costs nothing (the compiled core keeps its history
  across ``advance`` calls); the others restart at every call, so they are given a whole
  segment unless memory must stay bounded.

:class:`CompiledBackend` runs the network compiled to C with its sparse-Jacobian BDF
(:mod:`hydroline.compiled`); :class:`CvodesBackend` runs SUNDIALS CVODES through CasADi with
the exact sparse Jacobian; :class:`ScipyBackend` is the plain reference path (SciPy's BDF on
the per-component Python right-hand side).
"""
from __future__ import annotations

import numpy as np

from .network import Network

__all__ = ["CompiledBackend", "CvodesBackend", "ScipyBackend", "make_backend", "SOLVERS"]

#: Names accepted by ``solver=``; "auto" is the compiled core where a C compiler exists, else
#: "cvodes": its BDF ("compiled"), or its Radau IIA ("radau") at 100x the tolerances where the
#: model's modes hold the BDF's order 3 below 40 us (``NativeSolver.RADAU_BELOW``, method "auto").
SOLVERS = ("auto", "compiled", "cvodes", "scipy", "radau")


class CompiledBackend:
    """The network as C code with a sparse-Jacobian BDF integrator (:mod:`hydroline.compiled`).

    Parameters
    ----------
    network : Network
        The model
    native : object
        Its :class:`hydroline.compiled.NativeModel`
    p : ndarray
        Runtime parameters, [SI]
    rtol : float
        Relative tolerance, [-]
    atol_scale : float
        Absolute tolerance as a fraction of each state's scale, [-]
    method : str
        The C core's integrator: "bdf" (variable-order NDF/BDF), "radau"
        (Radau IIA of order 5) or "auto" (one of them by the model's modes,
        :class:`hydroline.compiled.NativeSolver`)
    """

    chunked = True

    def __init__(self, network: Network, native, p, rtol: float, atol_scale: float,
                 method: str = "bdf"):
        self.n_signals = len(network.signal_names)
        self.solver = native.solver(p, rtol=rtol, atol=atol_scale, method=method)

    @property
    def name(self) -> str:
        """"compiled" (the BDF), or "radau" once the run steps with Radau IIA."""
        return "compiled" if self.solver.chosen_method == "bdf" else self.solver.chosen_method

    def start(self, a: float, x, b: float, p) -> None:
        """Begin a segment.

        Parameters
        ----------
        a : float
            Segment start, [s]
        x : ndarray
            States at ``a``, [SI]
        b : float
            Segment end (a breakpoint or sampling instant), [s]
        p : ndarray
            Runtime parameters over the segment, [SI]
        """
        self.solver.set_parameters(p)   # (a sampled component may have changed one)
        self.solver.start(a, x, b)

    def signals_at(self, t: float, x, p):
        """Every signal at (t, x) from the compiled code (before :meth:`start`: a run's first
        row), in ``network.signal_names`` order, [SI].

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
            Signal values, [SI].
        """
        self.solver.set_parameters(p)
        y = self.solver.signals(t, x)
        self.solver.reset_stats()   # (the evaluations of f made for it are no step's)
        return y

    def advance(self, grid, out=None):
        """States (and, the compiled core computing them, the signals) at the output times.

        Parameters
        ----------
        grid : ndarray
            Output times within the segment, increasing, [s]
        out : ndarray
            Where to write the table (C-contiguous rows of signals then states,
            one per time), or None (a new array), [SI]

        Returns
        -------
        X : ndarray
            States, one row per time, [SI]
        table : ndarray
            Signals and states side by side, [SI] (``out`` where given)
        """
        table = self.solver.advance(grid, table=True, out=out)   # signals and states
        return table[:, self.n_signals:], table

    def stats(self) -> dict:
        """Solver statistics: function and Jacobian evaluations, steps (counts).

        Returns
        -------
        dict
            Counter name -> count.
        """
        return self.solver.stats()

    def relax(self, rtol: float, atol_scale: float) -> bool:
        """Use these tolerances from the next step on (step size, order and history kept).

        Parameters
        ----------
        rtol : float
            Relative tolerance, [-]
        atol_scale : float
            Absolute tolerance as a fraction of each state's scale, [-]

        Returns
        -------
        bool
            True (done)
        """
        self.solver.relax(rtol, atol_scale)   # (Radau IIA: atol capped)
        return True


class CvodesBackend:
    """SUNDIALS CVODES through CasADi, exact sparse Jacobian, on the scaled states z = x/scale
    (one absolute tolerance then fits every state).

    Parameters
    ----------
    network : Network
        The model
    rtol : float
        Relative tolerance, [-]
    atol_scale : float
        Absolute tolerance as a fraction of each state's scale, [-]
    """

    name = "cvodes"
    chunked = False

    def __init__(self, network: Network, rtol: float, atol_scale: float):
        import casadi as ca

        model = network.compile()
        self.scales = network.state_scales
        z = ca.SX.sym("z", model.x.shape[0])
        x = z * ca.DM(self.scales)
        #: ``(t, z, p) -> (v, dz/dt)``: the scaled cut values consistent with the states and
        #: the rates there, where the network is cut open (:data:`CUT_OPEN`); None: the ODE
        #: on CVODES
        self.consistent = None
        cut = _cut_signals(network) if CUT_OPEN else []
        if cut:
            self.dae, self.consistent = _cut_open_dae(network, model, z, x, cut)
        else:
            ode = ca.substitute(model.dx, model.x, x) / ca.DM(self.scales)
            self.dae = {"t": model.t, "x": z, "p": model.p, "ode": ode}
        self.rtol, self.atol_scale = rtol, atol_scale
        self.counts = {"nfevals": 0, "njevals": 0, "nsteps": 0}

    def start(self, a: float, x, b: float, p) -> None:
        """Begin a segment.

        Parameters
        ----------
        a : float
            Segment start, [s]
        x : ndarray
            States at ``a``, [SI]
        b : float
            Segment end (a breakpoint or sampling instant), [s]
        p : ndarray
            Runtime parameters over the segment, [SI]
        """
        self.t, self.x, self.p = a, np.asarray(x, dtype=float), np.asarray(p, dtype=float)

    def advance(self, grid, out=None):
        """States (and, CVODES restarting at the segment's last time) at the output times.

        Parameters
        ----------
        grid : ndarray
            Output times within the segment, increasing, [s]
        out : ndarray
            Ignored (the sink evaluates the signals and copies the rows), [SI]

        Returns
        -------
        X : ndarray
            States, one row per time, [SI]
        table : None
            None (the sink evaluates the signals)
        """
        import casadi as ca

        options = {"reltol": self.rtol, "abstol": self.atol_scale, "max_num_steps": 200000}
        z0 = self.x / self.scales
        if self.consistent is None:
            F = ca.integrator("F", "cvodes", self.dae, self.t, list(grid), options)
            out = F(x0=z0, p=self.p)
        else:      # the cut values and rates consistent with the states: no initial solve
            v0, rates = self.consistent(self.t, z0, self.p)
            options.update(calc_ic=False, init_xdot=rates, suppress_algebraic=True)
            F = ca.integrator("F", "idas", self.dae, self.t, list(grid), options)
            out = F(x0=z0, z0=v0, p=self.p)
        X = np.asarray(out["xf"]).T * self.scales
        st = F.stats()
        self.counts["nfevals"] += int(st.get("nfevals", 0))
        self.counts["njevals"] += int(st.get("njevals", 0) or st.get("nlinsetups", 0))
        self.counts["nsteps"] += int(st.get("nsteps", 0))
        return self._accept(grid, X), None

    def signals_at(self, t: float, x, p):
        """None: this backend leaves the signals to the CasADi graph (or the components).

        Parameters
        ----------
        t : float
            Time, [s]
        x : ndarray
            States, [SI]
        p : ndarray
            Runtime parameters, [SI]
        """
        return None

    def relax(self, rtol: float, atol_scale: float) -> bool:
        """Not done on this backend (its tolerances stay): it restarts at every call.

        Parameters
        ----------
        rtol : float
            Relative tolerance, [-]
        atol_scale : float
            Absolute tolerance as a fraction of each state's scale, [-]

        Returns
        -------
        bool
            False (not done)
        """
        return False

    def _accept(self, grid, X):
        if not np.all(np.isfinite(X)):
            raise RuntimeError(f"integration produced non-finite states in "
                               f"[{self.t:.6g}, {grid[-1]:.6g}] s")
        self.t, self.x = grid[-1], X[-1].copy()
        return X

    def stats(self) -> dict:
        """Solver statistics: function and Jacobian evaluations, steps (counts).

        Returns
        -------
        dict
            Counter name -> count.
        """
        return dict(self.counts)


class ScipyBackend(CvodesBackend):
    """The reference path: SciPy's BDF on the per-component Python right-hand side
    (:meth:`Network.rhs`), per-state absolute tolerance ``atol_scale * scale``.

    Parameters
    ----------
    network : Network
        The model
    rtol : float
        Relative tolerance, [-]
    atol_scale : float
        Absolute tolerance as a fraction of each state's scale, [-]
    """

    name = "scipy"

    def __init__(self, network: Network, rtol: float, atol_scale: float):
        self.network = network
        self.rtol, self.atol = rtol, atol_scale * network.state_scales
        self.counts = {"nfevals": 0, "njevals": 0, "nsteps": 0}

    def advance(self, grid, out=None):
        """States (and, SciPy's BDF restarting at the segment's last time) at the output times.

        Parameters
        ----------
        grid : ndarray
            Output times within the segment, increasing, [s]
        out : ndarray
            Ignored (the sink evaluates the signals and copies the rows), [SI]

        Returns
        -------
        X : ndarray
            States, one row per time, [SI]
        table : None
            None (the sink evaluates the signals)
        """
        from scipy.integrate import solve_ivp

        p = self.p
        sol = solve_ivp(lambda t, y: self.network.rhs(t, y, p), (self.t, grid[-1]), self.x,
                        method="BDF", t_eval=grid, rtol=self.rtol, atol=self.atol)
        if not sol.success:
            raise RuntimeError(f"integration failed at t = {sol.t[-1]:.6g} s: {sol.message}")
        self.counts["nfevals"] += sol.nfev
        self.counts["njevals"] += sol.njev
        return self._accept(grid, sol.y.T), None


#: The CVODES path integrates the network cut open at its interface signals
#: (:func:`hydroline.compiled.codegen.interface_signals`: the connections a component's
#: derivatives read, and the components' internal signals such as a hose end's cavity lift,
#: M45), as the compiled core's bordered Jacobian does: SUNDIALS IDAS (CVODES's DAE sibling,
#: the same variable-order BDF) on the index-1 DAE ``dz/dt = F(z, v)``, ``0 = H(z, v) - v``
#: whose Jacobian stays as sparse as the components' own blocks. On CVODES the ODE's
#: Jacobian holds every path through the connections (default rig: 3422 of 138^2 nonzeros;
#: 4890 with the hose ends' cavities, whose lift every state of a section reads), and its
#: factorisations cost most of a run. False: CVODES on the ODE.
CUT_OPEN = True


def _cut_signals(network: Network) -> list:
    """The signals the CVODES path cuts the network open at (:data:`CUT_OPEN`)."""
    from ..compiled.codegen import interface_signals

    return interface_signals(network)


def _cut_open_dae(network: Network, model, z, x, cut):
    """(dae, consistent): the network cut open at ``cut`` as the index-1 DAE of scaled states
    ``z`` and scaled cut values ``v`` (each signal over a typical magnitude: the largest
    state scale of its unit, else 1 SI unit, so that one absolute tolerance fits them), and
    ``(t, z, p) -> (v, dz/dt)`` consistent with the states (the connections' values from the
    uncut graph, an internal signal's from its component: of the states alone)."""
    import casadi as ca

    units = {}
    for c in network.components:
        for st in c.states:
            units[st.unit] = max(units.get(st.unit, 0.0), float(st.scale))
    scale = []
    for s in cut:
        if isinstance(s, tuple):
            scale.append(1.0)
        else:
            c, port = network.producer[s]
            scale.append(units.get(c.outputs[port].unit, 1.0))
    scale = np.array(scale)
    v = ca.SX.sym("v", len(cut))
    n, m = z.numel(), model.p.numel()
    xs, ps = [x[i] for i in range(n)], [model.p[i] for i in range(m)]
    dx, sig = network.evaluate(model.t, xs, ps, given={s: v[k] * scale[k] for k, s in enumerate(cut)})
    ode = ca.vertcat(*[ca.SX(d) for d in dx]) / ca.DM(network.state_scales)
    alg = ca.vertcat(*[ca.SX(sig[s]) for s in cut]) / ca.DM(scale) - v
    # consistent values: the uncut graph's connections; an internal signal's value is its
    # component's, of the states alone (``sig`` holds it)
    y = model.signals(model.t, x, model.p)
    at = {s: k for k, s in enumerate(network.signal_names)}
    v0 = ca.vertcat(*[y[at[s]] if s in at else ca.SX(sig[s]) for s in cut]) / ca.DM(scale)
    dae = {"t": model.t, "x": z, "z": v, "p": model.p, "ode": ode, "alg": alg}
    values = ca.Function("consistent", [model.t, z, model.p],
                         [v0, ca.substitute(ode, v, v0)])

    def consistent(t, z0, p):
        v_0, rates = values(t, z0, p)
        return np.asarray(v_0).ravel(), np.asarray(rates).ravel().tolist()

    return dae, consistent


def make_backend(network: Network, solver: str, p, rtol: float, atol_scale: float):
    """The backend for ``solver`` (one of :data:`SOLVERS`), and a note when "auto" fell back.

    Parameters
    ----------
    network : Network
        The model
    solver : str
        "auto", "compiled", "cvodes", "scipy" or "radau" (the compiled core
        with Radau IIA)
    p : ndarray
        Runtime parameters, [SI]
    rtol : float
        Relative tolerance, [-]
    atol_scale : float
        Absolute tolerance as a fraction of each state's scale, [-]

    Returns
    -------
    backend : object
        The backend object
    note : str or None
        None, or the reason "auto" did not get the compiled core
    build_time : float
        Time spent building or loading the compiled library, [s]
    """
    import time
    import warnings

    note = None
    build_time = 0.0
    if solver in ("auto", "compiled", "radau"):
        from .. import compiled

        tic = time.perf_counter()
        try:
            native = compiled.native_model(network, wait=True if solver != "auto" else None)
        except compiled.LibraryPending:   # built in the background for the next runs
            note = "compiled core being built in the background; this run used CVODES"
        except (compiled.CompilerUnavailable, compiled.UnsupportedOperation) as e:
            if solver != "auto":
                raise
            note = f"compiled core unavailable ({e}); used CVODES"
            if isinstance(e, compiled.CompilerUnavailable):   # a machine problem: say it once
                warnings.warn(note, RuntimeWarning, stacklevel=3)
            # (an operation the C writer lacks, e.g. a long interpolation table, is by design)
        else:
            build_time = time.perf_counter() - tic
            method = {"radau": "radau", "auto": "auto"}.get(solver, "bdf")
            return (CompiledBackend(network, native, p, rtol, atol_scale, method), None,
                    build_time)
        build_time = time.perf_counter() - tic
    if solver == "scipy":
        return ScipyBackend(network, rtol, atol_scale), note, build_time
    return CvodesBackend(network, rtol, atol_scale), note, build_time
