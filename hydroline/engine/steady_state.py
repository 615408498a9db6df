"""The rest state before the disturbance (docs/model.md section 6).

:func:`solve_steady_state` solves ``f(t0, x) = 0`` for the whole network: Newton's method with
the exact Jacobian of the compiled model (in C where a compiler exists), on states scaled by
their typical magnitudes, globalised by shifted (implicit-Euler) steps where a Newton step
fails on the kinks of check valves, stops and orifices; pseudo-transient continuation as the
last resort; then the components settle (:func:`settle_components`) and the solve repeats
until nothing changes.
"""
from __future__ import annotations

import hashlib
import math
import weakref
from dataclasses import dataclass

import numpy as np

from ..blas import one_blas_thread
from .component import Component
from .network import Network

__all__ = ["SteadyState", "SteadyStateError", "solve_steady_state", "pseudo_transient",
           "settle_components"]


class SteadyStateError(RuntimeError):
    """The steady-state solver did not converge; the message says how far it got.

    Parameters
    ----------
    message : str
        One line: what did not settle and which parameters to look at
    state : str
        The state with the largest scaled residual (None when unknown)
    residual : float
        Its scaled residual, [1/s] (None when unknown)

    Attributes
    ----------
    state : str
        The state with the largest scaled residual (None when unknown)
    residual : float
        Its scaled residual, [1/s]
    """

    def __init__(self, message, state=None, residual=None):
        super().__init__(message)
        self.state, self.residual = state, residual


@dataclass
class SteadyState:
    """A solved rest state.

    Attributes
    ----------
    x : ndarray
        States, [SI]
    p : ndarray
        Runtime parameters after settling, [SI]
    residual : float
        ``max_i |dx_i/dt| / scale_i`` at x, [1/s] (0 for an exact rest state)
    worst_state : str
        Name of the state with the largest scaled residual
    newton_steps : int
        Newton and chord steps taken, all rounds, [-]
    shifted_steps : int
        Shifted (implicit-Euler) steps the Newton iteration took where a
        Newton step failed, all rounds (:data:`SHIFT_START`), [-]
    fallback : bool
        True where the Newton iteration did not converge and the
        pseudo-transient continuation (:func:`pseudo_transient`) took over
    """

    x: np.ndarray
    p: np.ndarray
    residual: float
    worst_state: str
    newton_steps: int = 0
    shifted_steps: int = 0
    fallback: bool = False


def _scaled_residual(model, t, x, p, scales):
    r = model.rhs(t, x, p) / scales
    k = int(np.argmax(np.abs(r)))
    return float(abs(r[k])), k


class _CompiledRest:
    """f(t, x, p), its Jacobian and the signals from the network's compiled C library, with
    the interface of :class:`~hydroline.engine.CompiledModel` (``rhs``, ``jacobian``,
    ``signals``): the steady-state iterations then cost microseconds each instead of
    CasADi's call overhead, and a model loaded from the cache needs no CasADi graph."""

    def __init__(self, network, native):
        self.native = native
        self.solver = native.solver(network.parameter_values)
        self.scales = np.asarray(network.state_scales, dtype=float)
        self._bordered = None

    def rhs(self, t, x, p):
        self.solver.set_parameters(p)   # (the components' settling may change one)
        return self.solver.rhs(t, x)

    def scaled_jacobian(self, t, x, p):
        """d(dz/dt)/dz, dense, in the scaled states z = x/scale."""
        self.solver.set_parameters(p)   # (the components' settling may change one)
        return self.solver.scaled_jacobian(t, x)

    def jacobian(self, t, x, p):
        return self.scaled_jacobian(t, x, p) * self.scales[:, None] / self.scales[None, :]

    def solve_shifted(self, t, x, p, shift, b):
        """dz solving ``(shift I - J) dz = b`` (J of the scaled states) through the model's
        bordered Jacobian (:mod:`hydroline.compiled.bordered`; sparse on a large model, whose
        dense J grows with the square of its states and its solve with their cube).

        Parameters
        ----------
        t : float
            Time, [s]
        x : ndarray
            States, [SI]
        p : ndarray
            Runtime parameters, [SI]
        shift : float
            s, [1/s]
        b : ndarray
            Right-hand side, [1/s]
        """
        from ..compiled.bordered import BorderedSystem

        if self._bordered is None:
            self._bordered = BorderedSystem(self.native)
        return self._bordered.solve_shifted(t, x, p, shift, b)

    def signals(self, t, x, p):
        """Every signal at (t, x, p), [SI], in the network's signal order."""
        self.solver.set_parameters(p)   # (the components' settling may change one)
        return self.solver.signals(t, x)


