"""What the C writer (:mod:`.codegen`) produces for a network, as plain data: kept apart from
the writer so that a model loaded from its record needs no CasADi."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["GeneratedModel", "UnsupportedOperation", "number_prefix"]


class UnsupportedOperation(NotImplementedError):
    """The graph holds an operation the C writer does not know (the caller falls back).

    Parameters
    ----------
    *args : str
        The message: the operation.
    **kwargs : dict
        None taken (as ``NotImplementedError``).
    """


@dataclass
class GeneratedModel:
    """C source of one network structure and the constants of this network's values.

    Attributes
    ----------
    source : str
        C code (structure only)
    key : str
        SHA-256 of the source, the cache key
    constants : ndarray
        Values read by the code as ``c[k]``, [SI]
    n_states, n_parameters, n_signals, jac_nnz, lu_slots, lu_flops : int
        Sizes, [-]
    jac_colind, jac_row : ndarray
        Compressed-column pattern of the Jacobian (indices), [-]
    """

    source: str
    key: str
    constants: np.ndarray
    n_states: int
    n_parameters: int
    n_signals: int
    jac_nnz: int
    jac_colind: np.ndarray
    jac_row: np.ndarray
    lu_slots: int
    lu_flops: int


def number_prefix(network) -> np.ndarray:
    """The start of the constants array of a model whose C takes the components' numbers at
    run time (:func:`hydroline.compiled.codegen.scaled_functions`): the numbers
    (:meth:`~hydroline.engine.Network.compiled_numbers`), the state scales, then their
    inverses (the C multiplies by them: a division costs as much as a hose section's
    derivative), [SI].

    Parameters
    ----------
    network : Network
        The assembled model

    Returns
    -------
    ndarray
        [SI]
    """
    scales = np.asarray(network.state_scales, dtype=float)
    return np.concatenate([network.compiled_numbers()[1], scales, 1.0 / scales])
