"""Running an experiment on a rig: :func:`simulate` builds the network of the rig with the
experiment's command components, solves its steady state before the disturbance, integrates,
checks validity (pressures below the gas-release pressure) and returns a
:class:`~hydroline.engine.SimulationResult` whose ``metadata`` holds what the summary needs.

A :class:`Simulation` keeps the models it built (circuit, network, compiled library, rest
state), so that a repeated run of the same rig reuses them; :func:`simulate` runs on the
module's :data:`DEFAULT_SIMULATION`.
"""
from __future__ import annotations

from collections.abc import Mapping
import time as _time
from dataclasses import replace

import numpy as np

from ..blas import one_blas_thread
from ..limits import check_output_size
from ..rigs import Rig, load_rig
from ..rigs.parameters import ATMOSPHERIC_PRESSURE, steady_state_hint
from ..engine import SimulationResult, SteadyState, SteadyStateError, integrate, solve_steady_state
from ..system import build_circuit
from .experiments import Experiment, Scenario, build_scenario, default_scenario
from .summaries import WindowEnd, metrics_window

__all__ = ["simulate", "Simulation", "DEFAULT_SIMULATION", "describe_run", "rest_state",
           "watched_pressures", "axes_pressures", "check_cavitation", "cavity_warnings",
           "CAVITATION_PRESSURE", "WATCHED_NODES", "WATCHED_PRESSURES", "window_end",
           "AFTER_STOP_LOOSENING", "AFTER_STOP_RTOL_MAX", "after_stop_tolerance"]

#: Pressures watched for gas release and cavitation (docs/model.md 8): below the rig's
#: ``fluid.gas_release_pressure`` (absolute; default one atmosphere, the pressure at which oil
#: from a vented tank holds its dissolved air) the oil releases gas and the linear line model
#: no longer holds, [Pa].
CAVITATION_PRESSURE = ATMOSPHERIC_PRESSURE
#: Shared nodes watched besides every axis's ports and chambers (from its handles), where the
#: circuit has them: the HSM nodes of the template rig and of ``two_axis``.
WATCHED_NODES = ("supply.manifold_pressure", "return.manifold_pressure")
#: What is watched in a result without axis handles (the template rig's signals).
WATCHED_PRESSURES = ("supply_port_pressure", "return_port_pressure", "bottom_chamber_pressure",
                     "top_chamber_pressure") + WATCHED_NODES
#: How much looser than ``rtol`` :func:`simulate` integrates by default
#: (``after_stop_rtol="auto"``) once the piston has reached the stop that ends the metrics
#: window, where no metric looks. On the default rig at rtol 1e-6: 40 % fewer steps after the
#: stop and the traces there within 0.12 % of their excursion of a tight reference; 100x
#: (1e-4) saves 48 % at 0.51 %, 300x takes more steps (Newton failures on the ringing lines)
#: (benchmarks/bench_integration.py, docs/engine.md), [-].
AFTER_STOP_LOOSENING = 30.0
#: The loosest relative tolerance ``after_stop_rtol="auto"`` goes to after the stop (a run
#: whose own ``rtol`` is looser keeps it), [-].
AFTER_STOP_RTOL_MAX = 1e-4


def after_stop_tolerance(after_stop_rtol, rtol: float) -> float | None:
    """The relative tolerance of a run once the piston has reached the stop that ends its
    metrics window: :func:`simulate`'s ``after_stop_rtol`` resolved against its ``rtol``.

    Parameters
    ----------
    after_stop_rtol : float, str or None
        "auto": :data:`AFTER_STOP_LOOSENING` x ``rtol``, at most
        :data:`AFTER_STOP_RTOL_MAX`, never tighter than ``rtol``; a number: that
        tolerance; None: ``rtol`` throughout, [-]
    rtol : float
        The run's relative tolerance, [-]

    Returns
    -------
    float or None
        The tolerance after the stop, [-]; None where it is ``rtol`` (nothing to relax).
    """
    if isinstance(after_stop_rtol, str):
        if after_stop_rtol != "auto":
            raise ValueError(f"after_stop_rtol must be a number, 'auto' or None [-], got "
                             f"{after_stop_rtol!r}")
        after_stop_rtol = max(rtol, min(AFTER_STOP_LOOSENING * rtol, AFTER_STOP_RTOL_MAX))
    if after_stop_rtol is None or after_stop_rtol == rtol:
        return None
    return float(after_stop_rtol)



