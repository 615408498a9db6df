"""Analysis of simulated and measured traces."""
from .metrics import oscillation_amplitude, oscillation_frequency, settling_time

__all__ = ["oscillation_frequency", "oscillation_amplitude", "settling_time"]