def _rest_functions(network):
    """The model's f, Jacobian and signals for the steady-state solve: compiled C where a
    library can be built or loaded (it is the one the integration uses), else the CasADi
    functions."""
    try:
        from .. import compiled

        return _CompiledRest(network, compiled.native_model(network))
    except Exception:   # no compiler, an operation the C writer lacks, an unusable cache
        return network.compile()


def _scaled_jacobian(model, t, x, p, scales):
    if hasattr(model, "scaled_jacobian"):
        return model.scaled_jacobian(t, x, p)
    return model.jacobian(t, x, p) * scales[None, :] / scales[:, None]


def _solve_shifted(model, t, x, p, scales, shift, b, dense=False):
    """dz solving ``(shift I - J) dz = b``, J the Jacobian of the scaled states at (t, x):
    the model's own (sparse) solve where it has one and ``dense`` is False, else dense
    (numpy.linalg.LinAlgError when singular)."""
    solve = None if dense else getattr(model, "solve_shifted", None)
    dz = solve(t, x, p, shift, b) if solve is not None else None
    if dz is not None:
        return dz
    J = _scaled_jacobian(model, t, x, p, scales)
    if shift == 0.0:
        return np.linalg.solve(J, -b)
    return np.linalg.solve(np.eye(len(b)) * shift - J, b)


#: Newton's step (scaled states, i.e. a fraction of each state's typical magnitude) below
#: which the iteration has converged to the rounding of its evaluation: the step is taken
#: and the state returned, [-]. (The scaled residual of a short hose's fast tail states
#: does not fall below ~1e-9 to 2e-8 1/s, above the default tolerance 1e-9, while Newton's
#: last steps are ~1e-14 of the states' scales: a sweep's rest states then fell back to the
#: pseudo-transient continuation, 5-170 ms instead of ~1 ms, on 1 variant in 5.)
ROUNDING_STEP = 1e-10
#: Scaled residual below which a step under :data:`ROUNDING_STEP` counts as converged (far
#: above every rounding floor seen, far below a state still moving), [1/s].
ROUNDING_RESIDUAL = 1e-6


#: Largest model (states) whose rest-state Newton iteration works with a dense inverse of
#: its scaled Jacobian (chord steps, below), [-]. Larger ones solve through the model's own
#: (sparse) system at every step.
CHORD_STATES = 200
#: A chord step (the Jacobian's inverse from an earlier state) must cut the residual norm
#: to this fraction, else the Jacobian is taken anew at the current state, [-].
CHORD_RATE = 0.25


#: Per network, the inverse Jacobian its last rest-state solve kept (:func:`_newton`): a
#: sweep solves one network for every variant, each from the last one's rest state.
_CHORDS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


