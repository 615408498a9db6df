"""Physical components, one module each. Each declares ports, states and equations."""
from .accumulator import PistonAccumulator
from .actuator import Actuator
from .check_valve import CheckValve
from .commands import RampCommand, SineCommand, StepCommand, TableCommand
from .controller import PositionController
from .friction import StribeckFriction
from .hose import HoseSection
from .junction import FlowJunction
from .load import Load
from .pump import Pump
from .relief_valve import ReliefValve
from .resistance import LinearResistance
from .servovalve import Servovalve, valve_coefficient
from .sources import PressureSource
from .volume import HydraulicVolume

__all__ = ["PistonAccumulator", "Actuator", "CheckValve", "RampCommand", "SineCommand",
           "StepCommand", "TableCommand", "PositionController", "StribeckFriction",
           "HoseSection", "FlowJunction", "Load", "LinearResistance", "Servovalve",
           "valve_coefficient", "PressureSource", "HydraulicVolume", "Pump", "ReliefValve"]
