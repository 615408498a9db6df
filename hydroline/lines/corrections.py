"""Modal correction factors alpha_i, beta_i of the linear friction model (model reference §2.3, M15).

Each mode of the linear-friction line (M7) solves ``s^2 + (32 nu beta/(d^2 alpha)) s +
omega_i^2/alpha^2 = 0``. Matching that root to the root ``s_i`` of the dissipative model
(M6) on the same modal line ``Gamma(s_i) = j theta_i`` gives::

    alpha_i = omega_i/|s_i|,   beta_i = -2 Re(s_i) d^2 alpha_i/(32 nu)          (M15)

with ``theta_i = (i - 1/2) pi`` for the PQ/QP forms (cosh Gamma = 0) and ``theta_k = k pi``
for the PP/QQ forms (sinh Gamma = 0), ``omega_i = theta_i c/L``. The roots are found by
Newton's method on ``Gamma(s)^2 + theta^2 = 0`` (analytic in s), starting from the linear
friction root with alpha = beta = 1 and continued from the previous mode.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..cache import source_tag
from .memo import LineMemo, kept_in_memory
from .line import Line, bessel_ratio, check_form

__all__ = ["correction_factors", "modal_angles", "dissipative_root", "dissipative_roots",
           "check_modes", "kept_in_memory"]

#: Correction factors of the lines met in this process and on disk, key -> (alpha, beta)
_FACTORS = LineMemo("correction_factors")


def modal_angles(n_modes: int, form: str = "PQ") -> np.ndarray:
    """Modal angles theta_i of modes 1..n: (i - 1/2) pi for PQ/QP, i pi for PP/QQ.

    Parameters
    ----------
    n_modes : int
        Number of modes, >= 1.
    form : str
        Causal form "PQ", "QP" (cosh Gamma = 0 modes) or "PP", "QQ" (sinh Gamma = 0).

    Returns
    -------
    ndarray
        theta_1 ... theta_n, [rad]; the undamped modal frequencies are theta_i c/L (M9).

    Examples
    --------
    >>> import numpy as np
    >>> modal_angles(3, "PQ") / np.pi
    array([0.5, 1.5, 2.5])
    >>> modal_angles(3, "PP") / np.pi
    array([1., 2., 3.])
    """
    n_modes = check_modes(n_modes)
    form = check_form(form)
    i = np.arange(1, n_modes + 1, dtype=float)
    return (i - 0.5) * np.pi if form in ("PQ", "QP") else i * np.pi


def check_modes(n_modes) -> int:
    """A number of modes as an int, or ValueError naming ``n_modes``.

    Parameters
    ----------
    n_modes : int
        Number of modes, an integer >= 1.

    Returns
    -------
    int
        ``n_modes``.

    Raises
    ------
    ValueError
        If it is not a whole number >= 1.
    """
    if int(n_modes) != n_modes or n_modes < 1:
        raise ValueError(f"n_modes must be an integer >= 1, got {n_modes!r}")
    return int(n_modes)




def _gamma_squared(line: Line, s):
    """Gamma(s)^2 of the dissipative model (M6), analytic in s off the negative real axis."""
    kappa = line.radius * np.sqrt(s / line.fluid.kinematic_viscosity)
    g = (s * line.wave_time) ** 2 * bessel_ratio(kappa)
    return g * line.wall_factor(s) if line.viscoelastic else g      # (M44)


def dissipative_root(line: Line, theta: float, guess: complex | None = None,
                     tol: float = 1e-13, max_iter: int = 100) -> complex:
    """Root s (upper half plane) of ``Gamma_dissipative(s) = j theta`` (M6).

    Newton's method on ``Gamma(s)^2 + theta^2 = 0``, damped so that no step is longer than
    half the distance to the origin.

    Parameters
    ----------
    line : Line
        The line.
    theta : float
        Modal angle, (i - 1/2) pi or k pi (see :func:`modal_angles`), [rad].
    guess : complex or None
        Starting point, [1/s]; from the linear friction model (alpha = beta = 1) when None.
    tol : float
        Relative step size at which the iteration stops, [-].
    max_iter : int
        Largest number of Newton steps.

    Returns
    -------
    complex
        The root s_i: ``abs(s_i)`` is the mode's natural frequency and ``-Re(s_i)`` its decay
        rate, [1/s].

    Raises
    ------
    ValueError
        If the mode is overdamped (the root leaves the upper half plane), which happens only
        for very viscous, long, narrow lines (Dn of order 1).
    RuntimeError
        If Newton's method does not converge in ``max_iter`` steps.
    """
    start = _linear_friction_start(line, np.array([theta])) if guess is None else [guess]
    roots, converged = _newton_roots(line, np.array([theta], dtype=float), start, tol, max_iter)
    if not converged:
        raise RuntimeError(f"root of mode theta={theta:.4g} did not converge (line {line})")
    s = complex(roots[0])
    if s.imag <= 1e-9 * abs(s) or s.real >= 0:
        raise ValueError(
            f"mode with theta={theta:.4g} of this line is overdamped or unresolved "
            f"(Dn = {line.dissipation_number:.3g}); modal corrections need Dn well below 1")
    return s


def _linear_friction_start(line: Line, thetas: np.ndarray) -> np.ndarray:
    """Newton's start for the roots of modal angles ``thetas``: the linear friction model's
    (alpha = beta = 1), kept off the real axis, [1/s]."""
    omega = thetas / line.wave_time
    a = 16.0 * line.fluid.kinematic_viscosity / line.diameter**2
    return -a + 1j * np.sqrt(np.maximum(omega**2 - a**2, (0.1 * omega) ** 2))


def _newton_roots(line: Line, thetas: np.ndarray, start, tol: float, max_iter: int):
    """Damped Newton on ``Gamma(s)^2 + theta^2 = 0`` (M6) for every modal angle at once:
    central-difference derivative, no step longer than half the distance to the origin, a
    mode done when its step is below ``tol`` of |s|. Returns (roots [1/s], whether every
    mode converged within ``max_iter`` steps)."""
    s = np.array(start, dtype=complex)
    target = -thetas**2
    active = np.arange(s.size)
    for _ in range(max_iter):
        sa = s[active]
        m = sa.size
        h = 1e-7 * np.abs(sa)
        g = _gamma_squared(line, np.concatenate((sa, sa + h, sa - h)))
        step = (g[:m] - target[active]) / ((g[m:2 * m] - g[2 * m:]) / (2 * h))
        limit = 0.5 * np.abs(sa)
        long = np.abs(step) > limit
        step[long] *= limit[long] / np.abs(step[long])
        sa = sa - step
        s[active] = sa
        active = active[~(np.abs(step) < tol * np.abs(sa))]
        if active.size == 0:
            return s, True
    return s, False


def dissipative_roots(line: Line, thetas, tol: float = 1e-13, max_iter: int = 100):
    """Roots s_i of ``Gamma_dissipative(s) = j theta_i`` (M6) of several modes at once.

    The iteration of :func:`dissipative_root` (damped Newton on ``Gamma(s)^2 + theta^2 = 0``,
    central-difference derivative, same stopping rule), run on every mode together from its
    own linear-friction start (alpha = beta = 1): one Bessel evaluation of all modes per
    step instead of three per mode and step.

    Parameters
    ----------
    line : Line
        The line.
    thetas : array_like
        Modal angles, [rad] (see :func:`modal_angles`).
    tol : float
        Relative step size at which a mode's iteration stops, [-].
    max_iter : int
        Largest number of Newton steps.

    Returns
    -------
    complex ndarray or None
        The roots, [1/s]; None where some mode did not converge within ``max_iter`` steps
        or left the upper half plane (:func:`correction_factors` then solves mode by mode,
        which says why).
    """
    thetas = np.asarray(thetas, dtype=float)
    s, converged = _newton_roots(line, thetas, _linear_friction_start(line, thetas), tol,
                                 max_iter)
    if not converged:
        return None
    if np.any(s.imag <= 1e-9 * np.abs(s)) or np.any(s.real >= 0) or not np.all(np.isfinite(s)):
        return None
    return s


def correction_factors(line: Line, n_modes: int, form: str = "PQ"):
    """Correction factors alpha_i, beta_i (M15) of modes 1..n_modes.

    Parameters
    ----------
    line : Line
        The line (geometry, fluid, effective bulk modulus).
    n_modes : int
        Number of modes, >= 1.
    form : str
        Causal form; PQ/QP use the cosh Gamma = 0 modes, PP/QQ the sinh Gamma = 0 modes.

    Returns
    -------
    alpha : ndarray
        Frequency factors of modes 1..n, shape (n_modes,), [-].
    beta : ndarray
        Damping factors of modes 1..n, shape (n_modes,), [-].

    Examples
    --------
    The worked example of the model reference (§2.3): d = 19 mm, nu = 3.2e-5 m^2/s,
    c = 488 m/s, L = 3.048 m (first mode at 40 Hz, dimensionless frequency about 700):

    >>> from hydroline import Fluid
    >>> from hydroline.lines import Line
    >>> line = Line(3.048, 0.019, Fluid(870.0, 3.2e-5, 1.5e9), bulk_modulus=870.0 * 488.0**2)
    >>> alpha, beta = correction_factors(line, 6)
    >>> print(f"alpha_1 = {alpha[0]:.3f}, beta_1 = {beta[0]:.2f}")
    alpha_1 = 1.027, beta_1 = 4.97
    >>> print(f"alpha_6 = {alpha[5]:.3f}, beta_6 = {beta[5]:.2f}")
    alpha_6 = 1.008, beta_6 = 15.87
    """
    n_modes, form = check_modes(n_modes), check_form(form)
    # a pure function of these numbers, kept in this process and on disk: a later build of
    # the same line skips the root finding
    key = (f"{_SOURCE_TAG}|{form}|{n_modes}|{line.length!r}|{line.diameter!r}|"
           f"{line.fluid.kinematic_viscosity!r}|{line.wave_time!r}")

    def decode(stored):
        if len(stored) != 2 or not all(len(v) == n_modes for v in stored):
            return None
        return np.array(stored[0], dtype=float), np.array(stored[1], dtype=float)

    alphas, betas = _FACTORS.get(key, lambda: _solve_correction_factors(line, n_modes, form),
                                 lambda v: [v[0].tolist(), v[1].tolist()], decode)
    return alphas.copy(), betas.copy()


_SOURCE_TAG = source_tag(__file__, Path(__file__).with_name("line.py"),
                         Path(__file__).with_name("bessel.py"))


def _solve_correction_factors(line: Line, n_modes: int, form: str):
    """alpha_i, beta_i (M15) by root matching, modes 1..n_modes: every mode at once
    (:func:`dissipative_roots`), else mode by mode, each continued from the previous root."""
    thetas = modal_angles(n_modes, form)
    nu, d = line.fluid.kinematic_viscosity, line.diameter
    roots = dissipative_roots(line, thetas)
    if roots is not None:
        alphas = thetas / line.wave_time / np.abs(roots)
        return alphas, -2.0 * roots.real * d**2 * alphas / (32.0 * nu)
    alphas, betas, roots = [], [], []
    guess = None
    for k, theta in enumerate(thetas):
        if roots and len(roots) >= 1:
            # continue from the previous root, scaled to the next modal frequency
            prev = roots[-1]
            ratio = theta / thetas[k - 1]
            guess = complex(prev.real * np.sqrt(ratio), prev.imag * ratio)
        s = dissipative_root(line, theta, guess)
        roots.append(s)
        omega = theta / line.wave_time
        alpha = omega / abs(s)
        alphas.append(alpha)
        betas.append(-2.0 * s.real * d**2 * alpha / (32.0 * nu))
    return np.array(alphas), np.array(betas)
