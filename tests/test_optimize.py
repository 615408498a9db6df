"""Issue 28: ``hydroline optimize`` -- constrained design optimisation on the sweep's runner.

The optimiser's code path is checked on analytic objectives (a runner returning the sweep's
row columns from a formula, optimum known by hand, compared with a brute-force grid as the
issue asks); one small problem runs the real default rig (a short run, few evaluations).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hydroline.cli import main
from hydroline.rigs import RigError, load_rig
from hydroline.studies.journal import SweepFileError
from hydroline.studies.optimize import (COST_METRICS, FEASIBILITY_TOLERANCE, cost_metrics,
                                        metric_names, objective_gradient, optimize,
                                        parse_constraint)
from hydroline.studies.sweep import VariantRunner

L_BEST, D_BEST, C_BEST = 1.7, 0.0159, 2e-3


class Analytic:
    """A runner with the sweep's row columns from formulas: the supply amplitude a bowl of
    minimum 0.5 MPa at L = 1.7 m, C = 2 L, d = 15.9 mm; the supply frequency 100 Hz m / L."""

    def __init__(self):
        self.calls = 0

    def __call__(self, index, values):
        self.calls += 1
        L = values.get("supply.section2.length", 3.048)
        C = values.get("supply.accumulator.capacity", C_BEST)
        d = values.get("supply.section2.diameter", D_BEST)
        amp = 0.5 + (L - L_BEST) ** 2 + ((C - C_BEST) / 1e-3) ** 2 + ((d - D_BEST) / 1e-3) ** 2
        return {"variant": index, **values, "supply_amplitude_mpa": amp,
                "supply_frequency_hz": 100.0 / L, "error": None}


def amplitude(L, C=C_BEST):
    return 0.5 + (L - L_BEST) ** 2 + ((C - C_BEST) / 1e-3) ** 2


def test_1d_within_one_percent_of_a_fine_grid_in_a_fifth_of_its_evaluations():
    grid = np.linspace(0.5, 4.0, 60)
    best = min(amplitude(L) for L in grid)
    runner = Analytic()
    r = optimize(["supply.section2.length=0.5 m..4 m"], minimize="supply.amplitude_mpa",
                 runner=runner, max_evaluations=len(grid) // 5, starts=2, local_runs=1)
    assert r.objective <= best * 1.01
    assert r.evaluations <= len(grid) // 5 and runner.calls == r.evaluations
    assert abs(r.optimum["supply.section2.length"] - L_BEST) < 0.05
    assert r.feasible and r.converged and r.at_bounds == []


def test_2d_active_constraint_found_and_reported():
    # frequency = 100/L >= 80 Hz  ->  L <= 1.25 m: the optimum L = 1.25 m, C = 2 L
    La, Ca = np.linspace(0.5, 4.0, 30), np.linspace(0.2e-3, 4e-3, 30)
    feasible = [amplitude(L, C) for L in La for C in Ca if 100.0 / L >= 80.0]
    best = min(feasible)
    r = optimize(["supply.section2.length=0.5 m..4 m", "supply.accumulator.capacity=0.2 L..4 L"],
                 minimize="supply.amplitude_mpa", subject_to=["supply.frequency_hz>=80"],
                 runner=Analytic(), max_evaluations=len(La) * len(Ca) // 5)
    assert r.feasible and r.metrics["supply.frequency_hz"] >= 80.0 - 1e-6
    assert r.objective <= best * 1.01
    assert r.active_constraints == ["supply.frequency_hz>=80"]
    assert abs(r.optimum["supply.section2.length"] - 1.25) < 1e-3
    assert abs(r.optimum["supply.accumulator.capacity"] - C_BEST) < 0.05e-3


def test_discrete_choice_and_continuous_variable_global_method():
    r = optimize(["supply.section2.length=0.5 m..4 m"],
                 choose=["supply.section2.diameter=12.7 mm,15.9 mm,19.05 mm"],
                 minimize="supply.amplitude_mpa", runner=Analytic(), max_evaluations=120)
    assert r.method == "global"
    assert r.optimum["supply.section2.diameter"] == pytest.approx(D_BEST)
    assert r.objective == pytest.approx(0.5, abs=0.005)


def test_choices_alone_are_all_evaluated():
    runner = Analytic()
    r = optimize(choose=["supply.section2.diameter=12.7 mm,15.9 mm,19.05 mm"],
                 minimize="supply.amplitude_mpa", runner=runner)
    assert runner.calls == 4        # the base rig and the three bores
    assert r.optimum["supply.section2.diameter"] == pytest.approx(D_BEST) and r.converged


def test_every_evaluation_journaled_and_resumed_without_rerunning(tmp_path):
    args = (["supply.section2.length=0.5 m..4 m"],)
    kw = dict(minimize="supply.amplitude_mpa", subject_to=["supply.frequency_hz>=80"],
              out=tmp_path, figure=False)
    first = optimize(*args, runner=Analytic(), **kw)
    lines = (tmp_path / "optimize.jsonl").read_text().splitlines()
    assert len(lines) == 1 + first.n_computed
    with pytest.raises(SweepFileError, match="--resume"):
        optimize(*args, runner=Analytic(), **kw)
    again = Analytic()
    second = optimize(*args, runner=again, resume=True, **kw)
    assert again.calls == 0 and second.n_computed == 0
    assert second.optimum == first.optimum and second.evaluations == first.evaluations
    doc = json.loads((tmp_path / "optimize.json").read_text())
    assert {"optimum", "objective", "metrics", "evaluations", "feasible",
            "active_constraints", "converged"} <= set(doc)
    text = (tmp_path / "optimum.toml").read_text()
    assert "optimised for supply.amplitude_mpa, supply.frequency_hz>=80" in text
    back = load_rig(str(tmp_path / "optimum.toml"))
    assert back.values["supply.section2.length"] == pytest.approx(
        first.optimum["supply.section2.length"])


def test_cost_proxies_by_hand():
    # the 2005 rig: four sections of 3.048 m, two accumulators of 1 L
    c = cost_metrics(load_rig(None).values)
    assert c["total_hose_length_m"] == pytest.approx(4 * 3.048)
    assert c["accumulator_volume_l"] == pytest.approx(2.0)
    assert set(COST_METRICS) <= set(metric_names())
    r = optimize(["supply.section2.length=0.5 m..4 m"], minimize="total_hose_length_m",
                 subject_to=["supply.frequency_hz<=100"], runner=Analytic())
    # shortest hose with 100/L <= 100 Hz: L = 1 m, total 3 x 3.048 m + 1 m
    assert r.optimum["supply.section2.length"] == pytest.approx(1.0, abs=1e-3)
    assert r.objective == pytest.approx(3 * 3.048 + 1.0, abs=1e-3)


def test_real_rig_one_variable_respects_constraint_and_beats_baseline():
    # on [2.5, 3.5] m the supply amplitude falls with the length and the frequency too:
    # frequency >= 38 Hz bounds the length near 3.2 m (baseline 3.048 m: 40 Hz, 1.0 MPa)
    r = optimize(["supply.section2.length=2.5 m..3.5 m"], minimize="supply.amplitude_mpa",
                 subject_to=["supply.frequency_hz>=38"], starts=1, local_runs=1,
                 max_evaluations=14, maxiter=4)
    L = r.optimum["supply.section2.length"]
    assert 2.5 <= L <= 3.5
    # feasible to the optimiser's tolerance, relative to the bound (FEASIBILITY_TOLERANCE)
    assert r.feasible and r.metrics["supply.frequency_hz"] >= 38.0 * (1 - FEASIBILITY_TOLERANCE)
    assert r.objective <= r.baseline_objective
    assert r.evaluations <= 14


@pytest.mark.parametrize("argv, needles", [
    (["--vary", "supply.section2.length=1 m", "--minimize", "supply.amplitude_mpa"],
     ("--vary", "LOW..HIGH")),
    (["--vary", "supply.section2.length=3 m..1 m", "--minimize", "supply.amplitude_mpa"],
     ("--vary supply.section2.length", "LOW must be below HIGH")),
    (["--vary", "supply.section2.length=1..3", "--minimize", "supply.amplitude_mpa"],
     ("supply.section2.length",)),
    (["--vary", "supply.section2.length=1 m..3 m", "--minimize", "supply.amplitude"],
     ("--minimize", "supply.amplitude", "supply.amplitude_mpa")),
    (["--vary", "supply.section2.length=1 m..3 m", "--minimize", "supply.amplitude_mpa",
      "--subject-to", "supply.frequency_hz=>30"], ("--subject-to",)),
    (["--vary", "supply.section2.length=1 m..3 m"], ("--minimize",)),
    (["--minimize", "supply.amplitude_mpa"], ("--vary",)),
    (["--choose", "supply.section2.diameter=12.7 mm", "--minimize", "supply.amplitude_mpa"],
     ("--choose supply.section2.diameter", "two")),
    (["--choose", "supply.section2.diameter=12.7 mm,19 mm", "--method", "local",
      "--minimize", "supply.amplitude_mpa"], ("--method local",)),
])
def test_cli_bad_input_is_one_line_exit_2(capsys, argv, needles):
    rc = main(["optimize", *argv])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in lines[0], err


def test_constraint_syntax():
    c = parse_constraint(" supply.frequency_hz >= 30 ")
    assert (c.metric, c.sense, c.bound) == ("supply.frequency_hz", ">=", 30.0)
    assert c.margin(33.0) == pytest.approx(0.1) and c.margin(math.nan) == -math.inf


def test_two_objective_front_not_dominated_by_a_grid(tmp_path):
    # amplitude 0.5 + (L - 1.7)^2 + (C/L - 2)^2 [MPa] against the accumulator volume C/L + 1
    # (the return accumulator's 1 L): the front is L = 1.7 m, C = 0.2 ... 2 L, by hand
    objectives = ["supply.amplitude_mpa", "accumulator_volume_l"]
    r = optimize(["supply.section2.length=0.5 m..4 m", "supply.accumulator.capacity=0.2 L..4 L"],
                 minimize=objectives, runner=Analytic(), max_evaluations=60, out=tmp_path)
    front = [(p["objectives"][objectives[0]], p["objectives"][objectives[1]]) for p in r.front]
    assert len(front) >= 4
    for (a, v), p in zip(front, r.front):
        C = p["variables"]["supply.accumulator.capacity"]
        assert v == pytest.approx(C * 1e3 + 1.0)
        assert a == pytest.approx(0.5 + (p["variables"]["supply.section2.length"] - L_BEST) ** 2
                                  + (C / 1e-3 - 2.0) ** 2)
    # the ends: the amplitude's minimum (C = 2 L) and the smallest accumulator (0.2 L)
    assert front[0][0] == pytest.approx(0.5, abs=0.005) and r.objective == front[0][0]
    assert front[-1][1] == pytest.approx(1.2, abs=0.005)
    grid = [(amplitude(L, C), C * 1e3 + 1.0) for L in np.linspace(0.5, 4.0, 30)
            for C in np.linspace(0.2e-3, 4e-3, 30)]
    # a grid point dominates a front point beyond tolerance where it is better in both
    # objectives by more than 1 % of the point's value (a point off the front by more than
    # that has front points, and grid points near them, better in both)
    for a, v in front:
        for ga, gv in grid:
            assert not (ga < 0.99 * a and gv < 0.99 * v), ((a, v), (ga, gv))
    doc = json.loads((tmp_path / "optimize.json").read_text())
    assert len(doc["front"]) == len(front)
    assert set(doc["front"][0]) == {"variables", "objectives", "rig"}
    assert (tmp_path / "optimize.png").exists()


def central(f, x, h):
    return (f(x + h) - f(x - h)) / (2 * h)


def test_optimiser_gradients_match_central_differences_on_analytic_metrics():
    # the forward differences SLSQP is given (step 1e-3 of each range) against central
    # differences of the runner (and the hand derivative): within 1 %
    runner = Analytic()
    vary = ["supply.section2.length=0.5 m..4 m", "supply.accumulator.capacity=0.2 L..4 L"]
    at = {"supply.section2.length": 3.0, "supply.accumulator.capacity": 1e-3}

    def metric(name, **change):
        return runner(0, {**at, **change})[name]

    for name, hand in (("supply_amplitude_mpa", (2 * (3.0 - L_BEST), -2.0 / 1e-3)),
                       ("supply_frequency_hz", (-100.0 / 3.0 ** 2, 0.0))):
        g = objective_gradient(vary, minimize=name.replace("_", ".", 1), at=at, runner=runner)
        gl, gc = g["supply.section2.length"], g["supply.accumulator.capacity"]
        cl = central(lambda L: metric(name, **{"supply.section2.length": L}), 3.0, 1e-4)
        cc = central(lambda C: metric(name, **{"supply.accumulator.capacity": C}), 1e-3, 1e-7)
        assert gl == pytest.approx(cl, rel=0.01) and cl == pytest.approx(hand[0], rel=1e-6)
        assert gc == pytest.approx(cc, rel=0.01, abs=1e-9) and cc == pytest.approx(hand[1],
                                                                               abs=1e-6)


def test_optimiser_gradient_matches_central_differences_on_the_real_rig():
    # supply.peak_to_peak_mpa over section II near 3.048 m (0.1 s open-loop step, 5 runs).
    # The optimiser's forward difference of step h is the slope at x + h/2 (to h^2 f'''/24),
    # and so is the central difference about x + h/2 of half-width h (to h^2 f'''/6). A
    # run's metric moves by up to e = 4e-5 MPa with rounding in its rest state (a start
    # 1e-16 apart changes BDF's step sequence at rtol 1e-6; one variant run after 8 others:
    # spread 9e-6 MPa on main, 3.8e-5 with numbers as parameters), so the two differ by at
    # most 2e/h + e/h, plus the truncation 5 h^2 |f'''| / 24 (the slope runs from -0.106 to
    # -0.15 MPa/m over 3.0-3.1 m: f'' ~ -0.45 MPa/m^2; |f'''| < 2 MPa/m^3 taken): at
    # h = 5 cm 2.4e-3 + 5e-4 MPa/m, ~2 % of the slope (at 5 mm the jitter alone is 19 %,
    # and the forward difference's own offset from the slope at x, f'' h / 2, 1 %)
    rig = load_rig(None)
    units = {"supply.section2.length": "m"}
    runner = VariantRunner(rig, "open-loop-step", 0.1, "auto", units, [])
    h, jitter, third = 0.05, 4e-5, 2.0      # (the range is 1 m: the scaled step is h)
    g = objective_gradient(["supply.section2.length=2.5 m..3.5 m"], rig,
                           minimize="supply.peak_to_peak_mpa", step=h, runner=runner)
    c = central(lambda L: runner(0, {"supply.section2.length": L})["supply_peak_to_peak_mpa"],
                3.048 + h / 2, h)
    assert c < 0
    assert g["supply.section2.length"] == pytest.approx(
        c, abs=3 * jitter / h + 5 * h ** 2 * third / 24)


def test_interrupted_run_resumes_running_only_the_missing_evaluations(tmp_path):
    vary = ["supply.section2.length=0.5 m..4 m", "supply.accumulator.capacity=0.2 L..4 L"]
    kw = dict(minimize="supply.amplitude_mpa", subject_to=["supply.frequency_hz>=80"],
              figure=False)
    whole = optimize(vary, runner=Analytic(), **kw)
    first = optimize(vary, runner=Analytic(), out=tmp_path, **kw)
    path = tmp_path / "optimize.jsonl"
    lines = path.read_text().splitlines()
    kept = len(lines[1:]) // 2
    # killed mid-run: the header, half the rows and a row cut short while written
    path.write_text("\n".join(lines[:1 + kept]) + "\n" + lines[1 + kept][:25])
    again = Analytic()
    resumed = optimize(vary, runner=again, out=tmp_path, resume=True, **kw)
    assert again.calls == first.n_computed - kept == resumed.n_computed
    assert resumed.optimum == first.optimum == whole.optimum
    assert resumed.evaluations == first.evaluations
    rows = [json.loads(line) for line in path.read_text().splitlines()[1:]]
    assert len(rows) == first.n_computed        # the cut row dropped, every line whole


def test_dask_cluster_gives_the_in_process_result():
    distributed = pytest.importorskip("distributed")
    vary = ["supply.section2.length=0.5 m..4 m"]
    kw = dict(minimize="supply.amplitude_mpa", subject_to=["supply.frequency_hz>=80"],
              figure=False)
    here = optimize(vary, runner=Analytic(), **kw)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        there = optimize(vary, runner=Analytic(), scheduler=client, **kw)
    assert there.optimum == here.optimum and there.evaluations == here.evaluations
    assert there.n_computed == here.n_computed


# --------------------------------------------------------------------------- bandwidth metric

def test_closed_loop_bandwidth_of_an_integrating_plant_by_hand():
    # H = Kv/s under i = Kp e - Kd v closes to Kv Kp / (s (1 + Kv Kd) + Kv Kp): a first-order
    # lag of corner Kv Kp / (1 + Kv Kd) / (2 pi) [Hz]
    from hydroline.analysis.loop import closed_loop_bandwidth

    f = np.logspace(-3, 3, 6001)
    H = 20.0 / (2j * np.pi * f)
    assert closed_loop_bandwidth(f, H, 1.5) == pytest.approx(30.0 / (2 * np.pi), rel=1e-4)
    assert closed_loop_bandwidth(f, H, 1.5, derivative_gain=0.05) == pytest.approx(
        30.0 / 2.0 / (2 * np.pi), rel=1e-4)


def test_position_bandwidth_of_the_rig_at_low_gain_is_the_valve_integrator_corner():
    # at a gain far below the valve's and the actuator's dynamics the closed loop is the lag
    # of corner Kp Kv / (2 pi), Kv the plant's low-frequency velocity gain [m/(s A)] (read
    # from the valve-current-to-velocity channel at 0.01 Hz, not the position loop); their
    # phase lag at the corner lifts it by ~0.2 % at 0.14 Hz (1.6 % at 1 Hz, 0.15 A/m)
    from hydroline.analysis.frequency import state_space_response
    from hydroline.analysis.linearize import linearize
    from hydroline.analysis.loop import position_bandwidth

    rig = load_rig(None)
    rig.set("controller.proportional_gain", "0.02 A/m")
    sys = linearize(rig, None, ["valve_current"], ["piston_velocity"])
    kv = abs(state_space_response(sys.A, sys.B, sys.C, sys.D, [0.01], sys.state_scales)[0, 0, 0])
    assert position_bandwidth(rig) == pytest.approx(0.02 * kv / (2 * np.pi), rel=0.01)


def test_bandwidth_constraint_on_the_real_rig_is_active_at_its_bound():
    # the least proportional gain whose closed position loop keeps 8 Hz (the rig's 1.5 A/m
    # gives 12.5 Hz): only the linear model runs (no simulation is asked for)
    from hydroline.analysis.loop import position_bandwidth

    r = optimize(["controller.proportional_gain=0.5 A/m..3 A/m"], minimize="position_bandwidth_hz",
                 subject_to=["position_bandwidth_hz>=8"], starts=1, local_runs=1,
                 max_evaluations=12)
    assert "position_bandwidth_hz" in metric_names()
    assert r.feasible and r.active_constraints == ["position_bandwidth_hz>=8"]
    assert r.objective == pytest.approx(8.0, rel=1e-3)
    assert r.baseline_objective > 12.0 and r.metrics["supply.amplitude_mpa"] is None
    rig = load_rig(None)
    rig.set("controller.proportional_gain", f"{r.optimum['controller.proportional_gain']!r} A/m")
    assert position_bandwidth(rig) == pytest.approx(r.objective, rel=1e-9)


# --------------------------------------------------------------------------- rough metrics

STAIR = 0.02        # [MPa] the step of a piecewise-constant (quantised) amplitude


def stair(L, C):
    return 0.5 + STAIR * math.floor(((L - L_BEST) ** 2 + ((C - C_BEST) / 1e-3) ** 2) / STAIR)


class Stepped(Analytic):
    """The bowl of :class:`Analytic` read in steps of 0.02 MPa (as a metric measured on a
    coarse grid or decided by a verdict): its finite-difference gradient is 0 or huge."""

    def __call__(self, index, values):
        row = super().__call__(index, values)
        row["supply_amplitude_mpa"] = stair(values.get("supply.section2.length", 3.048),
                                            values.get("supply.accumulator.capacity", C_BEST))
        return row


@pytest.mark.parametrize("method", ["local", "derivative-free"])
def test_stepped_metric_within_one_percent_of_a_grid_derivative_free(method):
    # SLSQP alone stops on a step (zero gradient: 0.66 and 0.84 MPa here); the local method
    # then goes on with COBYQA from the best point, derivative-free uses COBYQA from the start
    La, Ca = np.linspace(0.5, 4.0, 30), np.linspace(0.2e-3, 4e-3, 30)
    vary = ["supply.section2.length=0.5 m..4 m", "supply.accumulator.capacity=0.2 L..4 L"]
    for bound, cons in ((None, []), (80.0, ["supply.frequency_hz>=80"])):
        best = min(stair(L, C) for L in La for C in Ca if bound is None or 100.0 / L >= bound)
        r = optimize(vary, minimize="supply.amplitude_mpa", subject_to=cons, runner=Stepped(),
                     method=method, max_evaluations=len(La) * len(Ca) // 5)
        assert r.feasible and r.objective <= best * 1.01, (r.objective, best, r.message)
        assert "COBYQA" in r.message
        if bound is not None:
            assert r.active_constraints == ["supply.frequency_hz>=80"]
    if method == "local":
        assert "stalled, COBYQA from the best point" in r.message


# --------------------------------------------------------------------------- Dask, fronts

def test_scheduler_local_and_an_address_give_the_in_process_result():
    distributed = pytest.importorskip("distributed")
    vary = ["supply.section2.length=0.5 m..4 m"]
    kw = dict(minimize="supply.amplitude_mpa", subject_to=["supply.frequency_hz>=80"],
              figure=False)
    here = optimize(vary, runner=Analytic(), **kw)
    # "local": a cluster of one worker process started and closed by optimize
    there = optimize(vary, runner=Analytic(), scheduler="local", workers=1, **kw)
    assert there.optimum == here.optimum and there.n_computed == here.n_computed
    # an address, as --scheduler tcp://host:port: an in-process cluster of two workers
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  protocol="tcp://", host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        remote = optimize(vary, runner=Analytic(), scheduler=cluster.scheduler_address, **kw)
    assert remote.optimum == here.optimum and remote.n_computed == here.n_computed


A3 = ((1.0, 1e-3), (3.0, 1e-3), (2.0, 3e-3))     # the three bowls' centres (L [m], C [m^3])


class ThreeBowls:
    """Three metrics, bowls of equal curvature centred on A3 in (L, C / 1 mm^3 x 1e-3): the
    Pareto set of three such bowls is the triangle of their centres, by hand."""

    def __call__(self, index, values):
        L = values["supply.section2.length"]
        C = values["supply.accumulator.capacity"]
        f = [(L - a) ** 2 + ((C - c) / 1e-3) ** 2 for a, c in A3]
        return {"variant": index, **values, "supply_amplitude_mpa": f[0],
                "return_amplitude_mpa": f[1], "supply_first_excursion_mpa": f[2],
                "error": None}


def _in_triangle(p, tri, tol):
    """Distance of p from the triangle tri (0 inside), in the scaled plane."""
    (x1, y1), (x2, y2), (x3, y3) = tri
    d = (y2 - y3) * (x1 - x3) + (x3 - x2) * (y1 - y3)
    a = ((y2 - y3) * (p[0] - x3) + (x3 - x2) * (p[1] - y3)) / d
    b = ((y3 - y1) * (p[0] - x3) + (x1 - x3) * (p[1] - y3)) / d
    return min(a, b, 1 - a - b) >= -tol


def test_three_objective_front_against_a_grid_and_the_triangle_by_hand(tmp_path):
    objectives = ["supply.amplitude_mpa", "return.amplitude_mpa", "supply.first_excursion_mpa"]
    r = optimize(["supply.section2.length=0.5 m..4 m", "supply.accumulator.capacity=0.2 L..4 L"],
                 minimize=objectives, runner=ThreeBowls(), front_points=5, out=tmp_path,
                 figure=False)
    pts = [[p["objectives"][m] for m in objectives] for p in r.front]
    assert len(pts) >= 10
    # every objective's minimum (0, at its centre) is on the front
    for j in range(3):
        assert min(p[j] for p in pts) == pytest.approx(0.0, abs=1e-3)
    tri = [(a, c / 1e-3) for a, c in A3]
    for p in r.front:
        v = p["variables"]
        assert _in_triangle((v["supply.section2.length"], v["supply.accumulator.capacity"] / 1e-3),
                            tri, 0.02), p
    # no point of a 40 x 40 grid dominates a front point beyond 1 % of its range per objective
    runner = ThreeBowls()
    grid = np.array([[runner(0, {"supply.section2.length": L,
                                 "supply.accumulator.capacity": C})[k]
                      for k in ("supply_amplitude_mpa", "return_amplitude_mpa",
                                "supply_first_excursion_mpa")]
                     for L in np.linspace(0.5, 4.0, 40) for C in np.linspace(0.2e-3, 4e-3, 40)])
    tol = 0.01 * np.ptp(np.array(pts), axis=0)
    for p in np.array(pts):
        assert not np.any(np.all(grid < p - tol, axis=1)), p
    # one rig file per front point, its values those of the point
    doc = json.loads((tmp_path / "optimize.json").read_text())
    assert [p["rig"] for p in doc["front"]] == [f"front_{k:02d}.toml"
                                                for k in range(1, len(r.front) + 1)]
    for p in doc["front"]:
        text = (tmp_path / p["rig"]).read_text()
        assert "# optimised for Pareto front point" in text
        back = load_rig(str(tmp_path / p["rig"]))
        for path, value in p["variables"].items():
            assert back.values[path] == pytest.approx(value, rel=1e-12)


def test_resume_reruns_the_evaluations_without_a_metric_now_asked_for(tmp_path):
    # the first run recorded no settling time (as a run without position_bandwidth_hz records
    # no bandwidth); asked for on resume, those evaluations run again, the others do not
    class WithSettling(Analytic):
        def __call__(self, index, values):
            return {**super().__call__(index, values), "supply_settling_time_s": 0.1}

    vary = ["supply.section2.length=0.5 m..4 m"]
    first = optimize(vary, minimize="supply.amplitude_mpa", runner=Analytic(), out=tmp_path,
                     figure=False)
    again = WithSettling()
    second = optimize(vary, minimize="supply.amplitude_mpa", runner=again, out=tmp_path,
                      subject_to=["supply.settling_time_s<=1"], resume=True, figure=False)
    assert second.optimum == first.optimum and again.calls == second.n_computed == first.evaluations
    third = WithSettling()
    optimize(vary, minimize="supply.amplitude_mpa", runner=third, out=tmp_path,
             subject_to=["supply.settling_time_s<=1"], resume=True, figure=False)
    assert third.calls == 0


def test_stepped_metric_with_a_choice_global_method_then_cobyqa():
    # differential evolution over the length and the capacity's choices, then SLSQP at the
    # best choice, which stalls on a step: COBYQA goes on; within 1 % of a 60 x 3 grid's best
    # in a fifth of its evaluations
    La, Cs = np.linspace(0.5, 4.0, 60), (1e-3, 2e-3, 3e-3)
    best = min(stair(L, C) for L in La for C in Cs)
    r = optimize(["supply.section2.length=0.5 m..4 m"],
                 choose=["supply.accumulator.capacity=1 L,2 L,3 L"],
                 minimize="supply.amplitude_mpa", runner=Stepped(),
                 max_evaluations=len(La) * len(Cs) // 5, seed=3)
    assert r.method == "global" and r.evaluations <= len(La) * len(Cs) // 5
    assert r.objective <= best * 1.01 and "COBYQA" in r.message
    assert r.optimum["supply.accumulator.capacity"] == pytest.approx(C_BEST)


def test_constraint_near_its_bound_everywhere_is_not_reported_active():
    # a metric that hardly moves (0.1 s + 1e-7 s/m x L, as the bandwidth over section II)
    # lies within 0.1 % of a bound 0.05 % above it everywhere: it restricts nothing, so it is
    # not active; the frequency bound that does restrict (L <= 1.25 m) is
    class NearlyConstant(Analytic):
        def __call__(self, index, values):
            row = super().__call__(index, values)
            return {**row, "supply_settling_time_s": 0.1 + 1e-7 * values.get(
                "supply.section2.length", 3.048)}

    r = optimize(["supply.section2.length=0.5 m..4 m"], minimize="supply.amplitude_mpa",
                 subject_to=["supply.settling_time_s<=0.10005", "supply.frequency_hz>=80"],
                 runner=NearlyConstant())
    assert r.feasible and abs(r.optimum["supply.section2.length"] - 1.25) < 1e-3
    assert r.active_constraints == ["supply.frequency_hz>=80"]


def test_a_constraint_value_may_carry_a_unit_of_its_metrics_dimension():
    """``--subject-to`` reads a quantity in the unit the metric's name ends with (by hand:
    5 bar = 0.5 MPa, 30 ms = 0.03 s, 12 Hz), a plain number as that unit, and refuses a unit
    of another dimension in one line naming the metric."""
    from hydroline.studies.optimize import parse_constraint

    assert parse_constraint("supply.amplitude_mpa<=5 bar").bound == pytest.approx(0.5)
    assert parse_constraint("supply.settling_time_s<=30 ms").bound == pytest.approx(0.03)
    assert parse_constraint("position_bandwidth_hz>=12 Hz").bound == 12.0
    assert parse_constraint("accumulator_volume_l<=4").bound == 4.0
    with pytest.raises(RigError, match="supply.amplitude_mpa.*dimension"):
        parse_constraint("supply.amplitude_mpa<=5 m")
