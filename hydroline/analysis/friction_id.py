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
   per direction; C_s minimises the total residual (variable projection). Without points at
   speeds near C_s, F_s and C_s are not identifiable; the result says so.

Data come as :class:`~hydroline.analysis.fit.Measurements` (CSV columns of
:mod:`hydroline.analysis.fit`): ``time``, ``piston_position``, ``bottom_chamber_pressure``,
``top_chamber_pressure``; optional ``piston_velocity``, ``external_force``, ``valve_current``.
:func:`virtual_friction_tests` makes such records with the model itself (for checking).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .. import components as comp
from ..rigs import Rig, load_rig
from ..simulation import integrate
from ..system import build_network
from .fit import DataError, Measurements
from .linearize import OperatingPoint, _transfer_state, solve_operating_point

__all__ = ["newton_friction", "steady_velocity_point", "StribeckFit", "fit_stribeck",
           "FrictionIdentification", "identify_friction", "virtual_friction_tests",
           "FRICTION_COLUMNS"]

#: Columns friction identification needs.
FRICTION_COLUMNS = ("time", "piston_position", "bottom_chamber_pressure", "top_chamber_pressure")


def _areas(rig):
    area = rig.get("actuator.area")
    return rig.get("actuator.bottom_area", area), rig.get("actuator.top_area", area)