def describe_run(res: SimulationResult, rig: Rig, circuit, net, sc: "Scenario", ss, tic: float,
                 window: bool = True) -> None:
    """Fill a finished run's metadata and warnings as :func:`simulate` gives them (the
    experiment, its axes, natural frequencies, gas-release warnings, metrics window); also
    used by :func:`hydroline.studies.sweep.simulate_shared`, whose variants run on a model
    shared among them.

    Parameters
    ----------
    res : SimulationResult
        The run (modified)
    rig : Rig
        Parameters (SI)
    circuit : Circuit
        The rig's circuit (axis handles)
    net : Network
        The run's network (its components give stroke and w_h)
    sc : Scenario
        The experiment's commands and times
    ss : SteadyState
        The rest state the run started from
    tic : float
        ``time.perf_counter()`` at the run's start, [s]
    window : bool
        Take the metrics window (False for a streamed run)
    """
    res.steady_state = ss
    first = next(iter(circuit.axes.values()))
    act = net.component(first.actuator)
    exp = sc.experiment
    driven = exp.driven_axes(circuit.axes)
    res.metadata.update(exp.metadata())
    res.metadata.update(scenario=sc.name, t_disturbance=sc.t_disturbance, rig=rig.source,
                        stroke=act.stroke, axes=circuit.axes, experiment=exp,
                        driven_axes=driven, stepped_axis=driven[0] if driven else first.name,
                        actuator_natural_frequency_hz=act.hydraulic_natural_frequency(0.0),
                        axis_natural_frequency_hz={
                            n: net.component(a.actuator).hydraulic_natural_frequency(0.0)
                            for n, a in circuit.axes.items()},
                        total_wall_time=_time.perf_counter() - tic,
                        steady_state_residual=ss.residual, n_states=len(net.state_names))
    threshold = rig.get("fluid.gas_release_pressure", CAVITATION_PRESSURE)
    if "stream_stats" not in res.metadata:
        res.warnings.extend(check_cavitation(res, threshold))
    else:   # streamed or kept in part: the column statistics have every column
        lows = res.metadata["stream_stats"]["min"]
        res.warnings.extend(f"{k} falls below the gas-release pressure {threshold / 1e6:.3g} MPa "
                            f"absolute (fluid.gas_release_pressure; lowest {lows[k] / 1e6:.3g} "
                            f"MPa): the line model is not valid there"
                            for k in watched_pressures(res)
                            if k in lows.index and lows[k] < threshold)
    res.warnings.extend(cavity_warnings(res, net))
    if window:
        res.metadata["metrics_window"] = metrics_window(res)
    res.metadata["total_wall_time"] = _time.perf_counter() - tic


