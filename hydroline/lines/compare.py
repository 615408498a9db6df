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
    """One resonance peak of one matrix entry of both models.

    Attributes
    ----------
    entry : tuple of int
        Matrix entry (output index, input index) in form order.
    mode : int
        Peak number, 1 for the lowest.
    exact_frequency_hz : float
        Peak frequency of the exact dissipative model (M6), [Hz].
    exact_magnitude : float
        Its magnitude, [SI unit of the entry].
    model_frequency_hz : float
        Peak frequency of the model, [Hz].
    model_magnitude : float
        Its magnitude, [SI unit of the entry].
    """

    entry: tuple[int, int]
    mode: int
    exact_frequency_hz: float
    exact_magnitude: float
    model_frequency_hz: float
    model_magnitude: float

    @property
    def frequency_error_pct(self) -> float:
        """Model minus exact peak frequency, relative to exact, [%]."""
        return 100.0 * (self.model_frequency_hz / self.exact_frequency_hz - 1.0)

    @property
    def magnitude_error_pct(self) -> float:
        """Model minus exact peak magnitude, relative to exact, [%]."""
        return 100.0 * (self.model_magnitude / self.exact_magnitude - 1.0)

    def entry_name(self, form: str) -> str:
        """Name of the entry as ``output/input``, e.g. ``downstream_pressure/upstream_pressure``.

        Parameters
        ----------
        form : str
            Causal form of the compared models.

        Returns
        -------
        str
            The entry's name.
        """
        ins, outs = FORM_PORTS[form]
        return f"{outs[self.entry[0]]}/{ins[self.entry[1]]}"


def find_resonances(response, f_max: float, entry, n_points: int = 4000, f_min: float = 0.0):
    """Peaks of ``|response(2j pi f)[..., i, j]|`` below f_max, refined by bounded search.

    Parameters
    ----------
    response : callable
        ``s -> array`` of shape ``s.shape + (2, 2)``, s in [1/s].
    f_max : float
        Upper frequency, [Hz].
    entry : tuple of int
        Matrix entry (output, input).
    n_points : int
        Grid points of the coarse scan.
    f_min : float
        Lower frequency of the scan, [Hz].

    Returns
    -------
    list of tuple
        ``(frequency [Hz], magnitude [SI unit of the entry])`` of each local maximum.
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
    """Frequency up to which the first ``n_peaks`` resonances of a form are scanned.

    Half a mode spacing above the n-th undamped modal frequency (M9): PQ/QP resonate at
    ``(k - 1/2) pi/tau``, PP/QQ at ``k pi/tau``; the scan stops at ``n pi/tau`` or
    ``(n + 1/2) pi/tau`` (``tau = L/c``).

    Parameters
    ----------
    line : Line
        The line.
    form : str
        Causal form "PQ", "QP", "PP" or "QQ".
    n_peaks : int
        Number of resonances to include.

    Returns
    -------
    float
        Upper scan frequency, [Hz].
    """
    theta_top = (n_peaks + 0.5) * np.pi if form in ("PP", "QQ") else n_peaks * np.pi
    return theta_top / line.wave_time / (2 * np.pi)


def _same_grid_once(response):
    """``response`` that keeps its last array result and returns it for the same ``s`` again
    (the coarse scan of :func:`find_resonances` is the same grid for every entry)."""
    last = {}

    def remembered(s):
        s = np.asarray(s)
        if s.size < 2:
            return response(s)
        if "s" in last and last["s"].shape == s.shape and np.array_equal(last["s"], s):
            return last["H"]
        last["s"], last["H"] = s.copy(), response(s)
        return last["H"]

    return remembered


def compare_resonances(line, model, n_peaks: int | None = None, f_max: float | None = None):
    """Resonances of every entry of ``model.transfer`` against ``line.transfer`` (dissipative).

    Peaks are matched by order. Default: the model's retained modes (``model.n_modes``),
    scanning up to the frequency of mode n + 1/2.

    Parameters
    ----------
    line : Line
        The line; its exact dissipative transfer matrix (M6) is the reference.
    model : StateSpaceLine
        The model (with ``form``, ``transfer`` and, unless ``n_peaks`` is given, ``n_modes``).
    n_peaks : int or None
        Resonances compared per entry; ``model.n_modes`` when None.
    f_max : float or None
        Upper scan frequency, [Hz]; from :func:`resonance_f_max` when None.

    Returns
    -------
    list of Resonance
        One per entry and peak.

    Examples
    --------
    A 10 ft, 15.9 mm hose (SAE 100R2 size -10, effective bulk modulus 178 MPa), six
    Yang-Tobler modes: resonance frequencies within 0.2 % of the
    exact model, peaks within 10 % (the model reference, §2.2):

    >>> from hydroline import MINERAL_OIL
    >>> from hydroline.lines import Line, ModalLine
    >>> line = Line(3.048, 0.0159, MINERAL_OIL, bulk_modulus=178e6)
    >>> rows = compare_resonances(line, ModalLine(line, 6))
    >>> len(rows), max(abs(r.frequency_error_pct) for r in rows) < 0.2
    (24, True)
    >>> max(abs(r.magnitude_error_pct) for r in rows) < 10.5
    True
    """
    form = model.form
    n = n_peaks or model.n_modes
    if f_max is None:
        f_max = resonance_f_max(line, form, n)

    def exact(s):
        return line.transfer(s, form)

    # the four entries scan the same grid: evaluate each response on it once
    exact, modelled = _same_grid_once(exact), _same_grid_once(model.transfer)
    rows = []
    for i in range(2):
        for j in range(2):
            pe = find_resonances(exact, f_max, (i, j))
            pm = find_resonances(modelled, f_max, (i, j))
            for k, ((fe, me), (fm, mm)) in enumerate(zip(pe[:n], pm[:n])):
                rows.append(Resonance((i, j), k + 1, fe, me, fm, mm))
    return rows
