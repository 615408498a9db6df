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
from dataclasses import dataclass

import numpy as np

from .network import Component, Network

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


class _CompiledRest:
    """f(t, x, p) and its Jacobian from the network's compiled C library, with the interface
    of :class:`~hydroline.network.CompiledModel` (``rhs``, ``jacobian``, ``signals``): the
    steady-state iterations then cost microseconds each instead of CasADi's call overhead."""

    def __init__(self, model, native):
        self.model = model
        self.solver = native.solver(model.network.parameter_values)
        self.p_bytes = np.asarray(model.network.parameter_values, dtype=float).tobytes()
        self.scales = np.asarray(model.network.state_scales, dtype=float)
        g = native.generated
        self.rows = np.asarray(g.jac_row, dtype=np.intp)
        self.cols = np.repeat(np.arange(g.n_states), np.diff(g.jac_colind))
        self.jnz = np.empty(max(g.jac_nnz, 1))
        self.signals = model.signals

    def _use(self, p):
        b = np.asarray(p, dtype=float).tobytes()
        if b != self.p_bytes:   # the components' settling changed a parameter
            self.solver.set_parameters(p)
            self.p_bytes = b

    def rhs(self, t, x, p):
        self._use(p)
        return self.solver.rhs(t, x)

    def scaled_jacobian(self, t, x, p):
        """d(dz/dt)/dz, dense, in the scaled states z = x/scale."""
        self._use(p)
        J = np.zeros((len(self.scales), len(self.scales)))
        self.solver.scaled_jacobian_nonzeros(t, x, self.jnz)
        J[self.rows, self.cols] = self.jnz[:len(self.rows)]
        return J

    def jacobian(self, t, x, p):
        return self.scaled_jacobian(t, x, p) * self.scales[:, None] / self.scales[None, :]


def _rest_functions(network):
    """The model's f and Jacobian for the steady-state solve: compiled C where a library can
    be built (it is the one the integration uses), else the CasADi functions."""
    model = network.compile()
    try:
        from . import compiled

        return _CompiledRest(model, compiled.native_model(network))
    except Exception:   # no compiler, an operation the C writer lacks, an unusable cache
        return model


def _scaled_jacobian(model, t, x, p, scales):
    if hasattr(model, "scaled_jacobian"):
        return model.scaled_jacobian(t, x, p)
    return model.jacobian(t, x, p) * scales[None, :] / scales[:, None]


def _newton(model, t0, x, p, scales, tol, max_iter=30):
    """Newton's method with the exact Jacobian and a backtracking line search on the scaled
    states, from x. Returns (x, converged): quick where it converges; where it does not (the
    kinks of check valves, stops and orifices), pseudo-transient continuation takes over."""
    z = x / scales

    def resid(z):
        return model.rhs(t0, z * scales, p) / scales

    r = resid(z)
    norm = np.linalg.norm(r)
    for _ in range(max_iter):
        if not np.isfinite(norm):
            return x, False
        if np.max(np.abs(r)) < tol:
            return z * scales, True
        J = _scaled_jacobian(model, t0, z * scales, p, scales)
        try:
            dz = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:
            return x, False
        lam = 1.0
        while True:
            z_new = z + lam * dz
            r_new = resid(z_new)
            norm_new = np.linalg.norm(r_new)
            if np.isfinite(norm_new) and norm_new <= (1.0 - 1e-4 * lam) * norm:
                break
            lam *= 0.5
            if lam < 0.05:   # far from the root's basin: leave it to the continuation
                return x, False
        z, r, norm = z_new, r_new, norm_new
    return (z * scales, True) if np.max(np.abs(r)) < tol else (x, False)


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
        J = _scaled_jacobian(model, t0, z * scales, p, scales)
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

    Newton's method with the compiled model's exact Jacobian (in C where a compiler exists),
    on the states scaled by their typical magnitudes, starting from the components' guesses;
    where Newton does not converge, pseudo-transient continuation from the same start.
    Components then settle (e.g. accumulators adopt the steady pressure as their charge
    state) and the solve repeats until nothing changes.

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
    model = _rest_functions(network)
    scales = network.state_scales
    p = network.parameter_values.copy()
    x = network.guess() if x_guess is None else np.asarray(x_guess, dtype=float).copy()
    # only components that define settle() can change anything after a solve
    settling = [c for c in network.components if type(c).settle is not Component.settle]
    for _ in range(max_rounds):
        x_newton, converged = _newton(model, t0, x, p, scales, tol)
        x = x_newton if converged else _pseudo_transient(model, t0, x, p, scales, tol)
        changed = False
        for c in settling:
            sl = network.state_slice(c.name)
            xs = {s.name: x[sl.start + i] for i, s in enumerate(c.states)}
            u = _signals(model, network, t0, x, p)
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


