"""The hose-layout study of Ayalew & Kulakowski (2005), Figs. 13-14.

The paper's design question: what happens to the supply and return pressure oscillations at
the servovalve when the hoses between the hydraulic service manifold (HSM) and the valve --
the sections II -- are shortened, down to close-coupling the manifold and its accumulators to
the valve. :func:`layout` sets ``supply.section2.length`` and ``return.section2.length`` to
each length in turn (0 removes the section: the manifold node is joined to the valve port,
see :func:`hydroline.system.build_network`), runs the scenario (the 50 mA open-loop step by
default) from the solved steady state and takes the port metrics of
:func:`hydroline.scenarios.summarize` over the metrics window (step to the piston's arrival at
the stop it moves toward): oscillation frequency [Hz], oscillation amplitude (two-sided, about
the pressure's one-period mean) [MPa], first excursion and steady change [MPa], and the
settling time [s] of :func:`hydroline.analysis.port_settling` within +-2 % of the final
absolute pressure (``settling_band``) -- measured on the window where the port pressure
settles within it, else estimated from the exponential decay of its oscillation's crests (the
table's ``*_settling_method`` column says which, and ``*_settling_note`` how, or why there is
none). A frequency of None means the port
pressure does not ring (amplitude 0, ``*_amplitude_note`` says so). :func:`conclusion` writes
the design conclusion from the numbers.

What to expect (docs/model.md 1-2): a section II with a nearly blocked valve end and the
accumulator-stiffened manifold at the other is close to a quarter-wave resonator, so the
frequency rises roughly as 1/L when the hose is shortened (c/(4L) is about 39 Hz for 3 m). The
amplitude is the water hammer Z0 * dQ that the valve's flow step starts -- but only where the
flow rises faster than the hose's round trip 2L/c. On the default rig the flow rises (10-90 %)
in about 5 ms (spool 140 Hz, zeta = 1, and the actuator's acceleration; the table's
``flow_rise_time_ms``), against round trips of 12.6 ms at 3.048 m and 3.1 ms at 0.7512 m
(``*_round_trip_ms``): the long hoses differ little (1.00 / 1.02 / 0.97 MPa at the supply port
for 3.048 / 2.286 / 1.524 m), the 0.7512 m hose's reflection returns before the flow has risen
(0.56 MPa), and close-coupling removes the resonator (0). How much a valve whose flow rises like
a second-order system can put into the quarter-wave mode is (M26), the table's
``*_valve_bound_mpa`` (:mod:`hydroline.analysis.water_hammer`). The paper: peak amplitudes
"progressively reduced", "slightly", the close coupling "eliminates" the oscillation.

References
----------
Ayalew, B. and Kulakowski, B. T. (2005), Modeling supply and return line dynamics for an
electrohydraulic actuation system, ISA Transactions 44(3), 329-343,
doi:10.1016/S0019-0578(07)60207-6. Figs. 13-14: port pressures for section II lengths of
10, 7.5, 5 and 2.46 ft and a close-coupled manifold.
"""
from __future__ import annotations

import functools
import math
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..compiled.toolchain import many_runs
from ..rigs import Rig, RigError, load_rig
from ..scenarios.experiments import scenario_names
from ..scenarios.running import simulate
from ..engine import SimulationResult, SteadyStateError
from ..engine.result import write_csv_table
from ..lines import Line
from ..system import make_fluid
from ..units import parse_quantity
from .settling import BAND, SettlingBand, port_summary

__all__ = ["layout", "LayoutStudy", "DEFAULT_LENGTHS", "parse_lengths", "SIDES", "conclusion",
           "layout_sections", "run_order"]

#: The paper's section II lengths, 10, 7.5, 5, 2.46 ft and 0 (close-coupled manifold), [m].
DEFAULT_LENGTHS = (3.048, 2.286, 1.524, 0.7512, 0.0)
SIDES = ("supply", "return")
_METRICS = ("frequency_hz", "amplitude_mpa", "settling_time_s", "settling_band_mpa")
#: The table's further port metrics (:func:`hydroline.analysis.pressure_metrics`).
_MORE = ("first_excursion_mpa", "steady_change_mpa", "peak_to_peak_mpa")