class Simulation:
    """Runs experiments on rigs and keeps the models of its recent runs: a repeated run of the
    same rig, scenario and ``t_end`` in one process reuses its circuit, network, compiled
    library and rest state (built anew otherwise). :func:`simulate` runs on
    :data:`DEFAULT_SIMULATION`; an object of one's own keeps its models apart.

    Parameters
    ----------
    models_kept : int
        How many recent models are kept (the oldest goes first)
    recorded_rest_states : bool
        A rest state solved from the components' guess is read from, and stored in, the
        cache's table of rest states (``solve_steady_state(recorded=True)``: the same bits,
        checked by one evaluation of f): a command's single run in a new process
    """

    def __init__(self, models_kept: int = 8, recorded_rest_states: bool = False):
        self.models_kept = models_kept
        self.recorded_rest_states = recorded_rest_states
        #: (scenario, t_end, rig values) -> (circuit, scenario, network, steady state)
        self.models: dict = {}
        #: (scenario, t_end, rig values) -> (circuit, scenario, network) built by
        #: :meth:`model` for a run not made yet
        self.built: dict = {}

    def model(self, rig: Rig, scenario: "str | Experiment | None" = None,
              t_end: float | None = None) -> tuple:
        """The circuit, experiment and network a run of :meth:`run` with these arguments
        integrates, built now and kept for that run (a command reads the model's size before
        the run: it is built once).

        Parameters
        ----------
        rig : Rig
            Parameters (SI)
        scenario : str, Experiment or None
            As :meth:`run`
        t_end : float
            Simulated time, [s] (None: the experiment's own)

        Returns
        -------
        tuple
            ``(circuit, scenario, network)``: the :class:`~hydroline.circuit.Circuit`, the
            :class:`~hydroline.scenarios.experiments.Scenario` and the
            :class:`~hydroline.engine.Network`.
        """
        scenario = scenario or default_scenario(rig)
        key = self.model_key(rig, scenario, t_end)
        if key in self.models:
            return self.models[key][:3]
        model = self.built.get(key) if key is not None else None
        if model is None:
            model = self._build(rig, scenario, t_end)
            if key is not None:
                self.built = {key: model}   # (only the next run's)
        return model

    @staticmethod
    def _build(rig, scenario, t_end):
        circuit = build_circuit(rig)
        sc = build_scenario(rig, scenario, t_end, axes=circuit.axes)
        if sc.position_guess is not None:
            circuit = build_circuit(rig, sc.position_guess)
        return circuit, sc, circuit.network(sc.commands)

    @staticmethod
    def model_key(rig: Rig, scenario, t_end):
        """Key of a run's model in :attr:`models` (None: not kept: a table file may change, or
        an experiment object).

        Parameters
        ----------
        rig : Rig
            Parameters (SI)
        scenario : str or Experiment
            The experiment
        t_end : float
            Simulated time, [s] (None: the experiment's own)

        Returns
        -------
        tuple or None
            The key, or None when the model is not kept.
        """
        if not isinstance(scenario, str) or any(k.endswith(".file") for k in rig.values):
            return None
        return (scenario, t_end, repr(sorted(rig.values.items())))

    def remember(self, key, model) -> None:
        """Keep ``model`` under ``key`` (:meth:`model_key`; None: not kept), forgetting the
        oldest beyond :attr:`models_kept`.

        Parameters
        ----------
        key : tuple
            From :meth:`model_key`
        model : tuple
            (circuit, scenario, network, steady state)
        """
        if key is None:
            return
        if len(self.models) >= self.models_kept:
            self.models.pop(next(iter(self.models)))
        self.models[key] = model

    def rest_state(self, net, key) -> SteadyState:
        """The rest state of a new model, started from that of the most recent kept model of
        the same scenario and states (a rig differing in numbers: its states carried over in
        units of their scales), with its inverse Jacobian for the chord steps: on the default
        rig ~0.9 ms instead of ~5 ms from the components' guess (shifted
        steps, then Newton's). Both starts end on the same rest state, and on the same bits
        but in rare cases (:func:`hydroline.engine.steady_state.polished`), so that a run
        does not depend on what ran before it in the process; where the neighbour's start
        fails, the guess's. A model of the same rig values and scenario (another ``t_end``)
        gets its rest state.

        Parameters
        ----------
        net : Network
            The new model's network
        key : tuple or None
            Its :meth:`model_key` (None: from the components' guess)

        Returns
        -------
        SteadyState
            As :func:`rest_state`.
        """
        if key is None:
            return rest_state(net)
        if self.recorded_rest_states and not self.models:
            return rest_state(net, recorded=True)   # (no neighbour in this process)
        for kept in reversed(list(self.models)):
            _, _, near, near_ss = self.models[kept]
            if kept[0] != key[0] or near.state_names != net.state_names:
                continue
            if kept[2] == key[2]:
                return near_ss          # the same numbers: the same rest state
            try:
                x_guess = near_ss.x / near.state_scales * net.state_scales
                ss = rest_state(net, x_guess, like=near)
            except SteadyStateError:
                break
            if not ss.fallback:
                return ss
            break
        return rest_state(net)

    def run(self, rig: Rig | str | None = None, scenario: "str | Experiment | None" = None,
            t_end: float | None = None, dt_out: float = 1e-4, solver: str = "auto",
            progress=None, rtol: float = 1e-6, atol_scale: float = 1e-7, stream_to=None,
            stream_columns=None, metrics_only: bool = False,
            after_stop_rtol: float | str | None = "auto", **options) -> SimulationResult:
        """Run a scenario on a rig, from its solved steady state, reusing this simulation's
        recent models (:func:`simulate` runs on :data:`DEFAULT_SIMULATION`).

        Parameters
        ----------
        rig, scenario, t_end, dt_out, solver, progress, rtol, atol_scale, stream_to, stream_columns, metrics_only, after_stop_rtol :
            As :func:`simulate` (the same keywords and defaults): the rig,
            the experiment, simulated time [s], output step [s], the integrator and its
            tolerances [-], the streamed output, a run only for its metrics, the tolerance
            after the metrics window's stop [-]
        **options
            Further keywords of :func:`simulate`

        Returns
        -------
        SimulationResult
            As :func:`simulate`
        """
        with one_blas_thread():   # (small dense matrices: a BLAS library's threads only spin)
            return self._run(rig, scenario, t_end, dt_out, solver, progress, rtol, atol_scale,
                             stream_to, stream_columns, metrics_only, options, after_stop_rtol)

    def _run(self, rig, scenario, t_end, dt_out, solver, progress, rtol, atol_scale, stream_to,
             stream_columns, metrics_only, options, after_stop_rtol="auto"):
        tic = _time.perf_counter()
        if not isinstance(rig, Rig):
            rig = load_rig(rig)
        scenario = scenario or default_scenario(rig)
        key = self.model_key(rig, scenario, t_end)
        if key in self.models:
            circuit, sc, net, ss = self.models[key]
        elif key is not None and key in self.built:
            circuit, sc, net = self.built.pop(key)
        else:
            circuit, sc, net = self._build(rig, scenario, t_end)
        kept = options.get("keep_columns")   # bounded memory: only these columns stay in memory
        # (a streamed file holds every stream_every-th row: its size on the disk is that of those)
        written = dt_out * max(int(options.get("stream_every", 1)), 1) if stream_to is not None \
            else dt_out
        check_output_size(sc.t_end, written, len(kept) if kept is not None and stream_to is None
                          else len(net.signal_names) + len(net.state_names),
                          stream_to=stream_to if kept is None or stream_to is not None else None,
                          name="t_end" if t_end is not None else f"scenario.{sc.name}.t_end")
        if key not in self.models:
            ss = self.rest_state(net, key)
            self.remember(key, (circuit, sc, net, ss))
        ss = replace(ss, x=ss.x.copy(), p=ss.p.copy())
        if metrics_only:
            options["until"] = window_end(circuit, sc)
        elif (relaxed := after_stop_tolerance(after_stop_rtol, rtol)) is not None:
            options["relax"] = (window_end(circuit, sc), relaxed, atol_scale * relaxed / rtol)
        res = integrate(net, ss.x, sc.t_end, dt_out=dt_out, p=ss.p, solver=solver,
                        progress=progress, rtol=rtol, atol_scale=atol_scale, stream_to=stream_to,
                        stream_columns=stream_columns, **options)
        if "relaxed_at" in res.stats:   # (the tolerance the rows after res.stats["relaxed_at"] had)
            res.metadata["after_stop_rtol"] = options["relax"][1]
        describe_run(res, rig, circuit, net, sc, ss, tic,
                     window=stream_to is None or options.get("keep_columns") is not None)
        return res