def _signals(model, network, t, x, p) -> dict:   # model: CompiledModel or _CompiledRest
    """Every signal at (t, x, p) from the compiled graph (as ``network.signals_at``, whose
    per-component Python evaluation costs about a hundred times more)."""
    return dict(zip(network.signal_names, np.asarray(model.signals(t, x, p), dtype=float).ravel()))


class SimulationResult:
    """Time series of every named signal and state.

    Attributes
    ----------
    data : pandas.DataFrame   Index ``time`` [s]; one column per signal and per state
                              (``<component>.<state>``), SI units (made on first access;
                              ``res[name]``, ``res.t`` and ``name in res`` need no pandas)
    columns : list[str]       Column names of ``data``, signals first
    steady_state : SteadyState
    wall_time : float         Integration wall time, [s]
    stats : dict              Solver statistics (function/Jacobian evaluations, steps)
    warnings : list[str]      Validity warnings (e.g. pressure below zero absolute)
    """

    def __init__(self, data=None, steady_state: SteadyState | None = None, wall_time: float = 0.0,
                 stats: dict | None = None, warnings: list | None = None,
                 metadata: dict | None = None, *, times=None, table=None, columns=None):
        if data is not None:   # a DataFrame given: its index is the time
            times, table, columns = data.index.to_numpy(), data.to_numpy(), list(data.columns)
        self._times = np.asarray(times, dtype=float)
        self._table = np.asarray(table, dtype=float).reshape(len(self._times), -1)
        self.columns = list(columns)
        self._column_index = {c: k for k, c in enumerate(self.columns)}
        self._data = data
        self.steady_state = steady_state
        self.wall_time = wall_time
        self.stats = {} if stats is None else stats
        self.warnings = [] if warnings is None else warnings
        self.metadata = {} if metadata is None else metadata

    @property
    def data(self):
        if self._data is None:
            import pandas as pd

            self._data = pd.DataFrame(self._table, index=pd.Index(self._times, name="time"),
                                      columns=self.columns, copy=False)
        return self._data

    @property
    def t(self) -> np.ndarray:
        return self._times

    def __getitem__(self, key) -> np.ndarray:
        if self._data is not None:
            return self._data[key].to_numpy()
        try:
            return self._table[:, self._column_index[key]]
        except KeyError:
            raise KeyError(key) from None

    def __contains__(self, key) -> bool:
        return key in self._column_index if self._data is None else key in self._data

    def csv_header(self) -> list[str]:
        """``time [s]``, then every column with its SI unit (``supply_port_pressure [Pa]``), as
        ``hydroline fit`` reads it."""
        units = self.metadata.get("units", {})
        return ["time [s]"] + [f"{c} [{units[c]}]" if c in units else c for c in self.columns]

    def to_csv(self, path, every: int = 1):
        """Write all series to CSV: ``time [s]`` first, then every column with its SI unit in
        the header (``supply_port_pressure [Pa]``), as ``hydroline fit`` reads it; with
        ``every`` > 1 only every n-th row and the last."""
        rows = slice(None)
        if every > 1:
            rows = np.unique(np.r_[np.arange(0, len(self._times), every), len(self._times) - 1])
        if self._data is not None:
            self._times, self._table = self._data.index.to_numpy(), self._data.to_numpy()
            self.columns = list(self._data.columns)
        with open(path, "w", buffering=1 << 20) as f:
            f.write(",".join(self.csv_header()) + "\n")
            write_csv_rows(f, self._times[rows], self._table[rows])

    def plot(self, signals=None, path=None, title=None):
        """Plot signals (default: the paper's Figs. 10-12 set when present). Returns the figure."""
        from .plotting import plot_result

        return plot_result(self, signals=signals, path=path, title=title)


