"""Steady-state start and time integration of an assembled network (docs/model.md section 6).

The model (a :class:`~hydroline.network.Network`), its parameters (components built from a
rig) and the solver are kept apart: :func:`solve_steady_state` finds the network's rest state
for the inputs before the disturbance; :func:`integrate` runs the model compiled to C with a
sparse-Jacobian BDF integrator (:mod:`hydroline.compiled`, the default where a C compiler
exists), with SUNDIALS CVODES (through CasADi, exact sparse Jacobian) or, as the plain reference
path, SciPy's BDF on the per-component Python right-hand side.
"""
from __future__ import annotations

import time as _time
import warnings
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import pandas as pd

from .network import Network

__all__ = ["SteadyState", "solve_steady_state", "integrate", "SimulationResult",
           "SteadyStateError", "SOLVERS", "column_units"]


class SteadyStateError(RuntimeError):
    """The steady-state solver did not converge; the message says how far it got.

    Attributes
    ----------
    state : str        The state with the largest scaled residual (None when unknown)
    residual : float   Its scaled residual, [1/s]
    """

    def __init__(self, message, state=None, residual=None):
        super().__init__(message)
        self.state, self.residual = state, residual


@dataclass
class SteadyState:
    """A solved rest state.

    Attributes
    ----------
    x : ndarray          States, [SI]
    p : ndarray          Runtime parameters after settling, [SI]
    residual : float     max_i |dx_i/dt| / scale_i at x, [1/s] (0 for an exact rest state)
    worst_state : str    Name of the state with the largest scaled residual
    """

    x: np.ndarray
    p: np.ndarray
    residual: float
    worst_state: str


def _scaled_residual(model, t, x, p, scales):
    r = model.rhs(t, x, p) / scales
    k = int(np.argmax(np.abs(r)))
    return float(abs(r[k])), k


def _pseudo_transient(model, t0, x, p, scales, tol, dt0=1e-5, max_iter=500):
    """Pseudo-transient continuation (Kelley & Keyes, SIAM J. Numer. Anal. 35 (1998) 508):
    implicit-Euler steps ``(I/dt - J) dz = f`` in scaled states with dt growing as the residual
    falls (switched evolution relaxation), ending in plain Newton steps. Robust where Newton
    alone stalls on the kinks of check valves, stops and orifices."""
    z0 = x / scales
    best, best_res = z0, np.inf
    for attempt in range(3):   # a first step too long can land in a far basin: shorter ones
        z = _pseudo_transient_run(model, t0, z0, p, scales, tol, dt0 * 0.1 ** attempt,
                                  max_iter * (1 + 3 * attempt))
        r = np.max(np.abs(model.rhs(t0, z * scales, p) / scales)) if np.all(np.isfinite(z)) else np.inf
        if r < best_res:   # keep the best attempt (a later, shorter start may end worse)
            best, best_res = z, r
        if r < tol:
            break
    return best * scales


def _pseudo_transient_run(model, t0, z, p, scales, tol, dt0, max_iter):
    """One pseudo-transient run from scaled states ``z``; returns the scaled states reached."""
    z = z.copy()
    n = len(z)

    def resid(z):
        return model.rhs(t0, z * scales, p) / scales

    r = resid(z)
    norm = np.linalg.norm(r)
    dt = dt0
    for _ in range(max_iter):
        if np.max(np.abs(r)) < tol:
            break
        J = model.jacobian(t0, z * scales, p) * scales[None, :] / scales[:, None]
        M = np.eye(n) / dt - J
        try:
            dz = np.linalg.solve(M, r)
        except np.linalg.LinAlgError:
            dz = np.linalg.lstsq(M, r, rcond=1e-14)[0]
        z_new = z + dz
        r_new = resid(z_new)
        norm_new = np.linalg.norm(r_new)
        if not np.isfinite(norm_new) or norm_new > 10 * norm:
            dt *= 0.1
            continue
        z, r = z_new, r_new
        # grow dt by the residual ratio, and by at least 1.5x per accepted step: a slow
        # transient (an accumulator filling through a 2 mm hose, a return side behind a
        # closed check valve) would otherwise creep for thousands of steps; a step that
        # overshoots is still refused above and dt cut
        dt = min(dt * max(norm / max(norm_new, 1e-300), 1.5), 1e12)
        norm = norm_new
    return z


