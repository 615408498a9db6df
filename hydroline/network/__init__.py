"""Compatibility names: the network layer now lives in :mod:`hydroline.engine`
(``hydroline.engine.component``, ``.network``, ``.ops``). ``from hydroline.network import
Network, ops`` keeps working; new code imports from :mod:`hydroline.engine`."""
from ..engine import ops
from ..engine.component import Component, Parameter, Port, State, parameter
from ..engine.network import CompiledModel, Network, NetworkError

__all__ = ["Component", "Port", "State", "Parameter", "parameter", "Network", "NetworkError",
           "CompiledModel", "ops"]
