"""FMU export: the rig's plant for co-simulation in Simulink, OpenModelica, Dymola or Python.

:func:`export_fmu` writes an FMI 2.0 or 3.0 FMU (Co-Simulation, Model Exchange or both) of a rig's
plant -- hoses, HSM, accumulators, check valve, servovalve, actuator, friction and load --
with inputs ``valve_current`` [A], ``external_force`` [N], ``pump_pressure`` and
``tank_pressure`` [Pa], the port and chamber pressures and the piston position and velocity
as outputs, and the structure-free values (actuator bulk modulus, load mass, friction,
manifold and check-valve resistances) as tunable parameters. See ``docs/fmu.md``.
"""
from .export import C_FLAGS, FMI_VERSIONS, KINDS, export_fmu, platform_folder
from .plant import INPUTS, OUTPUTS, TUNABLES, Plant, Tunable, rest_state, symbolic_model

__all__ = ["export_fmu", "FMI_VERSIONS", "KINDS", "C_FLAGS", "platform_folder", "INPUTS",
           "OUTPUTS", "TUNABLES", "Tunable", "Plant", "rest_state", "symbolic_model"]