def solve_steady_state(network: Network, t0: float = 0.0, x_guess=None, tol: float = 1e-9,
                       max_rounds: int = 3) -> SteadyState:
    """Solve ``f(t0, x) = 0`` for the whole network (docs/model.md 6), then let components settle.

    Pseudo-transient continuation with the compiled model's exact Jacobian, on the states
    scaled by their typical magnitudes, starting from the components' guesses; components
    then settle (e.g. accumulators adopt the steady pressure as their charge state) and the
    solve repeats until nothing changes.

    Parameters
    ----------
    network : Network   The assembled model
    t0 : float          Time at which the inputs are taken (before the disturbance), [s]
    x_guess : array     Start for the solver; the components' guesses when None
    tol : float         Required scaled residual, [1/s]

    Returns
    -------
    SteadyState
    """
    model = network.compile()
    scales = network.state_scales
    p = network.parameter_values.copy()
    x = network.guess() if x_guess is None else np.asarray(x_guess, dtype=float).copy()
    for _ in range(max_rounds):
        x = _pseudo_transient(model, t0, x, p, scales, tol)
        changed = False
        for c in network.components:
            sl = network.state_slice(c.name)
            xs = {s.name: x[sl.start + i] for i, s in enumerate(c.states)}
            u = network.signals_at(t0, x, p)
            ps = {k: p[network.parameter_names.index(f"{c.name}.{k}")]
                  for k in c.runtime_parameters()}
            cu = {port: u[c.signal(port)] for port in c.inputs}
            res = c.settle(xs, cu, ps)
            if res is None:
                continue
            new_x, new_p = res
            for i, s in enumerate(c.states):
                if s.name in new_x:
                    changed |= abs(new_x[s.name] - x[sl.start + i]) > 1e-12 * scales[sl.start + i]
                    x[sl.start + i] = new_x[s.name]
            for k, v in new_p.items():
                j = network.parameter_names.index(f"{c.name}.{k}")
                p[j] = v
        res, k = _scaled_residual(model, t0, x, p, scales)
        if res < tol and not changed:
            break
    res, k = _scaled_residual(model, t0, x, p, scales)
    if not np.all(np.isfinite(x)) or res > 1e-4:
        raise SteadyStateError(
            f"steady state not found: scaled residual {res:.3g} 1/s at state "
            f"'{network.state_names[k]}' (check pressures, laps and initial position)",
            state=network.state_names[k], residual=res)
    return SteadyState(x, p, res, network.state_names[k])


@dataclass
class SimulationResult:
    """Time series of every named signal and state.

    Attributes
    ----------
    data : pandas.DataFrame   Index ``time`` [s]; one column per signal and per state
                              (``<component>.<state>``), SI units
    steady_state : SteadyState
    wall_time : float         Integration wall time, [s]
    stats : dict              Solver statistics (function/Jacobian evaluations, steps)
    warnings : list[str]      Validity warnings (e.g. pressure below zero absolute)
    """

    data: pd.DataFrame
    steady_state: SteadyState | None = None
    wall_time: float = 0.0
    stats: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    metadata: dict = field(default_factory=dict)

    @property
    def t(self) -> np.ndarray:
        return self.data.index.to_numpy()

    def __getitem__(self, key) -> np.ndarray:
        return self.data[key].to_numpy()

    def to_csv(self, path):
        """Write all series to CSV: ``time [s]`` first, then every column with its SI unit in
        the header (``supply_port_pressure [Pa]``), as ``hydroline fit`` reads it."""
        units = self.metadata.get("units", {})
        named = {c: f"{c} [{units[c]}]" for c in self.data.columns if c in units}
        self.data.rename(columns=named).to_csv(path, index_label="time [s]")

    def plot(self, signals=None, path=None, title=None):
        """Plot signals (default: the paper's Figs. 10-12 set when present). Returns the figure."""
        from .plotting import plot_result

        return plot_result(self, signals=signals, path=path, title=title)