def newton_friction(meas: Measurements, rig: Rig, window: float = 2e-3,
                    stop_margin: float = 1e-3) -> pd.DataFrame:
    """Friction force on the piston from Newton's law (M23), sample by sample.

    Parameters
    ----------
    meas : Measurements   Record with the columns of :data:`FRICTION_COLUMNS`
    rig : Rig             Areas, moving mass, gravity, load
    window : float        Savitzky-Golay window of the derivatives, [s]: short enough to
                          follow the actuator's resonance after a friction reversal (1-2 ms
                          at 172 Hz), long enough to tame the noise of a measured position
    stop_margin : float   Samples closer than this to an end stop are dropped, [m]

    Returns
    -------
    pandas.DataFrame  columns time [s], velocity [m/s], acceleration [m/s^2],
    friction_force [N] (opposing +v when > 0), on a uniform time grid
    """
    from scipy.signal import savgol_filter

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
    else:
        v = savgol_filter(x, n_win, 3, deriv=1, delta=dt)
        a = savgol_filter(x, n_win, 3, deriv=2, delta=dt)
    Ab, At = _areas(rig)
    m = rig["actuator.moving_mass"] + rig.get("load.mass", 0.0)
    g = rig.get("actuator.gravity", 9.81)
    if "external_force" in meas.data:
        f_load = col("external_force")
    else:
        f_load = (rig.get("load.stiffness", 0.0) * (x - rig.get("load.free_position", 0.0))
                  + rig.get("load.damping", 0.0) * v + rig.get("load.applied_force", 0.0))
    F = Ab * col("bottom_chamber_pressure") - At * col("top_chamber_pressure") - f_load - m * g - m * a
    half = rig["actuator.stroke"] / 2
    keep = np.abs(x) < half - stop_margin
    keep[: n_win // 2] = False
    keep[len(keep) - n_win // 2:] = False
    return pd.DataFrame({"time": tu[keep], "velocity": v[keep], "acceleration": a[keep],
                         "friction_force": F[keep]})


def steady_velocity_point(nf: pd.DataFrame, tolerance: float = 0.02, min_samples: int = 20):
    """One (velocity, friction) point from an open-loop run at constant valve current.

    The steady velocity is the median velocity over the second half of the moving samples;
    the point averages the samples within ``tolerance`` (relative) of it.

    Parameters
    ----------
    nf : DataFrame        From :func:`newton_friction`
    tolerance : float     Relative velocity band of the steady part, [-]
    min_samples : int     Fewest samples for a point

    Returns
    -------
    (velocity [m/s], friction force [N], samples used) or None when there is no steady part
    """
    v, F = nf["velocity"].to_numpy(), nf["friction_force"].to_numpy()
    if len(v) < min_samples:
        return None
    v_ss = float(np.median(v[len(v) // 2:]))
    if v_ss == 0:
        return None
    sel = np.abs(v - v_ss) <= tolerance * abs(v_ss)
    # keep only the last contiguous run of steady samples (after the start-up transient)
    idx = np.flatnonzero(sel)
    if idx.size < min_samples:
        return None
    breaks = np.flatnonzero(np.diff(idx) > 1)
    start = idx[breaks[-1] + 1] if breaks.size else idx[0]
    seg = idx[idx >= start]
    if seg.size < min_samples:
        seg = idx
    return float(np.mean(v[seg])), float(np.mean(F[seg])), int(seg.size)


@dataclass
class StribeckFit:
    """(M24) coefficients fitted up (+) and down (-) separately.

    Attributes
    ----------
    viscous_up, viscous_down : float    F_v+-, [N s/m]
    coulomb_up, coulomb_down : float    F_c+-, [N]
    static_up, static_down : float      F_s+-, [N]
    stribeck_velocity : float           C_s, [m/s]
    stribeck_exponent : float           delta, [-] (held)
    static_identified : bool            Points near C_s were there to pin F_s and C_s
    rms_up, rms_down : float            rms residual per direction, [N]
    n_up, n_down : int                  Points per direction
    std : dict                          Standard errors of the linear coefficients, [SI]
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

    def force(self, v):
        """Friction force of the fitted (M24) at velocity v [m/s] (sgn, not regularised), [N]."""
        v = np.asarray(v, dtype=float)
        up = v > 0
        fv = np.where(up, self.viscous_up, self.viscous_down)
        fc = np.where(up, self.coulomb_up, self.coulomb_down)
        fs = np.where(up, self.static_up, self.static_down)
        e = np.exp(-(np.abs(v) / self.stribeck_velocity) ** self.stribeck_exponent)
        return fv * v + np.sign(v) * (fc + (fs - fc) * e)

    def rig_values(self) -> dict:
        """Rig paths -> values [SI] (``friction.*``); static terms only when identified."""
        out = {f"friction.{k}": getattr(self, k) for k in (
            "viscous_up", "viscous_down", "coulomb_up", "coulomb_down")}
        if self.static_identified:
            out.update({"friction.static_up": self.static_up, "friction.static_down": self.static_down,
                        "friction.stribeck_velocity": self.stribeck_velocity})
        return out

    def apply(self, rig: Rig) -> Rig:
        """A copy of the rig with the fitted coefficients (units written out)."""
        from ..rigs import SCHEMA

        out = rig.copy()
        for path, v in self.rig_values().items():
            out.set(path, f"{float(v)!r} {SCHEMA['friction'][path.split('.')[1]]}")
        return out


def _basis(v, cs, delta, sign):
    e = np.exp(-(np.abs(v) / cs) ** delta)
    return np.column_stack([v, sign * (1.0 - e), sign * e]), e


def _direction(v, F, cs, delta, sign):
    from scipy.optimize import nnls

    X, e = _basis(v, cs, delta, sign)
    if len(v) == 0:
        return np.zeros(3), 0.0, e, X
    coef, rnorm = nnls(X, F)
    return coef, rnorm**2, e, X


def fit_stribeck(v, F, stribeck_exponent: float = 2.0, stribeck_velocity: float | None = None,
                 min_speed: float = 2e-4) -> StribeckFit:
    """Fit (M24) to friction points, up and down separately (module docstring).

    Parameters
    ----------
    v : array_like                 Piston velocities, [m/s]
    F : array_like                 Friction forces, opposing +v when > 0, [N]
    stribeck_exponent : float      delta, held, [-]
    stribeck_velocity : float      C_s [m/s]; fitted (common to both directions) when None
    min_speed : float              Points slower than this are dropped (stick), [m/s]

    Returns
    -------
    StribeckFit
    """
    from scipy.optimize import minimize_scalar

    v, F = np.asarray(v, dtype=float), np.asarray(F, dtype=float)
    ok = np.isfinite(v) & np.isfinite(F) & (np.abs(v) >= min_speed)
    v, F = v[ok], F[ok]
    up, down = v > 0, v < 0
    if up.sum() < 2 or down.sum() < 2:
        raise ValueError(f"friction fit needs at least 2 points moving up and 2 moving down "
                         f"faster than {min_speed:g} m/s (got {int(up.sum())} up, {int(down.sum())} down)")

    def total(log_cs):
        cs = np.exp(log_cs)
        return (_direction(v[up], F[up], cs, stribeck_exponent, 1.0)[1]
                + _direction(v[down], F[down], cs, stribeck_exponent, -1.0)[1])

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
    res = {}
    std = {}
    for name, sel, sign in (("up", up, 1.0), ("down", down, -1.0)):
        coef, ssr, e, X = _direction(v[sel], F[sel], cs, stribeck_exponent, sign)
        n = int(sel.sum())
        rms = float(np.sqrt(ssr / max(n, 1)))
        try:
            cov = ssr / max(n - 3, 1) * np.linalg.inv(X.T @ X)
            sd = np.sqrt(np.clip(np.diag(cov), 0, np.inf))
        except np.linalg.LinAlgError:
            sd = np.full(3, np.inf)
        res[name] = (coef, rms, n, e)
        std.update({f"viscous_{name}": float(sd[0]), f"coulomb_{name}": float(sd[1]),
                    f"static_{name}": float(sd[2])})
    # F_s and C_s are pinned only by points where the Stribeck term is neither ~1 nor ~0,
    # and mean something only where the fit finds a hump (F_s above F_c by > 5 % and 2 sigma)
    e_all = np.concatenate([res["up"][3], res["down"][3]])
    (cu, ru, nu, _), (cd, rd, nd, _) = res["up"], res["down"]
    hump = any(c[2] - c[1] > max(0.05 * c[1], 2 * std[f"static_{k}"])
               for k, c in (("up", cu), ("down", cd)))
    identified = bool(np.sum((e_all > 0.05) & (e_all < 0.95)) >= 2 and hump)
    return StribeckFit(cu[0], cd[0], cu[1], cd[1], cu[2], cd[2], cs, stribeck_exponent, identified,
                       ru, rd, nu, nd, std)


@dataclass
class FrictionIdentification:
    """Friction points and the fitted (M24).

    Attributes
    ----------
    points : dict   Label -> (velocity [m/s], friction force [N]) arrays
    fit : StribeckFit
    """

    points: dict
    fit: StribeckFit


def identify_friction(rig: Rig | str | None, steady=(), sine=(), window: float = 2e-3,
                      min_speed: float = 2e-4, stribeck_exponent: float | None = None,
                      sine_min_speed: float = 0.02) -> FrictionIdentification:
    """Friction from steady-velocity open-loop runs and closed-loop sine records.

    Parameters
    ----------
    rig : Rig, str or None            Areas, mass, load (and delta of M24)
    steady : list[Measurements]       Open-loop runs at constant current, one point each
    sine : list[Measurements]         Closed-loop sine records, every moving sample a point
    window : float                    Derivative window, [s]
    min_speed : float                 Slowest point used in the fit, [m/s]
    stribeck_exponent : float         delta [-]; the rig's when None
    sine_min_speed : float            Slowest sine sample used: near reversal the piston
                                      sticks and Newton's law gives the applied force, [m/s]

    Returns
    -------
    FrictionIdentification
    """
    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    points = {}
    vs, Fs = [], []
    for meas in steady:
        pt = steady_velocity_point(newton_friction(meas, rig, window))
        if pt is not None:
            vs.append(pt[0])
            Fs.append(pt[1])
    if vs:
        points["steady-velocity open-loop runs"] = (np.array(vs), np.array(Fs))
    sv, sF = [], []
    for meas in sine:
        nf = newton_friction(meas, rig, window)
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
    delta = rig.get("friction.stribeck_exponent", 2.0) if stribeck_exponent is None else stribeck_exponent
    return FrictionIdentification(points, fit_stribeck(v, F, delta, None, min_speed))


def _record(res, columns=("valve_current", "supply_port_pressure", "return_port_pressure",
                          "bottom_chamber_pressure", "top_chamber_pressure", "piston_position")):
    data = {"time": res.t}
    data.update({c: res[c] for c in columns if c in res.data})
    return pd.DataFrame(data)


def virtual_friction_tests(rig: Rig | str | None = None, currents=None, t_run: float = 0.12,
                           sine: bool = True, dt: float = 1e-4):
    """The paper's friction experiments run on the model itself (to check the identification).

    Open-loop runs: the piston held at -40 mm (up runs) or +40 mm (down runs) by its holding
    current, then the current steps by each value of ``currents`` at 5 ms and the run lasts
    ``t_run`` or until the piston nears its stop. Closed-loop sine: the rig's
    ``closed-loop-sine`` scenario (the paper's 2 Hz, 35 mm under P control).

    Parameters
    ----------
    rig : Rig, str or None
    currents : list[float]   Current steps [A]; +-(0.3, 1, 3, 10, 25) % of rated when None
    t_run : float            Longest run, [s]
    sine : bool              Also run the closed-loop sine
    dt : float               Sampling interval, [s]

    Returns
    -------
    (steady, sine) : lists of Measurements
    """
    from ..scenarios import simulate

    rig = rig if isinstance(rig, Rig) else load_rig(rig)
    i_r = rig["servovalve.rated_current"]
    if currents is None:
        currents = [s * f * i_r for f in (0.003, 0.01, 0.03, 0.1, 0.25) for s in (1, -1)]
    steady = []
    half = rig["actuator.stroke"] / 2
    for di in currents:
        x0 = -0.04 if di > 0 else 0.04
        hold = solve_operating_point(rig, OperatingPoint(piston_position=x0))
        i0 = hold.valve_current
        cmd = comp.StepCommand(name="command", initial=i0, final=i0 + di, time=5e-3,
                               connections={"command": "valve_current"})
        net = build_network(rig, [cmd], x0)
        x, p = _transfer_state(hold, net)
        p[net.parameter_names.index("command.initial")] = i0
        p[net.parameter_names.index("command.final")] = i0 + di
        res = integrate(net, x, t_run, dt_out=dt, p=p)
        df = _record(res)
        near = np.flatnonzero(np.abs(df["piston_position"].to_numpy()) > half - 2e-3)
        if near.size:
            df = df.iloc[:max(int(near[0]), 10)]
        steady.append(Measurements(df, f"virtual open-loop run, {di * 1e3:+.3g} mA"))
    sines = []
    if sine:
        res = simulate(rig, "closed-loop-sine", dt_out=dt)
        sines.append(Measurements(_record(res), "virtual closed-loop sine"))
    return steady, sines
