"""Network layer: components wired by named signals, assembled into one explicit ODE."""
from .component import Component, Port, State
from .network import CompiledModel, Network, NetworkError

__all__ = ["Component", "Port", "State", "Network", "NetworkError", "CompiledModel"]