#: Shift of the first shifted step, where a Newton step fails: the step solves
#: ``(mu I - J) dz = f`` in scaled states, an implicit-Euler step of 1/mu seconds, [1/s].
#: (The components' guess of a rig puts a check valve at zero flow, the middle of its switch,
#: where its pressure drop rises with R_r/2 instead of R_f: the default rig's return check
#: valve at rest passes the servovalve's leakage, ~100 transition flows away, and Newton's
#: step from the guess, linearised on the reverse slope, raises the return manifold's
#: pressure by ~50 MPa; its line search then finds no descent. Shifted steps follow the
#: transient across the switch instead: 7-8 steps from 1e4 1/s on hoses of 0.02-3 m.)
SHIFT_START = 1e4
#: A shifted step may raise the residual norm by at most this factor (the transient it
#: follows need not lower the residual at every step: oscillating lines, accumulators), else
#: it is refused and the shift raised tenfold, [-].
SHIFT_REFUSE = 10.0
#: After an accepted shifted step the shift falls by the square of the residual norm's
#: ratio, and at least by this factor, [-]; below ``1 / NEWTON_LIKE_STEP`` the steps are
#: Newton's again. (By the ratio alone, the switched evolution relaxation of
#: :func:`pseudo_transient`, 11-30 steps; squared, 7-8.)
SHIFT_FALL = 1.5


def _newton(model, t0, x, p, scales, tol, max_iter=40, chord=None, counts=None):
    """Newton's method with the exact Jacobian and a backtracking line search on the scaled
    states, from x, globalised by shifted steps. Returns (x, converged): where it does not
    converge (a kink it cannot cross), pseudo-transient continuation takes over.
    Converged means a scaled residual below ``tol``, or, where rounding may keep the
    residual above it, a Newton step below :data:`ROUNDING_STEP` (taken) from a residual
    below :data:`ROUNDING_RESIDUAL`.

    Where a Newton step's line search finds no descent (or its Jacobian is singular), the
    following steps are shifted, ``(mu I - J) dz = f`` (implicit-Euler steps of 1/mu
    seconds, from ``mu =`` :data:`SHIFT_START`): each accepted unless it raises the residual
    norm by more than :data:`SHIFT_REFUSE` (then mu rises tenfold), mu falling after each
    by the square of the residual norm's ratio (at least by :data:`SHIFT_FALL`) until the
    steps are Newton's again.

    With ``chord`` (a dict kept by the caller across calls, for a model of at most
    :data:`CHORD_STATES` states) the steps use the inverse of the scaled Jacobian kept
    there (``"inverse"``) as long as each cuts the residual norm to :data:`CHORD_RATE`
    (chord steps: one matrix-vector product each); where one does not, or none is kept, the
    Jacobian at the current state is inverted and kept, and the step is Newton's with the
    line search. (A layout variant's rest state: ~2-4 Newton steps and one more after the
    accumulators settle, each a solve of the 138-state model's bordered system, ~0.4 ms.)
    ``counts`` (a dict) gets ``"newton"`` and ``"shifted"`` added: the steps of each kind."""
    z = x / scales
    n_newton = n_shifted = 0

    def resid(z):
        return model.rhs(t0, z * scales, p) / scales

    def inverse(z):
        inv = np.linalg.inv(_scaled_jacobian(model, t0, z * scales, p, scales))
        chord["inverse"] = inv
        return inv

    def done(z, converged):
        if counts is not None:
            counts["newton"] = counts.get("newton", 0) + n_newton
            counts["shifted"] = counts.get("shifted", 0) + n_shifted
        return (z * scales, True) if converged else (x, False)

    r = resid(z)
    norm = np.linalg.norm(r)
    mu = 0.0                            # the shift; 0: Newton's steps
    for _ in range(max_iter):
        if not np.isfinite(norm):
            return done(z, False)
        if np.max(np.abs(r)) < tol:
            return done(z, True)
        if mu > 0.0:                    # a shifted step
            n_shifted += 1
            try:     # (a model small enough for chord steps: dense, as they are)
                dz = _solve_shifted(model, t0, z * scales, p, scales, mu, r,
                                    dense=chord is not None)
            except np.linalg.LinAlgError:
                mu *= 10.0
                continue
            z_new = z + dz
            r_new = resid(z_new)
            norm_new = np.linalg.norm(r_new)
            if not np.isfinite(norm_new) or norm_new > SHIFT_REFUSE * norm:
                mu *= 10.0
                continue
            mu *= min((norm_new / max(norm, 1e-300)) ** 2, 1.0 / SHIFT_FALL)
            if mu < 1.0 / NEWTON_LIKE_STEP:
                mu = 0.0
            z, r, norm = z_new, r_new, norm_new
            continue
        n_newton += 1
        try:
            if chord is None:
                dz = _solve_shifted(model, t0, z * scales, p, scales, 0.0, r)
            else:
                kept = chord.get("inverse")
                if kept is not None:          # a chord step
                    dz = -(kept @ r)
                    z_new = z + dz
                    r_new = resid(z_new)
                    norm_new = np.linalg.norm(r_new)
                    if np.isfinite(norm_new) and norm_new <= CHORD_RATE * norm:
                        z, r, norm = z_new, r_new, norm_new
                        continue
                    if np.max(np.abs(dz)) <= ROUNDING_STEP and \
                            np.max(np.abs(r)) < ROUNDING_RESIDUAL:
                        return done(z_new, True)
                dz = -(inverse(z) @ r)
        except np.linalg.LinAlgError:
            mu = SHIFT_START
            continue
        if np.max(np.abs(dz)) <= ROUNDING_STEP and np.max(np.abs(r)) < ROUNDING_RESIDUAL:
            return done(z + dz, True)          # converged to the rounding of f
        lam = 1.0
        while True:
            z_new = z + lam * dz
            r_new = resid(z_new)
            norm_new = np.linalg.norm(r_new)
            if np.isfinite(norm_new) and norm_new <= (1.0 - 1e-4 * lam) * norm:
                break
            lam *= 0.5
            if lam < 0.05:   # far from the root's basin: shifted steps from here
                break
        if lam < 0.05:
            mu = SHIFT_START
            continue
        z, r, norm = z_new, r_new, norm_new
    return done(z, np.max(np.abs(r)) < tol)