#: The simulation :func:`simulate` (and ``hydroline.simulate``) runs on: its model cache.
DEFAULT_SIMULATION = Simulation()


def window_end(circuit, sc) -> WindowEnd:
    """The ``until`` of a run only for its metrics: its rows reach the end of its metrics
    window (:class:`~hydroline.scenarios.summaries.WindowEnd`).

    Parameters
    ----------
    circuit : Circuit
        The rig's circuit (axis handles: position signals, strokes)
    sc : Scenario
        The experiment's commands and times (its disturbance)

    Returns
    -------
    WindowEnd
    """
    return WindowEnd(sc.t_disturbance, {ax.position: ax.stroke for ax in circuit.axes.values()})


def simulate(rig: Rig | str | None = None, scenario: "str | Experiment | None" = None,
             t_end: float | None = None, dt_out: float = 1e-4, solver: str = "auto",
             progress=None, rtol: float = 1e-6, atol_scale: float = 1e-7, stream_to=None,
             stream_columns=None, metrics_only: bool = False,
             after_stop_rtol: float | str | None = "auto", simulation: Simulation | None = None,
             **options) -> SimulationResult:
    """Run a scenario on a rig, from its solved steady state, on :data:`DEFAULT_SIMULATION`
    (a repeated run of the same rig reuses its model: :class:`Simulation`).

    Parameters
    ----------
    rig : Rig, str or None
        A parsed rig, a path to a rig TOML file, or None for the
        embedded default (the 2005 paper's rig)
    scenario : str or Experiment
        A name (one of
        :data:`~hydroline.scenarios.experiments.SCENARIOS` or the rig's own
        ``[scenario.NAME]``) or an experiment object
        (:class:`~hydroline.scenarios.experiments.Experiment`); None: the
        rig's ``rig.scenario``, else "open-loop-step"
    t_end : float
        Simulated time, [s] (the scenario's default when None)
    dt_out : float
        Output sampling interval, [s]
    solver : str
        "auto" (the compiled C core where a C compiler exists, else
        "cvodes"; its BDF, or its Radau IIA at 100x the tolerances where the
        model's fast modes cap the BDF), "compiled" (its BDF), "cvodes"
        (CasADi + CVODES), "scipy"
        (reference Python path) or "radau" (the C core's Radau IIA); see
        :func:`hydroline.engine.integrate`
    progress : callable
        Called with the fraction done
    rtol : float
        Relative tolerance of the integrator (default 1e-6: the default
        scenario's port pressures and piston velocity then lie within
        6e-3 % of their excursion from a 1e-10 reference, benchmarks/), [-]
    atol_scale : float
        Absolute tolerance as a fraction of each state's typical
        magnitude, [-]
    stream_to : path
        Stream the time series to this CSV file in constant memory (long
        runs); ``data`` then holds the last row only and
        ``metadata["stream_stats"]`` per-column min/max/mean/rms
    stream_columns : list
        Columns to stream (all when None)
    metrics_only : bool
        A run only for its metrics (a study's): it ends at the end of its
        metrics window (the piston at the stop it moves toward,
        :func:`~hydroline.scenarios.summaries.metrics_window`), where
        every metric ends: the same metrics, less to integrate; its rows,
        and the gas-release check, end there too
    after_stop_rtol : float, str or None
        Relative tolerance once the piston has reached the stop that ends the metrics
        window (no metric looks there; ``atol_scale`` scaled alike), on the compiled core
        with rows in memory (streamed runs and the other solvers keep ``rtol``): "auto"
        (the default) 30x ``rtol``, at most 1e-4 (:func:`after_stop_tolerance`; the default
        rig's traces after the stop then within 0.12 % of their excursion of a tight
        reference, docs/engine.md); None: ``rtol`` throughout, [-]
    simulation : Simulation or None
        The :class:`Simulation` to run on (its kept models); None:
        :data:`DEFAULT_SIMULATION`
    options
        Further keywords of :func:`hydroline.engine.integrate`
        (``stream_every``, ``keep_columns``, ``preview_columns``, ...)

    Returns
    -------
    SimulationResult
        (``.data`` has every signal and state; ``.metadata`` the scenario,
        the disturbance time, the actuator's hydraulic natural frequency)
    """
    simulation = DEFAULT_SIMULATION if simulation is None else simulation
    return simulation.run(rig, scenario, t_end, dt_out=dt_out, solver=solver,
                          progress=progress, rtol=rtol, atol_scale=atol_scale,
                          stream_to=stream_to, stream_columns=stream_columns,
                          metrics_only=metrics_only, after_stop_rtol=after_stop_rtol, **options)