def _finite_or_none(v):
    """``v`` with every NaN or infinite float in it (nested dicts, lists) replaced by None."""
    if isinstance(v, dict):
        return {k: _finite_or_none(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite_or_none(x) for x in v]
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    return v.item() if isinstance(v, np.generic) else v


def parse_lengths(lengths) -> list[float]:
    """Section II lengths -> metres.

    Parameters
    ----------
    lengths : str or sequence
        ``"3.048,2.286,0"`` (bare numbers are metres: the option's documented unit),
        ``"10 ft,5 ft,0 m"``, or a sequence of numbers [m] and quantity strings; each >= 0

    Returns
    -------
    list[float]
        The lengths, [m]

    Raises
    ------
    UnitError, RigError
        (ValueErrors) One line naming ``--lengths``.
    """
    items = [s.strip() for s in lengths.split(",")] if isinstance(lengths, str) else list(lengths)
    if not items or any(isinstance(s, str) and not s for s in items):
        raise RigError(f"--lengths: expected comma-separated lengths in m, e.g. "
                       f"3.048,1.524,0 or '10 ft,5 ft,0 m'; got {lengths!r}")
    out = []
    for k, item in enumerate(items):
        name = f"--lengths[{k}]"
        if isinstance(item, str):
            try:
                value = float(item)            # a bare number: metres
            except ValueError:
                value = parse_quantity(item, "m", name)
        elif isinstance(item, (int, float, np.floating, np.integer)) and not isinstance(item, bool):
            value = float(item)
        else:
            value = parse_quantity(item, "m", name)
        if not np.isfinite(value) or value < 0:
            raise RigError(f"{name}: a section II length must be >= 0 m (0 removes the section), "
                           f"got {item!r}")
        out.append(value)
    return out


@dataclass
class LayoutStudy:
    """Results of :func:`layout`, one entry per section II length.

    Attributes
    ----------
    lengths : list[float]
        Section II lengths, [m]
    summaries : list[dict]
        :func:`hydroline.studies.settling.port_summary` of each run
        (``summarize`` with ``settling_method``/``settling_note``)
    results : list
        The :class:`~hydroline.engine.SimulationResult` of each run (each ends with its
        metrics window, the piston at its stop: ``simulate(metrics_only=True)``)
    sides : tuple
        Which sections II were set ("supply", "return")
    scenario : str
        The scenario run for every length.
    rig_name : str
        The rig's name (its file, or the embedded rig's).
    wall_time : float
        Wall time of the whole study, [s]
    wave_speeds : dict
        side -> wave speed c of its section II (M2), [m/s]
    files : dict
        What :meth:`save` wrote
    sections : tuple
        The hose sections whose length was set (template rig:
        ``supply.section2``, ...; circuit rig: component names)
    axis : str
        The servo axis whose port pressures the study reports (a
        multi-axis rig; None on a single-axis rig)
    """

    lengths: list
    summaries: list
    results: list
    sides: tuple = SIDES
    scenario: str = "open-loop-step"
    rig_name: str = ""
    wall_time: float = 0.0
    wave_speeds: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)
    sections: tuple = ()
    axis: str | None = None

    def records(self) -> list[dict]:
        """The rows of the ``--json`` document, one per length: ``{"section2_length_m", **summary}``
        with every key of that run's summary (:func:`hydroline.studies.settling.port_summary`),
        nested as it is: ``"supply"`` and ``"return"`` with every port metric and note,
        ``"flow"`` (flow rise and round trips), the metrics window, ``wall_time_s`` and
        ``warnings``; so every column of :meth:`table` is in it (``supply_x`` as
        ``["supply"]["x"]``, the flow's columns under ``["flow"]``). None where a metric does
        not exist; never NaN, so the rows are strict JSON.

        Returns
        -------
        list[dict]
            One row per length, in the order of :attr:`lengths`.
        """
        return [{"section2_length_m": float(L), **_finite_or_none(s)}
                for L, s in zip(self.lengths, self.summaries)]

    #: Columns of the study's summary table (``repr`` and a notebook).
    SUMMARY_HEADER = ("length [m]", "supply [Hz]", "supply amplitude [MPa]",
                      "return [Hz]", "return amplitude [MPa]", "supply settling [ms]")

    def _summary_rows(self):
        rows = [(L, s["supply"].get("frequency_hz"), s["supply"].get("amplitude_mpa"),
                 s["return"].get("frequency_hz"), s["return"].get("amplitude_mpa"),
                 None if s["supply"].get("settling_time_s") is None
                 else s["supply"]["settling_time_s"] * 1e3)
                for L, s in zip(self.lengths, self.summaries)]
        title = (f"hydroline LayoutStudy: {self.scenario} on {self.rig_name or 'a rig'}, "
                 f"{', '.join(self.sections) or 'sections II'} set to each length"
                 + (f" ({self.wall_time:.1f} s)" if self.wall_time > 0 else ""))
        return title, rows

    def __repr__(self) -> str:
        from ..engine.display import text_block

        title, rows = self._summary_rows()
        text = text_block(title, rows, self.SUMMARY_HEADER)
        return text + ("\n  " + conclusion(self) if self.results else "")

    def _repr_html_(self) -> str:
        from ..engine.display import html_block

        title, rows = self._summary_rows()
        return html_block(title, rows, self.SUMMARY_HEADER,
                          note=(conclusion(self) if self.results else "")
                          + " (every metric: .table(); the traces: .traces())")

    def table(self) -> "pandas.DataFrame":
        """The metrics as a table, one row per length.

        Returns
        -------
        pandas.DataFrame
            Columns ``section2_length_m``, ``{supply,return}_{frequency_hz, amplitude_mpa,
            settling_time_s, settling_band_mpa, first_excursion_mpa, steady_change_mpa,
            peak_to_peak_mpa, settling_method, settling_note, amplitude_note}``,
            ``settling_band`` (in words), ``flow_rise_time_ms`` (10-90 % rise of the valve's
            supply-port flow after the step), ``{supply,return}_round_trip_ms`` (2 L / c of
            that section II), ``{supply,return}_valve_bound_mpa`` (the most the valve's flow
            rise can put into that section's quarter-wave swing, docs/model.md M26),
            ``wall_time_s``, ``warnings``; NaN where a metric does not exist.
        """
        import pandas as pd     # here: a sweep's worker imports this module, never a table

        return pd.DataFrame(self.table_rows())

    def table_rows(self) -> list[dict]:
        """The rows of :meth:`table`, as dicts (column -> value; NaN where a metric does not
        exist), without pandas.

        Returns
        -------
        list[dict]
            One row per length, in the order of :attr:`lengths`.
        """
        rows = []
        for L, s in zip(self.lengths, self.summaries):
            row = {"section2_length_m": float(L)}
            for side in SIDES:
                for k in _METRICS:
                    v = s[side].get(k)
                    row[f"{side}_{k}"] = np.nan if v is None else v
            for side in SIDES:
                for k in _MORE:
                    v = s[side].get(k)
                    row[f"{side}_{k}"] = np.nan if v is None else v
            for side in SIDES:
                row[f"{side}_settling_method"] = s[side].get("settling_method") or ""
                row[f"{side}_settling_note"] = s[side].get("settling_note", "")
                row[f"{side}_amplitude_note"] = s[side].get("amplitude_note", "")
            row["settling_band"] = s.get("settling_band", "")
            for k in ("flow_rise_time_ms", "supply_round_trip_ms", "return_round_trip_ms",
                      "supply_valve_bound_mpa", "return_valve_bound_mpa"):
                row[k] = s.get("flow", {}).get(k, np.nan)
            row["wall_time_s"] = s["wall_time_s"]
            row["warnings"] = "; ".join(s["warnings"])
            rows.append(row)
        return rows

    def port_pressure(self, res, side: str) -> np.ndarray:
        """A run's valve port pressure on one side: the reported axis's on a multi-axis rig.

        Parameters
        ----------
        res : SimulationResult
            One run of the study
        side : str
            "supply" or "return"

        Returns
        -------
        numpy.ndarray
            The pressure at every output time, [Pa].
        """
        return _port_pressure(res, side, self.axis)

    def traces(self) -> "pandas.DataFrame":
        """Port pressures of every run on the common output grid (on a multi-axis rig those of
        the reported :attr:`axis`). A run ends with its metrics window (the piston at its
        stop): empty (NaN) after its end.

        Returns
        -------
        pandas.DataFrame
            Columns ``time_s`` [s] and ``{supply,return}_port_pressure_pa@L=<length>m`` [Pa].
        """
        import pandas as pd

        return pd.DataFrame(self.trace_columns())

    def trace_columns(self) -> dict:
        """The columns of :meth:`traces`, without pandas.

        Returns
        -------
        dict
            ``time_s`` [s] and ``{supply,return}_port_pressure_pa@L=<length>m`` [Pa] -> their
            values (NumPy arrays of one length; NaN after a run's end).
        """
        t = max((res.t for res in self.results), key=len)
        cols = {"time_s": t}
        for L, res in zip(self.lengths, self.results):
            for side in SIDES:
                y = self.port_pressure(res, side)
                cols[f"{side}_port_pressure_pa@L={L:g}m"] = np.interp(t, res.t, y, right=np.nan)
        return cols

    #: The files :meth:`save` writes, by role (the traces as CSV; see :meth:`file_names`).
    FILES = {"csv": "layout.csv", "traces": "layout_traces.csv", "figure": "layout.png"}
    #: The formats the traces may be written in (as ``hydroline simulate --format``).
    TRACE_FORMATS = ("csv", "parquet", "mat")

    @classmethod
    def file_names(cls, traces_format: str = "csv") -> dict:
        """The files :meth:`save` writes, by role, with the traces in ``traces_format``.

        Parameters
        ----------
        traces_format : str
            "csv", "parquet" or "mat"

        Returns
        -------
        dict
            role ("csv", "traces", "figure") -> file name.
        """
        if traces_format not in cls.TRACE_FORMATS:
            raise ValueError(f"traces format: one of {', '.join(cls.TRACE_FORMATS)}, got "
                             f"{traces_format!r}")
        return {**cls.FILES, "traces": f"layout_traces.{traces_format}"}

    def save(self, folder, temp=None, traces_format: str = "csv", figures=None) -> dict:
        """Write ``layout.csv`` (metrics), ``layout_traces.csv`` and ``layout.png`` to folder.

        Parameters
        ----------
        folder : path
            Output folder (created)
        temp : callable
            ``temp(name) -> path`` to write each file to first (e.g. the CLI's
            atomic writer, which renames them all at the end); the final names
            are returned either way
        traces_format : str
            The traces as "csv" (``layout_traces.csv``, columns ``time_s`` and
            ``{supply,return}_port_pressure_pa@L=<length>m``), "parquet" or "mat"
            (``layout_traces.parquet`` / ``.mat``: a column or variable ``time`` [s] and one
            per trace, ``{supply,return}_port_pressure@L=<length>m`` [Pa] (in MAT
            ``..._L_<length>m``), their units in the file as ``hydroline simulate --format``
            writes them)
        figures : object
            Where the figure is drawn while the tables are written: a
            :class:`hydroline.cli.figure_process.FigureProcess` (its ``submit`` and
            ``wait``); None: here

        Returns
        -------
        dict
            role ("csv", "traces", "figure") -> path
        """
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        names = self.file_names(traces_format)
        self.files = {role: folder / name for role, name in names.items()}
        where = {role: (temp(name) if temp else folder / name) for role, name in names.items()}
        if figures is not None:   # (arrays: the figure process imports neither model nor pandas)
            from ..plotting import plot_layout

            figures.submit(plot_layout, **self.figure_data(), path=str(where["figure"]))
        rows = self.table_rows()   # (the CSV files as pandas writes them, without its import)
        write_csv_table(where["csv"], {k: [row[k] for row in rows] for k in rows[0]})
        traces = self.trace_columns()
        if traces_format == "csv":
            write_csv_table(where["traces"], traces)
        else:   # written as a run's time series are (units in the file)
            columns = [c for c in traces if c != "time_s"]
            names = [c.replace("_pa@", "@") for c in columns]   # the unit in the file instead
            result = SimulationResult(times=traces["time_s"],
                                      table=np.column_stack([traces[c] for c in columns]),
                                      columns=names, metadata={"units": dict.fromkeys(names, "Pa")})
            getattr(result, f"to_{traces_format}")(where["traces"])
        if figures is not None:
            figures.wait()
        else:
            self.plot(where["figure"])
        return self.files

    def plot(self, path=None, title=None):
        """Port-pressure traces of every length stacked (the paper's Figs. 13-14: supply left,
        return right; dotted: step and piston stop, green dashed: a measured settling
        time; grey, as in every figure, outside the metrics window, said in the legend)
        above frequency and amplitude against length, each point labelled with its value
        where the label overlaps nothing (:func:`hydroline.plotting.place_value_labels`).

        Parameters
        ----------
        path : str or Path
            Write the figure there (PNG) when given
        title : str
            Figure title

        Returns
        -------
        matplotlib.figure.Figure
            The figure (written as PNG to ``path`` when given).
        """
        from ..plotting import plot_layout

        return plot_layout(**self.figure_data(title), path=path)

    #: What the figure reads of a run's summary, per port (:meth:`figure_data`).
    FIGURE_METRICS = ("frequency_hz", "amplitude_mpa", "first_excursion_mpa", "settling_time_s",
                      "settling_method")

    @classmethod
    def figure_run(cls, res, summary: dict, axis=None) -> tuple:
        """What the figure draws of one length's run: its entries of :meth:`figure_data`'s
        ``runs`` and ``summaries`` (also sent to a figure process as each run ends).

        Parameters
        ----------
        res : SimulationResult
            The length's run
        summary : dict
            Its metrics (the study's summary of that length)
        axis : str
            The reported axis of a multi-axis rig (None: the rig's only one)

        Returns
        -------
        tuple
            (:class:`hydroline.plotting.Traces` of the ``supply`` and ``return`` port
            pressures [Pa], ``t_disturbance`` and ``metrics_window`` in its metadata; per port
            the metrics of :data:`FIGURE_METRICS`)
        """
        from ..plotting import Traces

        meta = {"t_disturbance": res.metadata.get("t_disturbance", 0.0),
                "metrics_window": res.metadata.get("metrics_window")}
        run = Traces(res.t, {side: _port_pressure(res, side, axis) for side in SIDES}, meta)
        return run, {side: {k: summary[side].get(k) for k in cls.FIGURE_METRICS} for side in SIDES}

    def figure_data(self, title=None) -> dict:
        """What :meth:`plot` draws, as NumPy arrays and plain values: the arguments of
        :func:`hydroline.plotting.plot_layout`, which a figure process receives without
        importing the model (nor pandas).

        Parameters
        ----------
        title : str
            Figure title (None: the study's scenario, rig and sections)

        Returns
        -------
        dict
            ``lengths`` [m], ``runs`` (a :class:`hydroline.plotting.Traces` per length: the
            ``supply`` and ``return`` port pressures [Pa], ``t_disturbance`` and
            ``metrics_window`` in its metadata), ``summaries`` (per length and port, the
            metrics of :data:`FIGURE_METRICS`), ``wave_speeds`` [m/s], ``sides`` and ``title``.
        """
        runs, summaries = [], []
        for res, s in zip(self.results, self.summaries):
            run, summary = self.figure_run(res, s, self.axis)
            runs.append(run)
            summaries.append(summary)
        what = (f"sections II of {' and '.join(self.sides)} set" if not self.sections or
                set(self.sections) == {f"{s}.section2" for s in self.sides} else
                f"{', '.join(self.sections)} set" + (f"; ports of {self.axis}" if self.axis else ""))
        return {"lengths": [float(L) for L in self.lengths], "runs": runs,
                "summaries": summaries, "wave_speeds": dict(self.wave_speeds),
                "sides": tuple(self.sides),
                "title": title or f"Section II layout study: {self.scenario} on "
                                  f"{self.rig_name} ({what})"}


