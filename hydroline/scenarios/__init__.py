"""Experiments on a rig: the open-loop step and the closed-loop sine (the paper's tests), the
multi-axis position step and a rig's own command per axis; running them and summarizing the runs.

``simulate(rig, scenario, t_end)`` builds the network of the rig with the scenario's command
components, solves its steady state before the disturbance, integrates, checks validity
(pressures below the gas-release pressure) and returns a
:class:`~hydroline.engine.SimulationResult` whose ``metadata`` holds what the summary needs.

One job a module:

* :mod:`hydroline.scenarios.experiments`: the experiments and the command components they
  build (:func:`build_scenario`);
* :mod:`hydroline.scenarios.running`: :func:`simulate` and the :class:`Simulation` whose model
  cache a repeated run reuses, the validity checks of a run;
* :mod:`hydroline.scenarios.summaries`: the metrics window and the summary of a run
  (:func:`summarize`).

The names below are those of the modules, gathered here.
"""
from .experiments import (EXPERIMENTS, OWN_EXPERIMENTS, SCENARIOS, AxisCommand, AxisCommands,
                          ClosedLoopSine, Experiment, OpenLoopStep, PositionStep, Scenario,
                          build_scenario, default_scenario, experiment, hold_other_axes,
                          scenario_names, template_controller)
from .running import (CAVITATION_PRESSURE, DEFAULT_SIMULATION, WATCHED_NODES, WATCHED_PRESSURES,
                      Simulation, check_cavitation, describe_run, rest_state, simulate,
                      watched_pressures)
from .summaries import SineSummaryStream, metrics_window, ripple_metrics, summarize

__all__ = ["SCENARIOS", "EXPERIMENTS", "OWN_EXPERIMENTS", "Experiment", "OpenLoopStep",
           "ClosedLoopSine", "PositionStep", "AxisCommand", "AxisCommands", "experiment",
           "scenario_names", "simulate", "summarize", "SineSummaryStream", "build_scenario",
           "Scenario", "default_scenario", "hold_other_axes", "template_controller", "rest_state",
           "ripple_metrics", "Simulation", "DEFAULT_SIMULATION", "describe_run",
           "metrics_window", "watched_pressures", "check_cavitation", "CAVITATION_PRESSURE",
           "WATCHED_NODES", "WATCHED_PRESSURES"]