def _segments(t_end, breakpoints, sample_time=None):
    edges = {0.0, float(t_end)}
    edges.update(b for b in breakpoints if 0 < b < t_end)
    if sample_time:
        n = int(np.floor(t_end / sample_time + 1e-9))
        edges.update(k * sample_time for k in range(1, n + 1) if k * sample_time < t_end)
    return sorted(edges)


SOLVERS = ("auto", "compiled", "cvodes", "scipy")


def integrate(network: Network, x0, t_end: float, dt_out: float = 1e-4, p=None,
              solver: str = "auto", rtol: float = 1e-7, atol_scale: float = 1e-8,
              progress=None, stream_to=None, chunk_rows: int = 20000,
              stream_columns=None) -> SimulationResult:
    """Integrate the network from x0 over [0, t_end], sampled every dt_out.

    Parameters
    ----------
    network : Network   The model
    x0 : array          Initial state (e.g. ``solve_steady_state(...).x``), [SI]
    t_end : float       End time, [s]
    dt_out : float      Output interval, [s]
    p : array           Runtime parameters (network defaults when None)
    solver : str        "auto" (default: "compiled" where a C compiler is available, else
                        "cvodes"), "compiled" (the network as C code with a sparse-Jacobian
                        BDF integrator, :mod:`hydroline.compiled`; library cached on disk),
                        "cvodes" (CasADi + SUNDIALS CVODES, exact sparse Jacobian) or "scipy"
                        (reference: per-component Python right-hand side, SciPy BDF)
    rtol : float        Relative tolerance
    atol_scale : float  Absolute tolerance as a fraction of each state's typical magnitude
    progress : callable Called with the fraction done (0..1) after each segment or chunk
    stream_to : path    Write the time series to this CSV file chunk by chunk as the run
                        goes, keeping only per-column summary statistics in memory (constant
                        memory for long runs); ``data`` then holds the last row only and
                        ``metadata["stream_stats"]`` the min/max/mean/rms of every column
    chunk_rows : int    Output rows per chunk (streaming and the compiled path)
    stream_columns : list  Columns to write when streaming (all signals and states if None)

    Returns
    -------
    SimulationResult
    """
    if not t_end > 0:
        raise ValueError(f"t_end must be > 0 [s], got {t_end!r}")
    if solver not in SOLVERS:
        raise ValueError(f"solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
    if not (rtol > 0 and atol_scale > 0):
        raise ValueError(f"rtol and atol_scale must be > 0 [-], got {rtol!r} and {atol_scale!r}")
    p = network.parameter_values.copy() if p is None else np.asarray(p, dtype=float).copy()
    model = network.compile()
    n_out = int(round(t_end / dt_out))
    t_last = n_out * dt_out
    h_out = t_last / n_out

    def t_out(i0, i1):   # output times i0..i1-1 (made per chunk: constant memory)
        return np.arange(i0, i1) * h_out

    sampled = [c for c in network.components if getattr(c, "sample_time", None)]
    sample_time = sampled[0].sample_time if sampled else None
    edges = _segments(t_last, network.breakpoints(t_last), sample_time)
    atol = atol_scale * network.state_scales
    x = np.asarray(x0, dtype=float).copy()
    notes = []
    solver_note = None
    native = None
    build_time = 0.0
    if solver in ("auto", "compiled"):
        from . import compiled

        tic = _time.perf_counter()
        try:
            native = compiled.native_model(network)
        except (compiled.CompilerUnavailable, compiled.UnsupportedOperation) as e:
            if solver == "compiled":
                raise
            solver_note = f"compiled core unavailable ({e}); used CVODES"
            if isinstance(e, compiled.CompilerUnavailable):   # a machine problem: say it once
                warnings.warn(solver_note, RuntimeWarning, stacklevel=2)
            # (an operation the C writer lacks, e.g. a long interpolation table, is by design)
        build_time = _time.perf_counter() - tic
    backend = "compiled" if native is not None else ("cvodes" if solver == "auto" else solver)
    columns = list(network.signal_names) + list(network.state_names)
    sink = _Sink(columns, stream_to, stream_columns)
    stats = {"nfevals": 0, "njevals": 0, "nsteps": 0}
    scaled_dae = None
    if backend == "cvodes":
        dae = {"t": model.t, "x": model.x, "p": model.p, "ode": model.dx}
        # per-state absolute tolerance through scaling: CVODES integrates z = x / scale
        scaled_dae = _scaled_dae(dae, network.state_scales)
    ns = native.solver(p, rtol=rtol, atol=atol_scale) if native is not None else None
    sink.write(t_out(0, 1), x[None, :], None, model, p)
    chunk_rows = max(int(chunk_rows), 1)
    tic = _time.perf_counter()
    for a, b in zip(edges[:-1], edges[1:]):
        if sampled:
            _apply_samples(network, sampled, a, x, p)
        # output indices i0..i1-1 lie in (a, b]
        i0 = int(np.floor((a + 1e-12) / h_out)) + 1
        i1 = min(int(np.floor((b + 1e-12) / h_out)) + 1, n_out + 1)
        n_in = max(i1 - i0, 0)
        ends_on_grid = n_in > 0 and abs(t_out(i1 - 1, i1)[0] - b) <= 1e-12
        n_grid = n_in if ends_on_grid else n_in + 1   # the segment end b is always reached
        step = len_chunk = chunk_rows if (backend == "compiled" or stream_to is not None) else n_grid
        if backend == "compiled":
            if sampled:
                ns.set_parameters(p)
            ns.start(a, x, b)
        t_a = a
        for k in range(0, n_grid, step):
            g = t_out(i0 + k, i0 + min(k + len_chunk, n_in))
            if k + len_chunk >= n_grid and not ends_on_grid:
                g = np.append(g, b)
            if backend == "compiled":
                Y = ns.advance(g, table=True)   # signals and states in one table
                X = Y[:, len(network.signal_names):]
            else:   # CVODES/SciPy restart at each sub-interval when streaming (bounded memory)
                X = _integrate_cvodes_scipy(backend, network, scaled_dae, t_a, g, x, p, rtol,
                                            atol_scale, atol, stats)
                Y = None
                t_a = g[-1]
            m = min(n_in - k, len(g))
            if m > 0:
                if backend == "compiled":
                    sink.write(g[:m], None, Y[:m], model, p)
                else:
                    sink.write(g[:m], X[:m], None, model, p)
            x = X[-1].copy()
            if progress and n_grid > step:
                progress(g[-1] / t_last)
        if progress:
            progress(b / t_last)
    wall = _time.perf_counter() - tic
    if ns is not None:
        stats.update(ns.stats())
    stats["build_time"] = build_time
    res = SimulationResult(data=sink.result(), wall_time=wall, stats=stats, warnings=notes)
    res.metadata.update(solver=backend, rtol=rtol, atol_scale=atol_scale,
                        units=column_units(network))
    if solver_note:
        res.metadata["solver_note"] = solver_note
    if stream_to is not None:
        res.metadata.update(stream_to=str(stream_to), stream_stats=sink.stats_frame(),
                            stream_rows=sink.rows)
    return res


def column_units(network: Network) -> dict:
    """Signal or state name -> its SI unit (``"-"`` for a pure number), from the ports and
    states the components declare."""
    units = {}
    for c in network.components:
        for port, spec in c.outputs.items():
            units[c.signal(port)] = spec.unit
        for st in c.states:
            units[f"{c.name}.{st.name}"] = st.unit or "-"
    return units


def _integrate_cvodes_scipy(backend, network, scaled_dae, a, grid, x, p, rtol, atol_scale, atol,
                            stats):
    """States at the grid times (the last one is the segment end) by CVODES or SciPy BDF."""
    if backend == "cvodes":
        F = ca.integrator("F", "cvodes", scaled_dae, a, list(grid),
                          {"reltol": rtol, "abstol": atol_scale, "max_num_steps": 200000})
        out = F(x0=x / network.state_scales, p=p)
        Z = np.asarray(out["xf"]).T * network.state_scales
        st = F.stats()
        stats["nfevals"] += int(st.get("nfevals", 0))
        stats["njevals"] += int(st.get("njevals", 0) or st.get("nlinsetups", 0))
        stats["nsteps"] += int(st.get("nsteps", 0))
    else:
        from scipy.integrate import solve_ivp

        sol = solve_ivp(lambda t, y: network.rhs(t, y, p), (a, grid[-1]), x, method="BDF",
                        t_eval=grid, rtol=rtol, atol=atol)
        if not sol.success:
            raise RuntimeError(f"integration failed at t = {sol.t[-1]:.6g} s: {sol.message}")
        Z = sol.y.T
        stats["nfevals"] += sol.nfev
        stats["njevals"] += sol.njev
    if not np.all(np.isfinite(Z)):
        raise RuntimeError(f"integration produced non-finite states in [{a:.6g}, {grid[-1]:.6g}] s")
    return Z


class _Sink:
    """Collects output rows in memory, or streams them to CSV keeping column statistics."""

    def __init__(self, columns, path, keep=None):
        self.columns = columns
        self.path = path
        self.rows = 0
        self.parts = []
        self.last = None
        if path is not None:
            keep = list(columns) if keep is None else list(keep)
            unknown = [k for k in keep if k not in columns]
            if unknown:
                raise ValueError(f"stream_columns: unknown signal(s)/state(s) {', '.join(unknown)}")
            self.keep = keep
            self.index = np.array([columns.index(k) for k in keep], dtype=int)
            self.file = open(path, "w", buffering=1 << 20)
            self.file.write(",".join(["time"] + keep) + "\n")
            n = len(keep)
            self.mn, self.mx = np.full(n, np.inf), np.full(n, -np.inf)
            self.sum, self.sumsq = np.zeros(n), np.zeros(n)

    def write(self, t, X, Y, model, p):
        """Rows at times t: states X and signals Y (None: computed here), or with X None the
        table Y of signals and states side by side."""
        if X is None:
            block = Y
        else:
            if Y is None:
                Y = np.asarray(model.signals.map(len(t))(t, X.T, np.tile(p[:, None], len(t)))).T
            block = np.hstack([np.asarray(Y).reshape(len(t), -1), X])
        self.rows += len(t)
        if self.path is None:
            self.parts.append((np.array(t, dtype=float), block))
            return
        sel = block[:, self.index]
        self.mn = np.minimum(self.mn, sel.min(axis=0))
        self.mx = np.maximum(self.mx, sel.max(axis=0))
        self.sum += sel.sum(axis=0)
        self.sumsq += (sel * sel).sum(axis=0)
        np.savetxt(self.file, np.column_stack([t, sel]), fmt="%.9g", delimiter=",")
        self.last = (np.array(t[-1:], dtype=float), block[-1:])

    def result(self) -> pd.DataFrame:
        if self.path is not None:
            self.file.close()
            t, block = self.last
        else:
            t = np.concatenate([q[0] for q in self.parts])
            block = np.vstack([q[1] for q in self.parts])
        return pd.DataFrame(block, index=pd.Index(t, name="time"), columns=self.columns)

    def stats_frame(self) -> pd.DataFrame:
        n = max(self.rows, 1)
        mean = self.sum / n
        return pd.DataFrame({"min": self.mn, "max": self.mx, "mean": mean,
                             "rms": np.sqrt(self.sumsq / n)}, index=self.keep)


def _scaled_dae(dae, scales):
    """The ODE in scaled states z = x/scale, so one absolute tolerance fits every state."""
    z = ca.SX.sym("z", dae["x"].shape[0])
    ode = ca.substitute(dae["ode"], dae["x"], z * ca.DM(scales)) / ca.DM(scales)
    return {"t": dae["t"], "x": z, "p": dae["p"], "ode": ode}


def _apply_samples(network, sampled, t, x, p):
    sig = network.signals_at(t, x, p)
    for c in sampled:
        sl = network.state_slice(c.name)
        xs = {s.name: x[sl.start + i] for i, s in enumerate(c.states)}
        u = {port: sig[c.signal(port)] for port in c.inputs}
        for k, v in c.sample(xs, u).items():
            p[network.parameter_names.index(f"{c.name}.{k}")] = v