def _flow_change(res, flow_signal: str):
    """The valve port flow over the metrics window: ``(times, flows, q0, q1)`` with q0 at the
    step and q1 the mean over the last 20 % of the window, [s], [m^3/s]; None without it."""
    t0, t1, _ = res.metadata["metrics_window"]
    if flow_signal not in res:
        return None
    t, q = res.t, res[flow_signal]
    w = (t >= t0) & (t <= t1)
    tw, qw = t[w], q[w]
    q0 = float(np.interp(t0, t, q))
    q1 = float(np.mean(qw[tw >= t1 - 0.2 * (t1 - t0)]))
    return tw, qw, q0, q1


def _flow_rise_time(res, flow_signal: str = "supply_port_flow") -> float:
    """10-90 % rise time [s] of the valve's supply-port flow after the step (NaN if none).

    The flow step at the valve starts the water hammer; it reaches the hose as the full
    Joukowsky swing ``Z0 * dQ`` only when it rises faster than the hose's round-trip wave time
    ``2 L / c``. The final flow is the mean over the last 20 % of the metrics window."""
    change = _flow_change(res, flow_signal)
    if change is None:
        return float("nan")
    tw, qw, q0, q1 = change
    if not abs(q1 - q0) > 0:
        return float("nan")
    rel = (qw - q0) / (q1 - q0)
    reach = [np.flatnonzero(rel >= level) for level in (0.1, 0.9)]
    if any(r.size == 0 for r in reach):
        return float("nan")
    return float(tw[reach[1][0]] - tw[reach[0][0]])