def pseudo_transient(model, t0, x, p, scales, tol, dt0=1e-5, max_iter=500):
    """Pseudo-transient continuation (Kelley & Keyes, SIAM J. Numer. Anal. 35 (1998) 508):
    implicit-Euler steps ``(I/dt - J) dz = f`` in scaled states with dt growing as the residual
    falls (switched evolution relaxation), ending in plain Newton steps. Robust where Newton
    alone stalls on the kinks of check valves, stops and orifices.

    Parameters
    ----------
    model : object
        ``rhs(t, x, p)`` [state units/s] and ``jacobian(t, x, p)`` (or
        ``scaled_jacobian``) of the equations to bring to rest
    t0 : float
        Time at which the inputs are taken, [s]
    x : ndarray
        Start, [SI]
    p : ndarray
        Runtime parameters, [SI]
    scales : ndarray
        Typical magnitude of each state, [SI]
    tol : float
        Required scaled residual max|f_i/scale_i|, [1/s]
    dt0 : float
        First pseudo time step (in scaled time), [s]
    max_iter : int
        Steps of the first attempt (later, shorter-start attempts get more)

    Returns
    -------
    ndarray
        The best state reached, [SI] (check its residual: it may not meet ``tol``)
    """
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


#: Pseudo time step beyond which a step of the continuation is a Newton step, [s]
NEWTON_LIKE_STEP = 1e6
#: Accepted Newton-like steps (``dt`` beyond :data:`NEWTON_LIKE_STEP`) that must together
#: halve the residual norm; a run whose steps no longer do has reached the rounding floor of
#: its evaluation (the scaled residual of a hose's fast tail states, ~1e-9 1/s, sits at about
#: the default tolerance): it stops there, and the next attempt (a shorter first step:
#: another path, other roundings) tries again. (Before, such a run took its 500 steps, and
#: the next its 2000: ~100 ms instead of ~5.) [-]
STALL_STEPS = 5