def rest_state(net, x_guess=None, like=None, recorded: bool = False):
    """The network's steady state before the run; a failure is said in terms of the rig's
    parameters (:func:`hydroline.rigs.parameters.steady_state_hint`).

    Parameters
    ----------
    net : Network
        The rig's network with the experiment's commands
    x_guess : array
        Start for the solver, [SI]; the components' guesses when None
    like : Network or None
        A network of the same states solved before, whose inverse Jacobian starts
        the chord steps (:func:`hydroline.engine.steady_state.solve_steady_state`)
    recorded : bool
        Read and store it in the cache's table of rest states (``solve_steady_state``'s
        ``recorded``)

    Returns
    -------
    SteadyState

    Raises
    ------
    SteadyStateError
        Naming the balance that does not close and the parameters to look at
    """
    try:
        return solve_steady_state(net, t0=0.0, x_guess=x_guess, like=like, recorded=recorded)
    except SteadyStateError as e:   # say it in terms of the rig's parameters
        if getattr(e, "state", None) is None:
            raise
        raise SteadyStateError(f"steady state not found before the run: "
                               f"{steady_state_hint(e.state)}; the solver stopped with a scaled "
                               f"residual of {e.residual:.3g} 1/s at '{e.state}'",
                               e.state, e.residual) from None


def watched_pressures(res: SimulationResult) -> list[str]:
    """Pressure signals watched for cavitation: every axis's ports and chambers (from the
    handles in ``res.metadata["axes"]``) and the shared nodes (:data:`WATCHED_NODES`); the
    template's signals (:data:`WATCHED_PRESSURES`) for a result without handles.

    Parameters
    ----------
    res : SimulationResult
        A run

    Returns
    -------
    list of str
        Signal names.
    """
    return axes_pressures(res.metadata.get("axes") or {})