#: A port amplitude at least this share of the valve's bound (M26) is "close to it": the
#: conclusion then says the valve, not the hose, limits it, [-]
NEAR_BOUND = 0.6


def _valve_bound_mpa(res, line: Line, length: float, flow_signal: str, valve) -> float:
    """The valve's bound (M26, :func:`hydroline.analysis.water_hammer.valve_bound`) on the
    half peak-to-peak swing of a section of ``length`` at the port, for the run's flow change
    at the port, [MPa]; NaN for a removed section or without the flow."""
    from ..analysis.water_hammer import valve_bound

    change = _flow_change(res, flow_signal)
    if not length > 0 or change is None:
        return float("nan")
    _, _, q0, q1 = change
    bound = valve_bound(length, line.wave_speed, line.impedance, q1 - q0, *valve)
    return bound["swing_amplitude_pa"] / 1e6


def conclusion(study: "LayoutStudy") -> str:
    """The design conclusion in one sentence, written from the study's own numbers.

    Compares the port oscillation amplitude at the longest section II with the shortest
    non-zero one and, where the study has it, the close-coupled manifold (0 m).

    Parameters
    ----------
    study : LayoutStudy
        A finished layout study

    Returns
    -------
    str
        One sentence
    """
    recs = {r["section2_length_m"]: r for r in study.records()}
    hoses = sorted(L for L in recs if L > 0)
    parts = []
    if len(hoses) >= 2:
        long_, short = hoses[-1], hoses[0]
        pieces, monotone = [], True
        for side in study.sides:
            amps = [recs[L][side]["amplitude_mpa"] for L in reversed(hoses)]
            if any(a is None for a in amps):
                continue
            monotone &= all(b <= a for a, b in zip(amps, amps[1:]))
            pieces.append(f"{amps[0]:.2f} to {amps[-1]:.2f} MPa ({side})")
        if pieces:
            verb = "lowers" if monotone else "changes"
            how = " progressively" if monotone and len(hoses) > 2 else ""
            freqs = [recs[L]["supply"]["frequency_hz"] for L in (long_, short)]
            freq = (f", while its frequency rises from {freqs[0]:.0f} to {freqs[1]:.0f} Hz"
                    if None not in freqs else "")
            parts.append(f"shortening sections II from {long_:g} m to {short:g} m {verb} the "
                         f"port oscillation amplitude{how} from " + " and ".join(pieces) + freq)
        parts.extend(_settling_sentence(study, hoses))
    if hoses:
        bound = {L: study.summaries[study.lengths.index(L)]["flow"] for L in hoses}
        near = []
        for side in study.sides:
            pairs = [(recs[L][side]["amplitude_mpa"], bound[L].get(f"{side}_valve_bound_mpa",
                                                                   float("nan"))) for L in hoses]
            short_amp, short_bound = pairs[0]
            if short_amp is None or not short_bound > 0 or short_amp < NEAR_BOUND * short_bound:
                continue
            shares = [a / b for a, b in pairs if a is not None and b > 0]
            span = (f"{min(shares):.0%}-{max(shares):.0%}" if len(shares) > 1
                    else f"{shares[0]:.0%}")
            falls = (f" falls from {pairs[-1][1]:.2f} to {short_bound:.2f} MPa and"
                     if len(pairs) > 1 and pairs[-1][1] > 0 else " is")
            near.append(f"{side}: the bound{falls} the amplitude stays at {span} of it")
        if near:
            parts.append(f"at {hoses[0]:g} m the amplitude is close to the most the valve's "
                         "flow rise can put into the hose's quarter-wave mode (docs/model.md "
                         "M26; " + "; ".join(near) + "): the valve, not the hose, bounds it")
    if 0.0 in recs:
        left = [(side, recs[0.0][side]) for side in SIDES
                if recs[0.0][side]["frequency_hz"] is not None]
        longest = recs[hoses[-1]] if hoses else None

        def share(side, m):
            a = longest[side]["amplitude_mpa"] if longest else None
            return f", {m['amplitude_mpa'] / a * 100:.0f} % of the {hoses[-1]:g} m hose's" \
                if a and m["amplitude_mpa"] is not None else ""

        parts.append("close-coupling the manifold to the valve (0 m) removes the oscillation"
                     if not left else "close-coupling (0 m) leaves " + " and ".join(
                         f"{m['amplitude_mpa']:.2g} MPa at {m['frequency_hz']:.0f} Hz ({side}"
                         f"{share(side, m)})" for side, m in left))
    if not parts:
        return ""
    text = "; ".join(parts)
    return text[0].upper() + text[1:] + "."