def _pseudo_transient_run(model, t0, z, p, scales, tol, dt0, max_iter):
    """One pseudo-transient run from scaled states ``z``; returns the scaled states reached
    (where the residual met ``tol``, or where its Newton-like steps no longer reduce it: the
    rounding floor)."""
    z = z.copy()
    n = len(z)

    def resid(z):
        return model.rhs(t0, z * scales, p) / scales

    r = resid(z)
    norm = np.linalg.norm(r)
    dt = dt0
    newton_norms = []      # the residual norms after the Newton-like steps, in order
    for _ in range(max_iter):
        if np.max(np.abs(r)) < tol:
            break
        if (len(newton_norms) > STALL_STEPS
                and newton_norms[-1] > 0.5 * newton_norms[-1 - STALL_STEPS]):
            return z
        try:
            dz = _solve_shifted(model, t0, z * scales, p, scales, 1.0 / dt, r)
        except np.linalg.LinAlgError:
            M = np.eye(n) / dt - _scaled_jacobian(model, t0, z * scales, p, scales)
            dz = np.linalg.lstsq(M, r, rcond=1e-14)[0]
        z_new = z + dz
        r_new = resid(z_new)
        norm_new = np.linalg.norm(r_new)
        if not np.isfinite(norm_new) or norm_new > 10 * norm:
            dt *= 0.1
            continue
        z, r = z_new, r_new
        if dt >= NEWTON_LIKE_STEP:
            newton_norms.append(norm_new)
        # grow dt by the residual ratio, and by at least 1.5x per accepted step: a slow
        # transient (an accumulator filling through a 2 mm hose, a return side behind a
        # closed check valve) would otherwise creep for thousands of steps; a step that
        # overshoots is still refused above and dt cut
        dt = min(dt * max(norm / max(norm_new, 1e-300), 1.5), 1e12)
        norm = norm_new
    return z


def solve_steady_state(network: Network, t0: float = 0.0, x_guess=None, tol: float = 1e-9,
                       max_rounds: int = 3, like: Network | None = None,
                       recorded: bool = False) -> SteadyState:
    """Solve ``f(t0, x) = 0`` for the whole network (docs/model.md 6), then let components settle.

    Newton's method with the compiled model's exact Jacobian (in C where a compiler exists),
    on the states scaled by their typical magnitudes, starting from the components' guesses,
    with shifted steps where a Newton step fails (:data:`SHIFT_START`); where that does not
    converge, pseudo-transient continuation from the same start (``SteadyState.fallback``).
    Components then settle (e.g. accumulators adopt the steady pressure as their charge
    state) and the solve repeats until nothing changes.

    Parameters
    ----------
    network : Network
        The assembled model
    t0 : float
        Time at which the inputs are taken (before the disturbance), [s]
    x_guess : array
        Start for the solver, [SI]; the components' guesses when None
    tol : float
        Required scaled residual, [1/s]
    max_rounds : int
        Solve-and-settle rounds at most (components adopting the rest state)
    like : Network or None
        A network of the same states solved before (a rig differing in numbers): its last
        solve's inverse Jacobian starts this one's chord steps (:func:`_newton`; they are
        taken only while each cuts the residual to :data:`CHORD_RATE`)
    recorded : bool
        Read the rest state from the cache's table of rest states
        (:func:`hydroline.compiled.records.recorded_rest_state`) where a solve of
        the same compiled model, numbers, start and settings stored it (checked by one
        evaluation of f, whose scaled residual must be the one recorded: the same bits as
        the solve), and store it there after a solve; from the components' guess on the
        compiled core only (a command's single run: ~4 ms of a warm ``simulate``)

    Returns
    -------
    SteadyState
    """
    with one_blas_thread():     # (small dense solves: extra BLAS threads only spin)
        return _solve_steady_state(network, t0, x_guess, tol, max_rounds, like, recorded)


def _rest_record_key(model, network, x, t0, tol, max_rounds) -> str | None:
    """Key of a recorded rest state: the compiled model's numbers record key
    (structure and code), its constants (the numbers), the runtime parameters, the state
    scales, the start, the settings and this module's source; None off the compiled core."""
    from .fingerprint import Undescribable, module_source_tag

    native = getattr(model, "native", None)
    key = getattr(native, "numbers_record_key", None)
    if key is None:
        return None
    try:
        code = module_source_tag(__name__)
    except Undescribable:
        return None
    h = hashlib.sha256()
    for a in (native.generated.constants, network.parameter_values, network.state_scales, x):
        h.update(np.ascontiguousarray(a, dtype=float).tobytes())
        h.update(b"|")
    return f"rest:{key}:{h.hexdigest()}:{t0!r}:{tol!r}:{max_rounds}:{code}"


