"""Friction identification as the 2005 paper did it: Newton's law on measured traces, (M24) fit.

1. **Friction force by Newton's law** (M23) from the measured chamber pressures and piston
   position: ``F_f = A_b p_b - A_t p_t - F_load - m_p g - m_p a`` with the piston velocity
   ``v`` and acceleration ``a`` from a Savitzky-Golay derivative of the position (cubic,
   over 2 ms by default; noisy data need longer) and the load force from the rig's load
   (spring, damper, applied force) or a measured ``external_force`` column. Samples near
   the end stops are dropped.
2. **Steady-velocity open-loop runs** (constant valve current): each run gives one point,
   the mean friction force over the part of the run where the velocity is steady.
   **Closed-loop sine** (the paper's 2 Hz, 35 mm tracking under P control): every sample
   moving faster than ``sine_min_speed`` gives a point; the acceleration term matters here,
   and near each reversal (friction flips, the actuator rings) the derivatives lag, so the
   slowest sine points scatter -- as the paper's did.
3. **(M24) fitted up and down separately**: ``F = F_v v + sgn(v) (F_c + (F_s - F_c)
   exp(-(|v|/C_s)^delta))`` with its own ``F_v, F_c, F_s`` for v > 0 and v < 0 and a common
   Stribeck velocity C_s (one value in the rig, as in (M24)) and exponent delta (held). For
   a given C_s the model is linear in the coefficients, solved by non-negative least squares
   per direction, each steady point weighted by the samples it averages; C_s minimises the
   total residual (variable projection). F_s and C_s are identifiable only from steady points
   slower than about 2 C_s in both directions (a sine's samples there are reversals, and a
   fit to faster points hangs the hump on their ripple): ``static_identified`` is False
   without them, or when the standard error of F_s is not well below the hump F_s - F_c,
   and the rig's values are kept.
4. **Slow runs**: below ~2 C_s (M24)'s friction falls with speed, faster than the viscous
   term and the valve's pressure-flow slope damp, and an open-loop run stick-slips instead of
   settling (the default rig does at 0.1-0.2 mA). A viscous damper specimen, its
   force measured (``external_force``), restores a steady velocity there;
   :func:`hydroline.studies.friction_tests.virtual_friction_tests` does so.

Data come as :class:`~hydroline.analysis.fit.Measurements` (CSV columns of
:mod:`hydroline.analysis.fit`): ``time``, ``piston_position``, ``bottom_chamber_pressure``,
``top_chamber_pressure``; optional ``piston_velocity``, ``external_force``, ``valve_current``.
:func:`hydroline.studies.friction_tests.virtual_friction_tests` makes such records with the model itself (for checking).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .. import components as comp
from ..rigs import Rig, load_rig
from ..system import build_circuit
from .fit import DataError, Measurements, noise_level
from .linearize import select_axis

__all__ = ["newton_friction", "steady_velocity_point", "StribeckFit", "fit_stribeck",
           "FrictionIdentification", "identify_friction", "axis_mechanics", "friction_table",
           "FRICTION_UNITS",
           "FRICTION_COLUMNS"]

#: Columns friction identification needs.
FRICTION_COLUMNS = ("time", "piston_position", "bottom_chamber_pressure", "top_chamber_pressure")


@dataclass
class AxisMechanics:
    """What Newton's law (M23) on one axis's piston needs, from its components.

    Attributes
    ----------
    bottom_area, top_area : float
        A_b, A_t, [m^2]
    mass : float
        Moving mass, actuator and load, [kg]
    gravity : float
        g along the axis (0: horizontal), [m/s^2]
    stroke : float
        Full stroke, [m]
    load : Load or None
        The load on the piston (stiffness, damping, applied force)
    stribeck_exponent : float
        delta of (M24) of the axis's friction, [-]
    """

    bottom_area: float
    top_area: float
    mass: float
    gravity: float
    stroke: float
    load: object
    stribeck_exponent: float

    def load_force(self, x, v):
        """The load's force on the piston, positive down, [N] (M23).

        Parameters
        ----------
        x : array
            Piston position, [m]
        v : array
            Piston velocity, [m/s]

        Returns
        -------
        ndarray
            Load force, positive down, [N]
        """
        ld = self.load
        if ld is None:
            return np.zeros_like(x)
        return ld.stiffness * (x - ld.free_position) + ld.damping * v + ld.applied_force


def axis_mechanics(rig: Rig, axis: str | None = None) -> AxisMechanics:
    """The piston mechanics of one servo axis of a rig (its actuator, load and friction).

    Parameters
    ----------
    rig : Rig
        Parameters (SI)
    axis : str
        The axis (None: the first)

    Returns
    -------
    AxisMechanics
        Areas, moving mass, gravity, stroke and load of the axis.
    """
    ax = select_axis(rig, axis)
    circuit = build_circuit(rig)
    act = circuit.component(ax.actuator)
    load = next((c for c in circuit.components if isinstance(c, comp.Load)
                 and c.signal("load_force") == act.signal("load_force")), None)
    fr = circuit.component(ax.friction) if ax.friction else None
    return AxisMechanics(act.bottom_area, act.top_area,
                         act.moving_mass + (load.mass if load is not None else 0.0), act.gravity,
                         act.stroke, load, fr.stribeck_exponent if fr is not None else 2.0)


def newton_friction(meas: Measurements, rig: Rig, window: float = 2e-3,
                    stop_margin: float = 1e-3, axis: str | None = None,
                    mechanics: AxisMechanics | None = None) -> pd.DataFrame:
    """Friction force on the piston from Newton's law (M23), sample by sample.

    Parameters
    ----------
    meas : Measurements
        Record with the columns of :data:`FRICTION_COLUMNS`
    rig : Rig
        Areas, moving mass, gravity, load
    window : float
        Savitzky-Golay window of the derivatives, [s]: short enough to
        follow the actuator's resonance after a friction reversal (1-2 ms
        at 172 Hz), long enough to tame the noise of a measured position
    stop_margin : float
        Samples closer than this to an end stop are dropped, [m]
    axis : str
        The axis the record is of (None: the first)
    mechanics : AxisMechanics
        The axis's mechanics (from ``rig`` and ``axis`` when None)

    Returns
    -------
    pandas.DataFrame
        Columns ``time`` [s], ``velocity`` [m/s], ``acceleration`` [m/s^2] and
        ``friction_force`` [N] (opposing +v when > 0), on a uniform time grid; ``attrs`` hold
        the white-noise level of the position (or measured velocity), ``signal_noise``, and
        the filter that maps it into the velocity, ``velocity_filter`` (for
        :func:`steady_velocity_point`).
    """
    from scipy.signal import savgol_coeffs, savgol_filter

    for c in FRICTION_COLUMNS:
        if c not in meas.data:
            raise DataError(f"{meas.source}: friction identification needs column "
                            f"'{c} [{'s' if c == 'time' else 'm' if c == 'piston_position' else 'Pa'}]'")
    t = meas.t
    dt = float(np.median(np.diff(t)))
    tu = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)

    def col(name):
        return np.interp(tu, t, meas.data[name].to_numpy())

    n_win = max(5, int(round(window / dt)) | 1)
    if n_win > len(tu):
        raise DataError(f"{meas.source}: record too short ({len(tu)} samples) for a "
                        f"{window * 1e3:g} ms derivative window")
    x = col("piston_position")
    if "piston_velocity" in meas.data:
        v = col("piston_velocity")
        a = savgol_filter(v, n_win, 3, deriv=1, delta=dt)
        noise, h = noise_level(v), np.ones(1)
    else:
        v = savgol_filter(x, n_win, 3, deriv=1, delta=dt)
        a = savgol_filter(x, n_win, 3, deriv=2, delta=dt)
        noise, h = noise_level(x), savgol_coeffs(n_win, 3, deriv=1, delta=dt)
    mech = mechanics or axis_mechanics(rig, axis)
    Ab, At, m, g = mech.bottom_area, mech.top_area, mech.mass, mech.gravity
    f_load = col("external_force") if "external_force" in meas.data else mech.load_force(x, v)
    F = Ab * col("bottom_chamber_pressure") - At * col("top_chamber_pressure") - f_load - m * g - m * a
    half = mech.stroke / 2
    keep = np.abs(x) < half - stop_margin
    keep[: n_win // 2] = False
    keep[len(keep) - n_win // 2:] = False
    out = pd.DataFrame({"time": tu[keep], "velocity": v[keep], "acceleration": a[keep],
                        "friction_force": F[keep]})
    # white noise on the measured signal and the filter that maps it into the velocity
    out.attrs.update(signal_noise=noise, velocity_filter=h, window_samples=n_win)
    return out


def steady_velocity_point(nf: pd.DataFrame, tolerance: float = 0.02, min_samples: int = 20,
                          max_spread: float = 0.5, min_fraction: float = 0.25):
    """One (velocity, friction) point from an open-loop run at constant valve current.

    The steady velocity v_ss is the median velocity over the second half of the moving
    samples. The velocity is smoothed by a moving average over four derivative windows; the
    steady part is every sample after the last one whose smoothed velocity strays from v_ss
    by more than ``max(tolerance |v_ss|, 4 sigma)``, sigma being the noise that the measured
    position's white noise leaves on the smoothed velocity (``nf.attrs``). The point averages
    the velocity and the friction force over all of the steady part (not only the samples that
    the noise happens to put near v_ss, which would bias nothing but waste the data).

    Parameters
    ----------
    nf : DataFrame
        From :func:`newton_friction`
    tolerance : float
        Relative velocity band of the steady part, [-]
    min_samples : int
        Fewest samples for a point
    min_fraction : float
        The steady part must be at least this fraction of the record (a
        stick-slip run passes through v_ss only briefly), [-]
    max_spread : float
        No point when 4 sigma exceeds this fraction of ``|v_ss|``: the noise
        would hide a stick-slip run (use a longer derivative window), [-]

    Returns
    -------
    tuple or None
        ``(velocity [m/s], friction force [N], samples used)``, or None when there is no
        steady part.
    """
    v, F = nf["velocity"].to_numpy(), nf["friction_force"].to_numpy()
    if len(v) < min_samples:
        return None
    v_ss = float(np.median(v[len(v) // 2:]))
    if v_ss == 0:
        return None
    n_win = int(nf.attrs.get("window_samples", 1))
    L = int(max(1, min(4 * n_win, len(v) // 4)))
    box = np.ones(L) / L
    vs = np.convolve(v, box, mode="same")
    h = np.asarray(nf.attrs.get("velocity_filter", np.ones(1)), dtype=float)
    sigma = float(nf.attrs.get("signal_noise", 0.0)) * float(np.linalg.norm(np.convolve(h, box)))
    if 4 * sigma > max_spread * abs(v_ss):
        return None
    band = max(tolerance * abs(v_ss), 4 * sigma)
    inner = slice(L // 2, len(v) - (L - 1) // 2)      # where the moving average is complete
    out = np.flatnonzero(np.abs(vs[inner] - v_ss) > band) + inner.start
    start = int(out[-1]) + 1 if out.size else inner.start
    seg = np.arange(start, len(v))
    if seg.size < max(min_samples, min_fraction * len(v)):
        return None
    return float(np.mean(v[seg])), float(np.mean(F[seg])), int(seg.size)


@dataclass
class StribeckFit:
    """(M24) coefficients fitted up (+) and down (-) separately.

    Attributes
    ----------
    viscous_up, viscous_down : float
        F_v+-, [N s/m]
    coulomb_up, coulomb_down : float
        F_c+-, [N]
    static_up, static_down : float
        F_s+-, [N]
    stribeck_velocity : float
        C_s, [m/s]
    stribeck_exponent : float
        delta, [-] (held)
    static_identified : bool
        Slow steady-velocity points pinned F_s and C_s (see
        :func:`fit_stribeck`); when False the rig's values stand
    rms_up, rms_down : float
        rms residual per direction, [N]
    n_up, n_down : int
        Points per direction
    std : dict
        Standard errors, [SI]: coefficients (``viscous_up``, ...)
        and ``stribeck_velocity`` (0 when held)
    static_note : str
        Why F_s, C_s are not identified ("" when they are)
    """

    viscous_up: float
    viscous_down: float
    coulomb_up: float
    coulomb_down: float
    static_up: float
    static_down: float
    stribeck_velocity: float
    stribeck_exponent: float
    static_identified: bool
    rms_up: float
    rms_down: float
    n_up: int
    n_down: int
    std: dict = field(default_factory=dict)
    static_note: str = ""

    def force(self, v):
        """Friction force of the fitted (M24) at velocity v (sgn, not regularised), [N].

        Parameters
        ----------
        v : array_like
            Piston velocity, [m/s]

        Returns
        -------
        ndarray
            Friction force, opposing +v when > 0, [N]
        """
        v = np.asarray(v, dtype=float)
        up = v > 0
        fv = np.where(up, self.viscous_up, self.viscous_down)
        fc = np.where(up, self.coulomb_up, self.coulomb_down)
        fs = np.where(up, self.static_up, self.static_down)
        e = np.exp(-(np.abs(v) / self.stribeck_velocity) ** self.stribeck_exponent)
        return fv * v + np.sign(v) * (fc + (fs - fc) * e)

    def rig_values(self, prefix: str = "friction") -> dict:
        """Rig paths -> values [SI] (``<prefix>.*``); static terms only when identified.

        Parameters
        ----------
        prefix : str
            The friction's table: "friction" (template rig) or
            ``circuit.<component>`` (:func:`friction_table`)

        Returns
        -------
        dict
            Rig path -> value, [SI]
        """
        out = {f"{prefix}.{k}": getattr(self, k) for k in (
            "viscous_up", "viscous_down", "coulomb_up", "coulomb_down")}
        if self.static_identified:
            out.update({f"{prefix}.static_up": self.static_up,
                        f"{prefix}.static_down": self.static_down,
                        f"{prefix}.stribeck_velocity": self.stribeck_velocity})
        return out

    def apply(self, rig: Rig, prefix: str = "friction") -> Rig:
        """A copy of the rig with the fitted coefficients (units written out).

        Parameters
        ----------
        rig : Rig
            The rig
        prefix : str
            The friction's table (:func:`friction_table`)

        Returns
        -------
        Rig
            The calibrated copy.
        """
        out = rig.copy()
        for path, v in self.rig_values(prefix).items():
            key = path.rsplit(".", 1)[1]
            out.set(path, f"{float(v)!r} {FRICTION_UNITS[key]}")
        return out


#: Units of the identified (M24) coefficients, [SI].
FRICTION_UNITS = {"viscous_up": "N*s/m", "viscous_down": "N*s/m", "coulomb_up": "N",
                  "coulomb_down": "N", "static_up": "N", "static_down": "N",
                  "stribeck_velocity": "m/s"}


def friction_table(rig: Rig, axis: str | None = None) -> str:
    """The rig table of an axis's friction: "friction" on the template rig, else
    ``circuit.<component>``.

    Parameters
    ----------
    rig : Rig
        The rig
    axis : str
        The axis (None: the first)

    Returns
    -------
    str
        The table's name.
    """
    ax = select_axis(rig, axis)
    if ax.friction and f"circuit.{ax.friction}.type" in rig.raw:
        return f"circuit.{ax.friction}"
    return "friction"


def _basis(v, cs, delta, sign):
    e = np.exp(-(np.abs(v) / cs) ** delta)
    return np.column_stack([v, sign * (1.0 - e), sign * e]), e


def _direction(v, F, w, cs, delta, sign):
    """Weighted non-negative least squares of one direction at a given C_s."""
    from scipy.optimize import nnls

    X, e = _basis(v, cs, delta, sign)
    if len(v) == 0:
        return np.zeros(3), 0.0, e, X
    sw = np.sqrt(w)
    coef, rnorm = nnls(X * sw[:, None], F * sw)
    return coef, rnorm**2, e, X


def fit_stribeck(v, F, stribeck_exponent: float = 2.0, stribeck_velocity: float | None = None,
                 min_speed: float = 2e-4, weights=None, steady=None,
                 hump_sigmas: float = 4.0, slow_factor: float = 2.0, min_slow: int = 2) -> StribeckFit:
    """Fit (M24) to friction points, up and down separately (module docstring).

    F_s and C_s are claimed identified (``static_identified``) only when, in each direction,

    * at least ``min_slow`` steady-velocity points move slower than ``slow_factor`` times the
      fitted C_s (where the Stribeck term of (M24) is still above exp(-4) ~ 2 % for delta = 2),
      and
    * the standard error of F_s (from the full covariance, C_s included) is below
      ``1/hump_sigmas`` of the hump F_s - F_c it is meant to measure.

    Otherwise the fit can still place a hump on whatever ripple the fast points carry (a
    closed-loop sine's at 20-60 mm/s, say) and the values mean nothing; ``static_note`` then
    says why, and :meth:`StribeckFit.rig_values` leaves the rig's F_s, C_s alone.

    Parameters
    ----------
    v : array_like
        Piston velocities, [m/s]
    F : array_like
        Friction forces, opposing +v when > 0, [N]
    stribeck_exponent : float
        delta, held, [-]
    stribeck_velocity : float
        C_s [m/s]; fitted (common to both directions) when None
    min_speed : float
        Points slower than this are dropped (stick), [m/s]
    weights : array_like
        Relative weight of each point (a steady-velocity point that
        averages n samples: n; a single sample: 1); all 1 when
        None, [-]
    steady : sequence of bool
        Which points come from steady-velocity runs (only these
        count as evidence near C_s); all when None
    hump_sigmas : float
        The hump F_s - F_c must exceed this many standard errors
        of F_s, [-]
    slow_factor : float
        "Slow" means ``|v| < slow_factor * C_s``, [-]
    min_slow : int
        Slow steady points needed per direction

    Returns
    -------
    StribeckFit
        The coefficients per direction, their standard errors and residuals.
    """
    from scipy.optimize import minimize_scalar

    v, F = np.asarray(v, dtype=float), np.asarray(F, dtype=float)
    w = np.ones_like(v) if weights is None else np.asarray(weights, dtype=float)
    st = np.ones(v.shape, dtype=bool) if steady is None else np.asarray(steady, dtype=bool)
    if not (w.shape == v.shape == F.shape == st.shape):
        raise ValueError("fit_stribeck: v, F, weights and steady must have the same length")
    ok = np.isfinite(v) & np.isfinite(F) & (np.abs(v) >= min_speed) & np.isfinite(w) & (w > 0)
    v, F, w, st = v[ok], F[ok], w[ok], st[ok]
    up, down = v > 0, v < 0
    if up.sum() < 2 or down.sum() < 2:
        raise ValueError(f"friction fit needs at least 2 points moving up and 2 moving down "
                         f"faster than {min_speed:g} m/s (got {int(up.sum())} up, {int(down.sum())} down)")
    delta = stribeck_exponent

    def total(log_cs):
        cs = np.exp(log_cs)
        return (_direction(v[up], F[up], w[up], cs, delta, 1.0)[1]
                + _direction(v[down], F[down], w[down], cs, delta, -1.0)[1])

    if stribeck_velocity is None:
        speeds = np.abs(v)
        lo, hi = np.log(max(speeds.min() / 3, 1e-6)), np.log(speeds.max())
        grid = np.linspace(lo, hi, 60)
        costs = [total(g) for g in grid]
        k = int(np.argmin(costs))
        a, b = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
        cs = float(np.exp(minimize_scalar(total, bounds=(a, b), method="bounded").x)) if b > a \
            else float(np.exp(grid[k]))
    else:
        cs = float(stribeck_velocity)
    coefs, rms, counts = {}, {}, {}
    ssr = 0.0
    for name, sel, sign in (("up", up, 1.0), ("down", down, -1.0)):
        coef, ssr_d, _, _ = _direction(v[sel], F[sel], w[sel], cs, delta, sign)
        coefs[name], counts[name] = coef, int(sel.sum())
        ssr += ssr_d
        X, _ = _basis(v[sel], cs, delta, sign)
        r = F[sel] - X @ coef
        rms[name] = float(np.sqrt(np.mean(r**2))) if r.size else 0.0
    std = _stribeck_std(v, w, coefs, cs, delta, ssr, fit_cs=stribeck_velocity is None)
    # identifiability of F_s and C_s (docstring)
    notes = []
    for name, sel in (("up", up), ("down", down)):
        slow = int(np.sum(st[sel] & (np.abs(v[sel]) < slow_factor * cs)))
        hump = coefs[name][2] - coefs[name][1]
        if slow < min_slow:
            notes.append(f"{slow} steady-velocity point{'s' if slow != 1 else ''} moving {name} "
                         f"slower than {slow_factor:g} C_s = {slow_factor * cs * 1e3:.3g} mm/s "
                         f"(need {min_slow})")
        elif not hump > hump_sigmas * std[f"static_{name}"]:
            notes.append(f"F_s {name} - F_c {name} = {hump:.3g} N is not above {hump_sigmas:g} "
                         f"standard errors of F_s ({std[f'static_{name}']:.3g} N)")
    identified = not notes
    note = ("" if identified else "static friction and Stribeck velocity not identified: "
            + "; ".join(notes))
    cu, cd = coefs["up"], coefs["down"]
    return StribeckFit(cu[0], cd[0], cu[1], cd[1], cu[2], cd[2], cs, delta, identified,
                       rms["up"], rms["down"], counts["up"], counts["down"], std, note)


def _stribeck_std(v, w, coefs, cs, delta, ssr, fit_cs=True):
    """Standard errors of the (M24) coefficients from the weighted least-squares covariance.

    Parameters (F_v, F_c, F_s) up, (F_v, F_c, F_s) down and, when fitted, ln C_s; the residual
    variance per unit weight is pooled over both directions. F_s and C_s are strongly
    correlated, so the C_s column matters: without it the F_s error is far too small."""
    rows = []
    for sign, sel in ((1.0, v > 0), (-1.0, v < 0)):
        X, e = _basis(v[sel], cs, delta, sign)
        c = coefs["up" if sign > 0 else "down"]
        J = np.zeros((int(sel.sum()), 7))
        cols = slice(0, 3) if sign > 0 else slice(3, 6)
        J[:, cols] = X
        # d/d ln C_s of sgn (F_s - F_c) exp(-(|v|/C_s)^delta)
        J[:, 6] = sign * (c[2] - c[1]) * e * delta * (np.abs(v[sel]) / cs) ** delta
        rows.append(J * np.sqrt(w[sel])[:, None])
    J = np.vstack(rows)
    if not fit_cs:
        J = J[:, :6]
    dof = max(J.shape[0] - J.shape[1], 1)
    names = [f"{k}_{d}" for d in ("up", "down") for k in ("viscous", "coulomb", "static")]
    # columns scaled to unit norm (their sizes differ by orders of magnitude); a column that
    # is zero (no hump: C_s has no effect) or nearly dependent gets an infinite error
    scale = np.linalg.norm(J, axis=0)
    sd = np.full(J.shape[1], np.inf)
    hump_cols = [i for i in (2, 5, 6) if i < J.shape[1]]
    live = scale > 0
    if fit_cs and not live[6]:     # no hump: F_s is not determined without C_s either
        live[hump_cols] = False
    while live.any():
        Js = J[:, live] / scale[live]
        try:
            inv = np.linalg.inv(Js.T @ Js)
        except np.linalg.LinAlgError:
            inv = None
        if inv is not None and np.linalg.cond(Js) < 1e7:
            sd[live] = np.sqrt(np.clip(np.diag(inv), 0, np.inf) * ssr / dof) / scale[live]
            break
        # ill-determined: give F_s and C_s (together: they are correlated) infinite errors
        # and the linear F_v, F_c their errors without them
        if live[hump_cols].any():
            live[hump_cols] = False
        else:
            live[np.flatnonzero(live)[-1]] = False
    std = {k: float(s) for k, s in zip(names, sd[:6])}
    std["stribeck_velocity"] = float(cs * sd[6]) if fit_cs else 0.0
    return std


@dataclass
class FrictionIdentification:
    """Friction points and the fitted (M24).

    Attributes
    ----------
    points : dict
        Label -> (velocity [m/s], friction force [N]) arrays
    fit : StribeckFit
        The fitted curve (:func:`fit_stribeck`).
    """

    points: dict
    fit: StribeckFit


def identify_friction(rig: Rig | str | None, steady=(), sine=(), window: float = 2e-3,
                      min_speed: float = 2e-4, stribeck_exponent: float | None = None,
                      sine_min_speed: float = 0.02, axis: str | None = None) -> FrictionIdentification:
    """Friction from steady-velocity open-loop runs and closed-loop sine records.

    Parameters
    ----------
    rig : Rig, str or None
        Areas, mass, load (and delta of M24)
    steady : list[Measurements]
        Open-loop runs at constant current, one point each
    sine : list[Measurements]
        Closed-loop sine records, every moving sample a point
    window : float
        Derivative window, [s]
    min_speed : float
        Slowest point used in the fit, [m/s]
    stribeck_exponent : float
        delta [-]; the rig's when None
    sine_min_speed : float
        Slowest sine sample used: near reversal the piston
        sticks and Newton's law gives the applied force, [m/s]
    axis : str
        The axis the records are of (None: the first); its
        actuator, load and friction give the mechanics

    Returns
    -------
    FrictionIdentification
        The points and the fitted curve.

    Notes
    -----
    Each steady run's point is weighted by the samples it averages, each sine sample by 1;
    only steady points count as evidence for F_s and C_s (:func:`fit_stribeck`): a sine's
    samples near C_s are reversals, where Newton's law lags.
    """
    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    mech = axis_mechanics(rig, axis)
    points = {}
    vs, Fs, ns = [], [], []
    for meas in steady:
        pt = steady_velocity_point(newton_friction(meas, rig, window, mechanics=mech))
        if pt is not None:
            vs.append(pt[0])
            Fs.append(pt[1])
            ns.append(pt[2])
    if vs:
        points["steady-velocity open-loop runs"] = (np.array(vs), np.array(Fs))
    sv, sF = [], []
    for meas in sine:
        nf = newton_friction(meas, rig, window, mechanics=mech)
        moving = np.abs(nf["velocity"].to_numpy()) >= sine_min_speed
        sv.append(nf["velocity"].to_numpy()[moving])
        sF.append(nf["friction_force"].to_numpy()[moving])
    if sv:
        points["closed-loop sine"] = (np.concatenate(sv), np.concatenate(sF))
    if not points:
        raise ValueError("friction identification: no usable record (give steady-velocity runs "
                         "and/or a closed-loop sine)")
    v = np.concatenate([p[0] for p in points.values()])
    F = np.concatenate([p[1] for p in points.values()])
    n_sine = len(v) - len(vs)
    # a steady point averages n samples: weight n against a sine sample's 1
    weights = np.concatenate([np.asarray(ns, dtype=float), np.ones(n_sine)])
    is_steady = np.concatenate([np.ones(len(vs), dtype=bool), np.zeros(n_sine, dtype=bool)])
    delta = mech.stribeck_exponent if stribeck_exponent is None else stribeck_exponent
    return FrictionIdentification(points, fit_stribeck(v, F, delta, None, min_speed,
                                                       weights=weights, steady=is_steady))