def _settling_sentence(study: "LayoutStudy", hoses: list) -> list[str]:
    """The conclusion's clause on settling: how each port's settling time changes from the
    longest section II to the shortest, and when the longest is halved (the paper's
    comparison); "~" marks an estimate (empty list when no port has two settling times)."""
    by_length = dict(zip(study.lengths, study.summaries))
    long_ = hoses[-1]
    half = min(hoses, key=lambda L: abs(L - long_ / 2))
    pieces = []
    for side in study.sides:
        m = {L: by_length[L][side] for L in hoses}
        times = {L: v["settling_time_s"] for L, v in m.items() if v.get("settling_time_s")}
        if long_ not in times or len(times) < 2:
            continue

        def ms(L):
            return f"{'~' if m[L].get('settling_method') == 'estimated' else ''}" \
                   f"{times[L] * 1e3:.0f} ms"

        text = f"{side} " + ", ".join(f"{ms(L)} at {L:g} m" for L in reversed(hoses)
                                      if L in times)
        if half in times and half != long_ and abs(half - long_ / 2) <= 0.1 * long_:
            change = times[half] - times[long_]
            text += (f" (halving {long_:g} m to {half:g} m: {change * 1e3:+.0f} ms, "
                     f"{change / times[long_] * 100:+.0f} %)")
        pieces.append(text)
    if not pieces:
        return []
    band = next((s.get("settling_band") for s in study.summaries if s.get("settling_band")), "")
    return [f"the port pressures settle (within {band}) in " + "; ".join(pieces)]


