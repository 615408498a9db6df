"""Transmission-line models: parameters, exact four-pole models, modal state-space lines."""
from .line import FORMS, FORM_PORTS, Line, bessel_ratio

__all__ = ["FORMS", "FORM_PORTS", "Line", "bessel_ratio"]
