"""Analysis of simulated and measured traces."""
from .metrics import (first_excursion, oscillation_amplitude, oscillation_baseline,
                      oscillation_frequency, overshoot, peak_to_peak, port_settling,
                      pressure_metrics, settling_time)
from .linearize import OperatingPoint, OperatingPointError, linearize, solve_operating_point
from .frequency import bandwidth, bode_analysis, line_coupled_model, resonances
from .fit import DataError, fit_parameters, read_measurements
from .friction_id import fit_stribeck, identify_friction

__all__ = ["oscillation_frequency", "oscillation_amplitude", "oscillation_baseline", "overshoot",
           "first_excursion", "peak_to_peak", "pressure_metrics", "port_settling", "settling_time",
           "OperatingPoint", "OperatingPointError", "linearize", "solve_operating_point",
           "bandwidth", "bode_analysis", "line_coupled_model", "resonances",
           "DataError", "fit_parameters", "read_measurements", "fit_stribeck", "identify_friction"]