def layout_sections(rig: Rig, sections=None, sides=SIDES) -> tuple:
    """The hose sections a layout study varies, checked against the rig.

    Parameters
    ----------
    rig : Rig
        The rig
    sections : str or sequence
        Hose sections by name, comma-separated or a sequence: on a
        template rig ``supply.section2``, ``return.section1``, ...; on
        a circuit rig its hose components (``axis1.supply_hose``;
        a ``circuit.`` prefix is allowed). None: the sections II of
        ``sides`` (template rigs, and circuit rigs with hoses named
        ``supply.section2`` / ``return.section2``)
    sides : sequence
        "supply" and/or "return", for the default

    Returns
    -------
    tuple[str]
        Section names (circuit component names without ``circuit.``)

    Raises
    ------
    RigError
        One line naming the rig: a section it does not have, or a circuit rig whose
        hoses the study cannot tell (name them with ``--sections``).
    """
    from ..circuit import has_circuit

    circuit = has_circuit(rig.values)
    hoses = layout_sections_available(rig)
    if sections is None:
        names = [f"{side}.section2" for side in sides]
        if circuit and not all(n in hoses for n in names):
            raise RigError(f"rig {rig.source}: cannot tell which hoses the layout study varies "
                           f"(no hoses named {' and '.join(names)}); name them with --sections, "
                           f"e.g. --sections {','.join(hoses[:2]) or 'NAME'} (its hoses: "
                           f"{', '.join(hoses) or 'none'})")
        return tuple(names)
    items = [x.strip() for x in sections.split(",")] if isinstance(sections, str) else \
        [str(x).strip() for x in sections]
    items = [x[len("circuit."):] if x.startswith("circuit.") else x for x in items]
    if not items or not all(items):
        raise RigError(f"--sections: expected comma-separated hose sections of rig "
                       f"{rig.source} (its hoses: {', '.join(hoses)}), got {sections!r}")
    for name in items:
        if name not in hoses:
            raise RigError(f"--sections: rig {rig.source} has no hose section {name!r} "
                           f"(its hoses: {', '.join(hoses)})")
    if len(set(items)) != len(items):
        raise RigError(f"--sections: a hose section is named twice in {sections!r}")
    return tuple(items)


def _length_path(rig: Rig, section: str) -> str:
    from ..circuit import has_circuit

    return f"circuit.{section}.length" if has_circuit(rig.values) else f"{section}.length"