def axes_pressures(axes: dict) -> list[str]:
    """Pressure signals watched for cavitation in a circuit with these axes (what
    :func:`watched_pressures` gives for its runs, known before a run).

    Parameters
    ----------
    axes : dict
        Axis name -> :class:`~hydroline.circuit.Axis` (its signal handles); empty: the
        template's signals (:data:`WATCHED_PRESSURES`)

    Returns
    -------
    list of str
        Signal names.
    """
    if not axes:
        return list(WATCHED_PRESSURES)
    out = []
    for ax in axes.values():
        out += [s for s in (ax.supply_pressure, ax.return_pressure, ax.bottom_pressure,
                            ax.top_pressure) if s not in out]
    return out + [s for s in WATCHED_NODES if s not in out]


class _LazyColumns(Mapping):
    """A run's state columns by local state name, each read when asked for."""

    def __init__(self, res, columns: dict):
        self._res, self._columns = res, columns

    def __getitem__(self, name):
        return self._res[self._columns[name]]

    def __iter__(self):
        return iter(self._columns)

    def __len__(self):
        return len(self._columns)


def cavity_warnings(res: SimulationResult, net) -> list[str]:
    """One warning per chamber, volume or hose end in which a gas/vapour cavity opened (M42,
    M45: the component's ``cavity_equation``): when, and how large it grew (from the run's state columns; none for a run that did not keep them).

    Parameters
    ----------
    res : SimulationResult
        The run
    net : Network
        Its network (components with ``cavity_volumes``)

    Returns
    -------
    list[str]
        One line each
    """
    out = []
    for c in net.components:
        fluid = getattr(c, "fluid", None)
        if fluid is None or fluid.cavity_pressure is None or not hasattr(c, "cavity_volumes"):
            continue
        cols = {s.name: f"{c.name}.{s.name}" for s in c.states}
        if not all(k in res for k in cols.values()):
            continue
        # (each column read when asked for: a hose end reads its end pressure, or a few of
        # its modes)
        outputs = _LazyColumns(res, {port: c.signal(port) for port in c.outputs
                                     if c.signal(port) in res})
        for where, v in c.cavity_volumes(_LazyColumns(res, cols), outputs).items():
            v = np.asarray(v, dtype=float)
            i = int(np.argmax(v))
            if v[i] <= 0:
                continue
            first = res.t[np.argmax(v > 0)]
            out.append(f"{c.name} {where}: a gas/vapour cavity opened below "
                       f"fluid.cavity_pressure = {fluid.cavity_pressure / 1e3:.3g} kPa absolute "
                       f"from t = {first * 1e3:.1f} ms; largest {v[i] * 1e6:.3g} cm^3 at "
                       f"{res.t[i] * 1e3:.1f} ms, {v[-1] * 1e6:.3g} cm^3 at the end "
                       f"({getattr(c, 'cavity_equation', 'M42')})")
    return out


def check_cavitation(res: SimulationResult, threshold: float = CAVITATION_PRESSURE) -> list[str]:
    """One warning per watched pressure that falls below ``threshold`` absolute (docs/model.md
    8), giving the time of the first crossing.

    Parameters
    ----------
    res : SimulationResult
        A run
    threshold : float
        Gas-release pressure, absolute, [Pa] (``fluid.gas_release_pressure``)

    Returns
    -------
    list of str
        One warning per pressure that fell below ``threshold``.
    """
    out = []
    for k in watched_pressures(res):
        if k not in res:
            continue
        p = res[k]
        i = int(np.argmin(p))
        if p[i] < threshold:
            below = res.t[p < threshold]
            what = ("cavitate (below 0 Pa absolute)" if threshold <= 0 else
                    f"release gas (below the gas-release pressure {threshold / 1e6:.3g} MPa "
                    f"absolute, fluid.gas_release_pressure)")
            out.append(f"{k} falls below {threshold / 1e6:.3g} MPa absolute from t = "
                       f"{below[0] * 1e3:.1f} ms (lowest {p[i] / 1e6:.3g} MPa at "
                       f"{res.t[i] * 1e3:.1f} ms): the oil would {what} there and the line model "
                       f"is not valid; raise the return/back pressure or shorten the hose")
    return out
