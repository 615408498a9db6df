"""Circuits as data: component types with declared parameters, the builder, axis handles.

See :mod:`hydroline.circuit.builder` for the file format and :mod:`hydroline.circuit.types`
for the component types.
"""
from .builder import (Axis, Circuit, ComponentSpec, axes_of, build_components, check_circuit,
                      check_circuit_value, circuit_components, circuit_names, circuit_specs,
                      has_circuit, parse_circuit_value, rewire, rig_fluid)
from .types import COMPONENT_TYPES, CircuitError, ComponentType

__all__ = ["Axis", "Circuit", "ComponentSpec", "axes_of", "build_components", "check_circuit",
           "check_circuit_value", "circuit_components", "circuit_names", "circuit_specs",
           "has_circuit", "parse_circuit_value", "rewire", "rig_fluid",
           "COMPONENT_TYPES", "CircuitError", "ComponentType"]