def write_csv_rows(file, t, block):
    """Rows ``t, block[i, :]`` as CSV text, each number in Python's shortest round-trip form
    (what pandas writes; NaN as an empty field)."""
    data = np.column_stack([np.asarray(t, dtype=float), np.asarray(block, dtype=float)])
    step = max(1, 100_000 // max(data.shape[1], 1))
    for k in range(0, len(data), step):
        part = data[k:k + step]
        rows = part.tolist()
        if np.isnan(part).any():
            text = "\n".join(",".join("" if v != v else repr(v) for v in r) for r in rows)
        else:
            text = "\n".join(",".join(map(repr, r)) for r in rows)
        file.write(text + "\n")


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
              stream_columns=None, stream_every: int = 1, keep_columns=None,
              preview_columns=None, preview_rows: int = 50_000,
              observe=None) -> SimulationResult:
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
    stream_every : int  Write every n-th output row to ``stream_to`` (decimation; the last row
                        always), [-]
    keep_columns : list Keep only these columns in memory (every output row): ``data`` then
                        holds them, and ``metadata["stream_stats"]`` has the statistics of
                        every column (bounded memory for long runs without a file)
    preview_columns : list  Also keep these columns at every k-th row, at most
                        ``preview_rows`` rows (``metadata["preview"]``, a SimulationResult:
                        a figure of a long run)
    observe : callable  Called with ``(t, table, columns)`` for every block of output rows as
                        the run goes (times [s], rows of signals and states [SI], their names):
                        statistics of a long run computed chunk by chunk, in constant memory

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
    sink = _Sink(columns, stream_to, stream_columns, stream_every, keep_columns, n_out + 1,
                 preview_columns, preview_rows, column_units(network) if stream_to else None,
                 observe)
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
        bounded = stream_to is not None or keep_columns is not None
        step = len_chunk = chunk_rows if (backend == "compiled" or bounded) else n_grid
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
    t_rows, table, kept = sink.result()
    res = SimulationResult(times=t_rows, table=table, columns=kept, wall_time=wall,
                           stats=stats, warnings=notes)
    res.metadata.update(solver=backend, rtol=rtol, atol_scale=atol_scale,
                        units=column_units(network))
    if solver_note:
        res.metadata["solver_note"] = solver_note
    if stream_to is not None:
        res.metadata.update(stream_to=str(stream_to), stream_rows=sink.written,
                            stream_stats=sink.stats_frame(sink.keep_file))
    elif keep_columns is not None:
        res.metadata.update(stream_stats=sink.stats_frame())
    preview = sink.preview_result()
    if preview is not None:
        res.metadata["preview"] = SimulationResult(times=preview[0], table=preview[1],
                                                   columns=preview[2])
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
        import casadi as ca

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


def _column_indices(what, names, columns):
    names = list(names)
    unknown = [k for k in names if k not in columns]
    if unknown:
        raise ValueError(f"{what}: unknown signal(s)/state(s) {', '.join(unknown)}")
    return names, np.array([columns.index(k) for k in names], dtype=int)