def _recorded_rest_state(record, model, network, t0) -> SteadyState | None:
    """The rest state stored under ``record`` where f at it has the recorded residual."""
    from ..compiled.records import recorded_rest_state

    value = recorded_rest_state(record)
    try:
        x = np.array([float.fromhex(v) for v in value["x"]])
        p = np.array([float.fromhex(v) for v in value["p"]])
        if len(x) != len(network.state_names) or len(p) != len(network.parameter_values):
            return None
        res, k = _scaled_residual(model, t0, x, p, network.state_scales)
        if not np.all(np.isfinite(x)) or res.hex() != value["residual"]:
            return None
        return SteadyState(x, p, res, network.state_names[k], int(value["newton_steps"]),
                           int(value["shifted_steps"]), bool(value["fallback"]))
    except (TypeError, KeyError, ValueError, IndexError):   # none, or not of this form
        return None


def _solve_steady_state(network, t0, x_guess, tol, max_rounds, like=None, recorded=False):
    model = _rest_functions(network)
    scales = network.state_scales
    p = network.parameter_values.copy()
    x = network.guess() if x_guess is None else np.asarray(x_guess, dtype=float).copy()
    record = (_rest_record_key(model, network, x, t0, tol, max_rounds)
              if recorded and x_guess is None else None)
    if record is not None:
        kept = _recorded_rest_state(record, model, network, t0)
        if kept is not None:
            return kept
    # only components that define settle() can change anything after a solve
    settling = [c for c in network.components if type(c).settle is not Component.settle]
    chord = None
    if len(scales) <= CHORD_STATES:     # kept through the rounds, and for the next solve of
        chord = _CHORDS.setdefault(network, {})     # this network (a sweep's next variant)
        if not chord and like is not None and like.state_names == network.state_names:
            chord.update(_CHORDS.get(like, {}))
    counts, fallback = {}, False
    for _ in range(max_rounds):
        x_newton, converged = _newton(model, t0, x, p, scales, tol, chord=chord, counts=counts)
        fallback |= not converged
        x = x_newton if converged else pseudo_transient(model, t0, x, p, scales, tol)
        x = polished(model, t0, x, p, scales, tol)      # (what settles: the same bits)
        changed = bool(settling) and settle_components(network, settling, x, p,
                                                 _signals(model, network, t0, x, p))
        res, k = _scaled_residual(model, t0, x, p, scales)
        if (res < tol or converged) and not changed:
            break
    res, k = _scaled_residual(model, t0, x, p, scales)
    if not np.all(np.isfinite(x)) or res > 1e-4:
        raise SteadyStateError(
            f"steady state not found: scaled residual {res:.3g} 1/s at state "
            f"'{network.state_names[k]}' (check pressures, laps and initial position)",
            state=network.state_names[k], residual=res)
    ss = SteadyState(x, p, res, network.state_names[k], counts.get("newton", 0),
                     counts.get("shifted", 0), fallback)
    if record is not None:
        from ..compiled.records import record_rest_state

        record_rest_state(record, {
            "x": [v.hex() for v in x.tolist()], "p": [v.hex() for v in p.tolist()],
            "residual": res.hex(), "newton_steps": ss.newton_steps,
            "shifted_steps": ss.shifted_steps, "fallback": ss.fallback})
    return ss


#: The grid of the scaled states (2 to the minus this) that :func:`polished` starts its last
#: Newton step from, [-].
CANONICAL_BITS = 30


#: Longest step (scaled states) :func:`polished` takes from the grid point, [-]: a thousand
#: grid steps.
POLISH_STEP = 1e3 * 2.0 ** -CANONICAL_BITS