def _section_side(section: str) -> str | None:
    """"supply" or "return" where the section's name says which, else None."""
    for side in SIDES:
        if side in section.split(".")[-1] or section.split(".")[0] == side:
            return side
    return None


def _port_pressure(res, side: str, axis) -> np.ndarray:
    """A run's valve port pressure on one side (the axis ``axis``'s on a multi-axis rig), [Pa]."""
    axes = res.metadata.get("axes") or {}
    if axis is not None and axis in axes:
        return res[getattr(axes[axis], f"{side}_pressure")]
    return res[f"{side}_port_pressure"]


def _report_axis(res, sections, axis):
    """The axis whose ports the study reports: the one given, else the one whose name
    prefixes the first section's, else the experiment's stepped axis."""
    axes = res.metadata.get("axes") or {}
    if len(axes) <= 1:
        return None
    if axis is not None:
        if axis not in axes:
            raise RigError(f"--axis: no axis {axis!r} in the rig (axes: {', '.join(axes)})")
        return axis
    for name in axes:
        if any(s.startswith(f"{name}.") for s in sections):
            return name
    stepped = res.metadata.get("stepped_axis")
    return stepped if stepped in axes else next(iter(axes))


def _section_line(rig: Rig, section: str, fluid) -> Line:
    """A hose section's bore and bulk modulus as a 1 m :class:`~hydroline.lines.Line` (its
    wave speed c and impedance Z0, M2-M3, do not depend on the length)."""
    from ..circuit import has_circuit

    base = f"circuit.{section}" if has_circuit(rig.values) else section
    return Line(1.0, rig[f"{base}.diameter"], fluid, rig.get(f"{base}.bulk_modulus"))


def _valve(rig: Rig, res, chosen):
    """(port flow signals by side, (natural frequency [Hz], damping ratio [-])) of the valve
    of the reported axis: the template's servovalve, or the circuit axis's."""
    from ..circuit import has_circuit

    flows = {"supply": "supply_port_flow", "return": "return_port_flow"}
    if not has_circuit(rig.values):
        return flows, (rig["servovalve.natural_frequency"], rig["servovalve.damping_ratio"])
    axes = res.metadata.get("axes") or {}
    ax = axes.get(chosen) if chosen is not None else next(iter(axes.values()), None)
    if ax is None:
        return flows, (float("nan"), float("nan"))
    head = f"circuit.{ax.valve}"
    flows = {side: rig.get(f"{head}.ports.{side}_flow", flows[side]) for side in SIDES}
    return flows, (rig.get(f"{head}.natural_frequency", float("nan")),
                   rig.get(f"{head}.damping_ratio", float("nan")))


def run_order(lengths) -> list[int]:
    """The order a layout study runs its lengths in: the first, then every 0 m length (a
    template rig without the section: a network of its own), then the rest in order.

    The first run of a study starts the background build of its network's library (a
    compiled core, :mod:`hydroline.compiled.toolchain`) and waits for the build's quick
    library, as the later lengths of that network do. A 0 m length is another network, run
    on CVODES in any case: run during that wait (:func:`layout`), it takes its time out of
    the wait instead of adding it after the last run. The results are the same in any order.

    Parameters
    ----------
    lengths : list of float
        The study's section lengths, [m]

    Returns
    -------
    list of int
        Indices into ``lengths``.
    """
    rest = range(1, len(lengths))
    if not lengths or lengths[0] == 0:
        return list(range(len(lengths)))
    return [0, *(k for k in rest if lengths[k] == 0), *(k for k in rest if lengths[k] != 0)]


