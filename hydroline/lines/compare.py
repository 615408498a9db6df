"""Compare a line model's frequency response with the exact dissipative model.

Used by the tests, the ``hydroline line-response`` command and the benchmarks.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from .line import FORM_PORTS

__all__ = ["Resonance", "find_resonances", "compare_resonances", "resonance_f_max"]


@dataclass
class Resonance:
    """One resonance peak of one matrix entry of both models."""

    entry: tuple[int, int]
    mode: int
    exact_frequency_hz: float
    exact_magnitude: float
    model_frequency_hz: float
    model_magnitude: float

    @property
    def frequency_error_pct(self) -> float:
        return 100.0 * (self.model_frequency_hz / self.exact_frequency_hz - 1.0)

    @property
    def magnitude_error_pct(self) -> float:
        return 100.0 * (self.model_magnitude / self.exact_magnitude - 1.0)

    def entry_name(self, form: str) -> str:
        ins, outs = FORM_PORTS[form]
        return f"{outs[self.entry[0]]}/{ins[self.entry[1]]}"


def find_resonances(response, f_max: float, entry, n_points: int = 4000, f_min: float = 0.0):
    """Peaks of ``|response(2j pi f)[..., i, j]|`` below f_max, refined by bounded search.

    Parameters
    ----------
    response : callable      s -> array s.shape + (2, 2)
    f_max : float            Upper frequency, [Hz]
    entry : (int, int)       Matrix entry (output, input)
    n_points : int           Grid points of the coarse scan

    Returns
    -------
    list of (frequency [Hz], magnitude)
    """
    i, j = entry
    f = np.linspace(max(f_min, f_max / n_points), f_max, n_points)
    mag = np.abs(response(2j * np.pi * f)[:, i, j])
    out = []
    df = f[1] - f[0]
    for k in np.flatnonzero((mag[1:-1] > mag[:-2]) & (mag[1:-1] >= mag[2:])) + 1:
        res = minimize_scalar(
            lambda x: -abs(response(np.array([2j * np.pi * x]))[0, i, j]),
            bounds=(f[k] - df, f[k] + df), method="bounded", options={"xatol": 1e-6 * f[k]})
        out.append((float(res.x), float(-res.fun)))
    return out


def resonance_f_max(line, form: str, n_peaks: int) -> float:
    """Frequency up to which the first ``n_peaks`` resonances of a form are scanned, [Hz].

    Half a mode spacing above the n-th undamped modal frequency (M9): PQ/QP resonate at
    ``(k - 1/2) pi/tau``, PP/QQ at ``k pi/tau``; the scan stops at ``n pi/tau`` or
    ``(n + 1/2) pi/tau`` (``tau = L/c``).
    """
    theta_top = (n_peaks + 0.5) * np.pi if form in ("PP", "QQ") else n_peaks * np.pi
    return theta_top / line.wave_time / (2 * np.pi)


def compare_resonances(line, model, n_peaks: int | None = None, f_max: float | None = None):
    """Resonances of every entry of ``model.transfer`` against ``line.transfer`` (dissipative).

    Peaks are matched by order. Default: the model's retained modes (``model.n_modes``),
    scanning up to the frequency of mode n + 1/2.

    Returns
    -------
    list[Resonance]
    """
    form = model.form
    n = n_peaks or model.n_modes
    if f_max is None:
        f_max = resonance_f_max(line, form, n)

    def exact(s):
        return line.transfer(s, form)

    rows = []
    for i in range(2):
        for j in range(2):
            pe = find_resonances(exact, f_max, (i, j))
            pm = find_resonances(model.transfer, f_max, (i, j))
            for k, ((fe, me), (fm, mm)) in enumerate(zip(pe[:n], pm[:n])):
                rows.append(Resonance((i, j), k + 1, fe, me, fm, mm))
    return rows