class _Sink:
    """Where output rows go: kept in memory (all columns, or only ``keep``), streamed to CSV
    (every ``every``-th row of ``stream`` columns, the last row always) with per-column
    statistics, and a preview (``preview`` columns at most ``preview_rows`` rows, for a
    figure). Memory stays bounded by what is kept, whatever the run's length."""

    def __init__(self, columns, path, stream=None, every=1, keep=None, n_total=None,
                 preview=None, preview_rows=50_000, units=None, observe=None):
        self.columns = columns
        self.observe = observe   # (issue 13: per-chunk statistics of a long run)
        self.path = path
        self.rows = 0
        self.parts = []
        self.last = None
        self.every = max(int(every), 1)
        self.n_total = n_total
        self.stats_index = None
        if path is not None:
            self.keep_file, self.index = _column_indices(
                "stream_columns", columns if stream is None else stream, columns)
            self.file = open(path, "w", buffering=1 << 20)
            units = units or {}
            self.file.write(",".join(["time [s]"] + [f"{c} [{units[c]}]" if c in units else c
                                                    for c in self.keep_file]) + "\n")
            self.written = 0
        if path is not None or keep is not None:   # statistics of every column
            self.stats_names = list(columns)
            n = len(columns)
            self.mn, self.mx = np.full(n, np.inf), np.full(n, -np.inf)
            self.sum, self.sumsq = np.zeros(n), np.zeros(n)
            self.stats_index = True
        self.keep = self.kept = None
        if keep is not None:
            self.keep, self.keep_index = _column_indices("keep_columns", keep, columns)
            if n_total is not None:   # preallocated: no copy at the end
                self.kept_t = np.empty(n_total)
                self.kept = np.empty((n_total, len(self.keep)))
        self.preview = None
        if preview is not None:
            self.preview, self.preview_index = _column_indices("preview_columns", preview, columns)
            self.preview_every = max(1, -(-int(n_total or 1) // max(int(preview_rows), 1)))
            self.preview_parts = []

    def write(self, t, X, Y, model, p):
        """Rows at times t: states X and signals Y (None: computed here), or with X None the
        table Y of signals and states side by side."""
        if X is None:
            block = Y
        else:
            if Y is None:
                Y = np.asarray(model.signals.map(len(t))(t, X.T, np.tile(p[:, None], len(t)))).T
            block = np.hstack([np.asarray(Y).reshape(len(t), -1), X])
        t = np.asarray(t, dtype=float)
        if self.observe is not None:
            self.observe(t, block, self.columns)
        i0 = self.rows
        self.rows += len(t)
        if self.preview is not None:
            k = np.arange(i0, self.rows)
            sel = (k % self.preview_every == 0) | (k == (self.n_total or 0) - 1)
            if sel.any():
                self.preview_parts.append((t[sel], block[np.ix_(sel, self.preview_index)]))
        if self.stats_index is not None:
            self.mn = np.minimum(self.mn, block.min(axis=0))
            self.mx = np.maximum(self.mx, block.max(axis=0))
            self.sum += block.sum(axis=0)
            self.sumsq += np.einsum("ij,ij->j", block, block)   # (no temporary block)
        if self.keep is not None:
            if self.kept is not None and self.rows <= len(self.kept_t):
                self.kept_t[i0:self.rows] = t
                self.kept[i0:self.rows] = block[:, self.keep_index]
            else:   # more rows than foreseen: go on in parts
                if self.kept is not None:
                    self.parts.append((self.kept_t[:i0], self.kept[:i0]))
                    self.kept = None
                self.parts.append((t.copy(), block[:, self.keep_index]))
        elif self.path is None:
            self.parts.append((t, block))
        if self.path is not None:
            rows = np.arange(i0, self.rows)
            sel = (rows % self.every == 0)
            if self.n_total is not None:
                sel |= rows == self.n_total - 1   # the run's end is always written
            if sel.all():
                out_t, out = t, block[:, self.index]
            else:
                out_t, out = t[sel], block[np.ix_(sel, self.index)]
            if len(out_t):
                np.savetxt(self.file, np.column_stack([out_t, out]), fmt="%.9g", delimiter=",")
                self.written += len(out_t)
        self.last = (t[-1:].copy(), block[-1:].copy())

    def result(self):
        """(times, table, columns): the rows kept (all columns, or the ``keep`` columns), or the
        last row of every column when streaming without ``keep``."""
        if self.path is not None:
            self.file.close()
        if self.keep is not None:
            if self.kept is not None:
                return self.kept_t[:self.rows], self.kept[:self.rows], self.keep
            t = np.concatenate([q[0] for q in self.parts])
            return t, np.vstack([q[1] for q in self.parts]), self.keep
        if self.path is not None:
            return self.last[0], self.last[1], self.columns
        if len(self.parts) == 1:
            return self.parts[0][0], self.parts[0][1], self.columns
        return (np.concatenate([q[0] for q in self.parts]),
                np.vstack([q[1] for q in self.parts]), self.columns)

    def preview_result(self):
        """(times, table, columns) of the preview, or None."""
        if self.preview is None or not self.preview_parts:
            return None
        return (np.concatenate([q[0] for q in self.preview_parts]),
                np.vstack([q[1] for q in self.preview_parts]), self.preview)

    def stats_frame(self, names=None):
        import pandas as pd

        n = max(self.rows, 1)
        frame = pd.DataFrame({"min": self.mn, "max": self.mx, "mean": self.sum / n,
                              "rms": np.sqrt(self.sumsq / n)}, index=self.stats_names)
        return frame if names is None else frame.loc[list(names)]


def _scaled_dae(dae, scales):
    """The ODE in scaled states z = x/scale, so one absolute tolerance fits every state."""
    import casadi as ca

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