def layout(rig=None, lengths=DEFAULT_LENGTHS, *, sides=SIDES, sections=None, axis=None,
           scenario: str | None = None, t_end: float | None = None, solver: str = "auto",
           progress=None, settling_band=BAND, on_run=None) -> LayoutStudy:
    """The section II layout study: the scenario run once per hose length.

    Parameters
    ----------
    rig : Rig, str or None
        The rig (None: the embedded 2005 paper's rig; a shipped rig may
        be named)
    lengths : sequence or str
        Section lengths, [m] (numbers are metres; strings may carry
        units, "10 ft"); 0 removes a template rig's section
        (close-coupled manifold)
    sides : sequence
        Which sections II take the length: "supply", "return" or both
        (when ``sections`` is None)
    sections : str or sequence
        The hose sections that take the length (see
        :func:`layout_sections`): a circuit rig's hose components, e.g.
        "axis1.supply_hose,axis1.return_hose"; None: the sections II
    axis : str
        Multi-axis rig: the axis whose port pressures are reported (None:
        the axis the first section belongs to by name, else the stepped)
    scenario : str
        One of :func:`hydroline.scenarios.scenario_names`; None: the rig's
        ``rig.scenario``, else "open-loop-step" (the paper's)
    t_end : float
        Simulated time, [s]; the scenario's default when None
    solver : str
        See :func:`hydroline.engine.integrate`
    progress : callable
        ``progress(done, total)`` after each length
    settling_band : SettlingBand or str
        The port pressures' settling band
        (:meth:`hydroline.traces.metrics.SettlingBand.parse`; default +-2 %
        of the final absolute pressure)
    on_run : callable
        ``on_run(index, length, result, summary, axis)`` after each length's run and
        metrics (the reported axis: None on a single-axis rig), e.g. to hand its traces to
        a figure process while the next lengths run; called in the order of ``lengths``
        (the lengths run in :func:`run_order`'s: a 0 m length's run, made second, is
        handed on after the lengths before it)

    Returns
    -------
    LayoutStudy
        The runs and their metrics: ``records()`` is the ``--json`` list, ``table()`` a
        DataFrame, ``plot()`` and ``save(folder)`` the figure and CSV files.
    """
    from ..scenarios.experiments import default_scenario

    tic = _time.perf_counter()
    if not isinstance(rig, Rig):
        rig = load_rig(rig)
    scenario = scenario or default_scenario(rig)
    if scenario not in scenario_names(rig):
        raise RigError(f"--scenario: unknown scenario {scenario!r} (known: "
                       f"{', '.join(scenario_names(rig))})")
    sides = (sides,) if isinstance(sides, str) else tuple(sides)
    if not sides or any(s not in SIDES for s in sides):
        raise RigError(f"--side: expected 'supply', 'return' or both, got {sides!r}")
    sections = layout_sections(rig, sections, sides)
    if any(_section_side(s) is not None for s in sections):
        sides = tuple(side for side in SIDES if any(_section_side(s) == side for s in sections))
    else:
        sides = SIDES
    lengths = parse_lengths(lengths)
    settling_band = SettlingBand.parse(settling_band)
    summaries, results = [None] * len(lengths), [None] * len(lengths)
    chosen = None
    handed = 0                  # runs handed to on_run, in the lengths' order

    def run_length(k):
        """Run length ``k`` (unless it has run), its metrics, and hand on what has run."""
        nonlocal chosen, handed
        if results[k] is not None:
            return
        L = lengths[k]
        variant = rig.copy()
        try:
            for section in sections:
                variant.set(_length_path(rig, section), f"{L!r} m")
            res = simulate(variant, scenario, t_end, solver=solver, metrics_only=True)
        except (ValueError, SteadyStateError) as e:
            msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise RigError(f"section length {L:g} m: {msg}") from e
        summary = port_summary(res, settling_band)
        chosen = _report_axis(res, sections, axis)
        flow = "supply_port_flow"
        if chosen is not None:       # a multi-axis rig: that axis's ports
            summary = {**summary, **summary["axes"][chosen]}
            ax = res.metadata["axes"][chosen]
            flow = rig.get(f"circuit.{ax.valve}.ports.supply_flow", flow)
        rise = _flow_rise_time(res, flow) if res.metadata.get("scenario") != "position-step" \
            else float("nan")       # a position step's flow returns to zero: no final flow
        summary["flow"] = {"flow_rise_time_ms": rise * 1e3}
        summaries[k], results[k] = summary, res
        while on_run is not None and handed < len(lengths) and results[handed] is not None:
            on_run(handed, lengths[handed], results[handed], summaries[handed], chosen)
            handed += 1
        if progress is not None:
            progress(sum(r is not None for r in results), len(lengths))

    order = run_order(lengths)
    # (a 0 m length, a network of its own, runs on CVODES while the first run waits for its
    # library's quick build: compiled.many_runs)
    with many_runs(meanwhile=[functools.partial(run_length, k) for k in order[1:]
                              if lengths[k] == 0 != lengths[order[0]]]):
        for k in order:
            run_length(k)
    fluid = make_fluid(rig)
    lines = {}
    for side in SIDES:
        mine = [s for s in sections if _section_side(s) == side]
        default = f"{side}.section2"
        if mine:
            lines[side] = _section_line(rig, mine[0], fluid)
        elif default in layout_sections_available(rig):
            lines[side] = _section_line(rig, default, fluid)
    speeds = {side: line.wave_speed for side, line in lines.items()}
    for L, summary, res in zip(lengths, summaries, results):
        flows, valve = _valve(rig, res, chosen)
        for side in SIDES:
            summary["flow"][f"{side}_round_trip_ms"] = (2 * L / speeds[side] * 1e3
                                                        if side in speeds else float("nan"))
            summary["flow"][f"{side}_valve_bound_mpa"] = (
                _valve_bound_mpa(res, lines[side], L, flows[side], valve)
                if side in lines and all(math.isfinite(v) for v in valve) else float("nan"))
    return LayoutStudy(lengths, summaries, results, sides, scenario,
                       str(rig.get("rig.name", rig.source)), _time.perf_counter() - tic, speeds,
                       sections=sections, axis=chosen)


def layout_sections_available(rig: Rig) -> list[str]:
    """Every hose section of the rig by name.

    Parameters
    ----------
    rig : Rig
        The rig

    Returns
    -------
    list[str]
        Template rig: ``supply.section1`` ...; circuit rig: its hose components.
    """
    from ..circuit import circuit_names, has_circuit

    if has_circuit(rig.values):
        return [n for n in circuit_names(rig.values) if rig.get(f"circuit.{n}.type") == "hose"]
    return [f"{side}.section{k}" for side in SIDES for k in (1, 2)]
