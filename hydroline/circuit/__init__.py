"""Circuits as data: component types with declared parameters, the builder, axis handles.

See :mod:`hydroline.circuit.builder` for the file format and :mod:`hydroline.circuit.types`
for the component types.
"""
from .builder import (Axis, Circuit, axes_of, check_circuit, check_circuit_value,
                      circuit_components, circuit_names, has_circuit, parse_circuit_value, rewire)
from .types import COMPONENT_TYPES, CircuitError, ComponentType

__all__ = ["Axis", "Circuit", "axes_of", "check_circuit", "check_circuit_value",
           "circuit_components", "circuit_names", "has_circuit", "parse_circuit_value", "rewire",
           "COMPONENT_TYPES", "CircuitError", "ComponentType"]