def polished(model, t0, x, p, scales, tol):
    """The converged rest state x made independent of the path that reached it: rounded to a
    grid of 2**-:data:`CANONICAL_BITS` of each state's scale, then one Newton step with the
    Jacobian taken there. Two starts (the components' guess, a neighbour rig's rest state,
    each with its own chord inverse) end within ~1e-14 of the scales, on the same grid point
    but where they straddle one (odds ~1e-5 a state), and so on the same bits: what the
    components settle to from it (an accumulator's charge, a sampled controller's held
    current) too, and a run's rows do not depend on what ran before it. (Without this, a
    1e-14 difference of the start flips step decisions of the integrator and moves the
    rows by ~1e-5 of their excursion.) Every solve-and-settle round ends with it. The step
    from the grid, ~1e-9 away, lands within rounding of the root; where it is longer than
    :data:`POLISH_STEP` (a singular Jacobian: a state free at rest, as the piston under a
    held valve current) or does not lower the residual to the solver's tolerance (or twice
    the given state's), x is kept as it was.

    Parameters
    ----------
    model : object
        The rest-state functions (``rhs``, the Jacobian and its solves)
    t0 : float
        Time, [s]
    x : ndarray
        The converged rest state, [SI]
    p : ndarray
        Runtime parameters, [SI]
    scales : ndarray
        The states' scales, [SI]
    tol : float
        The solver's scaled-residual tolerance, [1/s]

    Returns
    -------
    ndarray
        The polished rest state, [SI] (x where the step does not hold).
    """
    grid = 2.0 ** -CANONICAL_BITS
    z = np.round(x / scales / grid) * grid
    r = model.rhs(t0, z * scales, p) / scales
    try:
        dz = _solve_shifted(model, t0, z * scales, p, scales, 0.0, r,
                            dense=len(scales) <= CHORD_STATES)
    except np.linalg.LinAlgError:
        return x
    if not np.all(np.abs(dz) <= POLISH_STEP):     # (a free direction: a sampled
        return x                                    # controller's held piston position)
    x_new = (z + dz) * scales
    r_new = model.rhs(t0, x_new, p) / scales
    r_old = model.rhs(t0, x, p) / scales
    if not np.all(np.isfinite(r_new)) or \
            np.max(np.abs(r_new)) > max(tol, 2.0 * np.max(np.abs(r_old))):
        return x
    return x_new


def settle_components(network: Network, components, x, p, signals: dict) -> bool:
    """Let components adopt a solved rest state (:meth:`Component.settle`: e.g. an accumulator
    takes the steady pressure as its charge state); updates ``x`` and ``p`` in place.

    Parameters
    ----------
    network : Network
        The model
    components : list
        The components to ask (those that define ``settle``)
    x : ndarray
        Solved states, [SI]; changed in place
    p : ndarray
        Runtime parameters, [SI]; changed in place
    signals : dict
        Every signal at (x, p), name -> value [SI]

    Returns
    -------
    bool
        True when a state moved by more than 1e-12 of its scale (solve again)
    """
    changed = False
    scales = network.state_scales
    for c in components:
        sl = network.state_slice(c.name)
        xs, ps = network.component_values(c, x, p)
        res = c.settle(xs, {port: signals[c.signal(port)] for port in c.inputs}, ps)
        if res is None:
            continue
        new_x, new_p = res
        for i, s in enumerate(c.states):
            if s.name in new_x:
                j = sl.start + i
                changed |= abs(new_x[s.name] - x[j]) > 1e-12 * scales[j]
                x[j] = new_x[s.name]
        for k, v in new_p.items():
            p[network.parameter_names.index(f"{c.name}.{k}")] = v
    return changed


def _signals(model, network, t, x, p) -> dict:   # model: CompiledModel or _CompiledRest
    """Every signal at (t, x, p) from the compiled graph (as ``network.signals_at``, whose
    per-component Python evaluation costs about a hundred times more)."""
    return dict(zip(network.signal_names, np.asarray(model.signals(t, x, p), dtype=float).ravel()))
