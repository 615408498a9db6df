"""Transmission-line models: parameters, exact four-pole models, modal state-space lines."""
from .corrections import correction_factors, dissipative_root, modal_angles
from .line import FORM_PORTS, FORMS, Line, bessel_ratio
from .modal import (DEFAULT_LINE_METHOD, LINE_METHODS, ModalLine, RigidColumnLine,
                    StateSpaceLine)

__all__ = ["FORMS", "FORM_PORTS", "Line", "bessel_ratio", "correction_factors",
           "dissipative_root", "modal_angles", "DEFAULT_LINE_METHOD", "LINE_METHODS", "ModalLine", "RigidColumnLine", "StateSpaceLine"]
