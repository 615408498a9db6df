"""hydroline: electrohydraulic servo systems with the dynamics of their supply and return hoses."""
from .fluid import MINERAL_OIL, Fluid, effective_bulk_modulus
from .rigs import Rig, load_rig
from .scenarios import simulate, summarize
from . import analysis, studies   # hydroline.studies.layout(...), hydroline.analysis.linearize(...)

__version__ = "0.1.0"
__all__ = ["Fluid", "MINERAL_OIL", "effective_bulk_modulus", "Rig", "load_rig", "simulate",
           "summarize", "analysis", "studies", "__version__"]
