"""Records of compiled models in the cache directory, so that a model seen before is loaded
without writing its C (and, under :func:`definition_key`, without building its CasADi graph
or importing CasADi): a model's record (its library, constants and sizes) under its
definition or its graph's fingerprint (:func:`model_fingerprint`), and a structure's record
(its library and where its constants sit in the graph) for a model of known structure with
other numbers. A record that does not fit the model it is found for is discarded with a
warning naming its file.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from ..cache import discard_table, load_table, source_tag, store_table
from .generated import GeneratedModel, number_prefix
from .toolchain import BDF_SOURCE, build_settings

__all__ = ["model_fingerprint", "definition_key", "known_model", "known_structure",
           "structure_record_key", "remember_structure", "remember_model", "forget_record",
           "numbers_key", "known_numbers_model", "remember_numbers_model", "REST_STATES",
           "recorded_rest_state", "record_rest_state"]

#: The compiled core's code generation, native model, records and integrator: a change makes
#: old model records unused.
_CODE_TAG = source_tag(Path(__file__), Path(__file__).with_name("native.py"),
                       Path(__file__).with_name("codegen.py"), BDF_SOURCE)
_MODELS: dict = {}


def model_fingerprint(model) -> str:
    """SHA-256 of a compiled model's CasADi graph (structure and numbers), its state scales
    and this machine's build settings: the same fingerprint means the same C code and the
    same constants, so the code generation can be skipped.

    Parameters
    ----------
    model : CompiledModel
        The network's CasADi functions (:class:`hydroline.engine.CompiledModel`)

    Returns
    -------
    str
        Hex digest.
    """
    scales = np.asarray(model.network.state_scales, dtype=float).tobytes()
    return _hash_parts(model.f.serialize(), model.signals.serialize(), _CODE_TAG,
                       build_settings(), scales)


def _hash_parts(*parts) -> str:
    """SHA-256 (hex) of text and byte parts, each closed by a zero byte (a record's key)."""
    h = hashlib.sha256()
    for part in parts:
        h.update(part.encode() if isinstance(part, str) else part)
        h.update(b"\0")
    return h.hexdigest()


_ARRAYS = ("constants", "jac_colind", "jac_row")
_SCALARS = ("key", "n_states", "n_parameters", "n_signals", "jac_nnz", "lu_slots", "lu_flops")


def definition_key(network) -> str | None:
    """Key of a model's record that is known before its CasADi graph is built: the network's
    :meth:`~hydroline.engine.Network.definition_fingerprint` (components, numbers, wiring,
    state scales, the source of the code involved) with this module's code tag and the
    build settings (compiler flags, platform, CPU); None where the network gives none.

    Parameters
    ----------
    network : Network
        The assembled model

    Returns
    -------
    str or None
        The key, ``"definition:<hex digest>"``; None where the network gives none.
    """
    describe = getattr(network, "definition_fingerprint", None)
    digest = describe() if describe is not None else None
    if digest is None:
        return None
    return "definition:" + _hash_parts("definition", digest, _CODE_TAG, build_settings())


_NUMBERS: dict = {}


def numbers_key(network) -> str | None:
    """Key of the record of a model whose C takes the components' numbers at run time, known
    before its CasADi graph is built: the network's definition without those numbers
    (:meth:`~hydroline.engine.Network.definition_fingerprint` with ``structure``), this
    module's code tag and the build settings; None where the network gives none. Networks
    that differ only in numbers share it, and the library it names.

    Parameters
    ----------
    network : Network
        The assembled model

    Returns
    -------
    str or None
        The key, ``"numbers:<hex digest>"``; None where the network gives none.
    """
    describe = getattr(network, "definition_fingerprint", None)
    try:
        digest = describe(structure=True) if describe is not None else None
    except TypeError:     # a network that cannot leave its numbers out
        digest = None
    if digest is None:
        return None
    return "numbers:" + _hash_parts("numbers", digest, _CODE_TAG, build_settings())


def known_numbers_model(key: str | None, network):
    """(GeneratedModel with this network's numbers and no source, library tag) of a structure
    whose C takes the components' numbers at run time, seen before (this process or the
    cache directory): its constants are this network's numbers and state scales
    (:func:`~hydroline.compiled.generated.number_prefix`) followed by the graph's own; (None,
    None) if unknown. A record that does not fit the network is discarded with a warning.

    Parameters
    ----------
    key : str
        :func:`numbers_key` of the network; None: unknown
    network : Network
        The assembled model the record must fit

    Returns
    -------
    tuple
        ``(GeneratedModel, library tag)``, or ``(None, None)`` when unknown.
    """
    if key is None:
        return None, None
    rec = _NUMBERS.get(key)
    if rec is None:
        rec = load_table("models", key)
        if rec is None:
            return None, None
        _NUMBERS[key] = rec
    try:
        prefix = number_prefix(network)
        gen = GeneratedModel(source="", **{k: rec[k] for k in _SCALARS},
                             constants=np.concatenate([prefix, np.asarray(rec["constants"],
                                                                          dtype=float)]),
                             jac_colind=np.asarray(rec["jac_colind"], dtype=np.int64),
                             jac_row=np.asarray(rec["jac_row"], dtype=np.int64))
        why = _misfit(gen, network) or ("its numbers do not fit the model"
                                         if len(prefix) != rec["n_prefix"] else "")
        if not why:
            return gen, str(rec["library"])
    except (TypeError, KeyError, ValueError):
        why = "its record is incomplete"
    _NUMBERS.pop(key, None)
    discard_table("models", key, why=why)
    return None, None


def remember_numbers_model(key: str | None, gen, n_prefix: int, library_path: Path) -> None:
    """Record a model whose C takes the components' numbers at run time under its
    :func:`numbers_key` (its library, sizes and the graph's own constants: those after the
    ``n_prefix`` numbers and scales), in this process and, the first time, in the cache
    directory.

    Parameters
    ----------
    key : str
        :func:`numbers_key` of the network (None: not recorded)
    gen : GeneratedModel
        The model
    n_prefix : int
        Its constants' numbers and state scales, [-]
    library_path : Path
        Its library in the cache directory
    """
    if key is None or key in _NUMBERS:
        return
    rec = {k: getattr(gen, k) for k in _SCALARS}
    rec.update({k: np.asarray(getattr(gen, k)).tolist() for k in _ARRAYS},
               library=library_path.stem[3:], n_prefix=int(n_prefix))
    rec["constants"] = rec["constants"][n_prefix:]
    _NUMBERS[key] = rec
    store_table("models", key, rec)


def known_model(fingerprint: str | None, network):
    """(GeneratedModel without its source, library tag) of a model seen before, in this
    process or recorded in the cache directory; (None, None) if unknown. A record that does
    not fit the network (its sizes, its Jacobian pattern) is discarded with a warning naming
    its file.

    Parameters
    ----------
    fingerprint : str
        The model's record key (:func:`definition_key`,
        :func:`model_fingerprint`); None: unknown
    network : Network
        The assembled model the record must fit

    Returns
    -------
    tuple
        ``(GeneratedModel, library tag)``, or ``(None, None)`` when unknown.
    """
    if fingerprint is None:
        return None, None
    known = _MODELS.get(fingerprint)
    if known is None:
        rec = load_table("models", fingerprint)
        if rec is None:
            return None, None
        try:
            gen = GeneratedModel(source="", **{k: rec[k] for k in _SCALARS},
                                 constants=np.asarray(rec["constants"], dtype=float),
                                 jac_colind=np.asarray(rec["jac_colind"], dtype=np.int64),
                                 jac_row=np.asarray(rec["jac_row"], dtype=np.int64))
            known = (gen, str(rec["library"]))
        except (TypeError, KeyError, ValueError):
            known = (None, None)
        _MODELS[fingerprint] = known   # on disk already: not written again
    why = _misfit(known[0], network)
    if why:
        _MODELS.pop(fingerprint, None)
        discard_table("models", fingerprint, why=why)
        return None, None
    return known


def _misfit(gen, network) -> str:
    """What makes a model read from a record unfit for ``network`` ("" when nothing): its
    sizes (states, parameters, signals) or its Jacobian's compressed-column pattern."""
    if gen is None:
        return "its record is incomplete"
    n = len(network.state_names)
    if (gen.n_states, gen.n_parameters, gen.n_signals) != (
            n, len(network.parameter_names), len(network.signal_names)):
        return "its sizes do not fit the model"
    colind, row = np.asarray(gen.jac_colind), np.asarray(gen.jac_row)
    if not (colind.shape == (n + 1,) and colind[0] == 0 and np.all(np.diff(colind) >= 0)
            and colind[-1] == gen.jac_nnz == row.size
            and (row.size == 0 or (row.min() >= 0 and row.max() < n))):
        return "its Jacobian pattern does not fit the model"
    return ""


_STRUCTURES: dict = {}


def structure_record_key(functions) -> str:
    """Key of a structure's record: the graph's listing with constants masked, this module's
    code and the build settings (compiler flags, platform, CPU: the record names a library
    built with them).

    Parameters
    ----------
    functions : object
        The model's scaled CasADi functions
        (:func:`hydroline.compiled.codegen.scaled_functions`)

    Returns
    -------
    str
        The key.
    """
    settings = hashlib.sha256(build_settings().encode()).hexdigest()[:16]
    from .codegen import structure_key

    return structure_key(functions) + _CODE_TAG + settings


def known_structure(functions, key: str, network):
    """(GeneratedModel with this model's constants and no source, library tag) when a model
    of the same structure (record key ``key``, :func:`structure_record_key`) was generated
    before (this process or recorded on disk): only the constants are read from the graph;
    (None, None) otherwise. A record that does not fit (its sizes, its Jacobian pattern, its
    constants' positions) is discarded with a warning naming its file.

    Parameters
    ----------
    functions : object
        The model's scaled CasADi functions
    key : str
        The structure's record key (:func:`structure_record_key`)
    network : Network
        The assembled model the record must fit

    Returns
    -------
    tuple
        ``(GeneratedModel, library tag)``, or ``(None, None)`` when unknown.
    """
    rec = _STRUCTURES.get(key)
    if rec is None:
        rec = load_table("structures", key)
        if rec is None:
            return None, None
        _STRUCTURES[key] = rec
    try:
        from .codegen import constants_at

        constants = constants_at(functions, rec["positions"], network)
        gen = GeneratedModel(source="", **{k: rec[k] for k in _SCALARS}, constants=constants,
                             jac_colind=np.asarray(rec["jac_colind"], dtype=np.int64),
                             jac_row=np.asarray(rec["jac_row"], dtype=np.int64))
        why = _misfit(gen, network) or (
            "its constants do not fit the model" if len(constants) != rec["n_constants"] else "")
        if not why:
            return gen, str(rec["library"])
    except (TypeError, KeyError, ValueError, RuntimeError):
        why = _misfit(None, network)
    _STRUCTURES.pop(key, None)
    discard_table("structures", key, why=why)
    return None, None


def remember_structure(functions, gen, library_path: Path) -> None:
    """Record a newly generated structure (its library and where its constants sit in the
    graph), in this process and in the cache directory.

    Parameters
    ----------
    functions : object
        The model's scaled CasADi functions
    gen : GeneratedModel
        The generated model
    library_path : Path
        Its library in the cache directory
    """
    from .codegen import constant_positions

    positions = constant_positions(functions)
    prefix = functions[0].nnz_in(3) if functions[0].n_in() == 4 else 0   # numbers, scales
    if prefix + sum(map(len, positions)) != len(gen.constants):
        return   # not the order generate() numbers
    rec = {k: getattr(gen, k) for k in _SCALARS}
    rec.update(jac_colind=np.asarray(gen.jac_colind).tolist(),
               jac_row=np.asarray(gen.jac_row).tolist(), positions=positions,
               n_constants=len(gen.constants), library=library_path.stem[3:])
    key = structure_record_key(functions)
    _STRUCTURES[key] = rec
    store_table("structures", key, rec)


def remember_model(fingerprint: str, gen, library_path: Path) -> None:
    """Record a model (its library, constants and sizes) under ``fingerprint``, in this
    process and, the first time, in the cache directory.

    Parameters
    ----------
    fingerprint : str
        The model's record key (:func:`definition_key`,
        :func:`model_fingerprint`)
    gen : GeneratedModel
        The model
    library_path : Path
        Its library in the cache directory
    """
    tag = library_path.stem[3:]
    if fingerprint in _MODELS:
        return
    _MODELS[fingerprint] = (gen, tag)
    rec = {k: getattr(gen, k) for k in _SCALARS}
    rec.update({k: np.asarray(getattr(gen, k)).tolist() for k in _ARRAYS}, library=tag)
    store_table("models", fingerprint, rec)


def forget_record(record: tuple, model_key: str | None, why: str) -> None:
    """Discard a record that does not fit the model it was found for, in the cache directory
    (with a warning naming its file and ``why``) and in this process.

    Parameters
    ----------
    record : tuple
        (table kind, key): ("models", key) or ("structures", key)
    model_key : str
        The model's record key (:func:`definition_key` or
        :func:`model_fingerprint`)
    why : str
        What does not fit, for the warning
    """
    discard_table(*record, why=why)
    _MODELS.pop(model_key, None)
    _STRUCTURES.pop(record[1], None)
    _NUMBERS.pop(record[1], None)


#: Table kind (:mod:`hydroline.cache`) of the rest states solved on compiled models
#: (:func:`hydroline.engine.solve_steady_state` with ``recorded``).
REST_STATES = "rest_states"


def recorded_rest_state(key: str):
    """The rest state recorded under ``key`` (:func:`record_rest_state`), as stored.

    Parameters
    ----------
    key : str
        Everything the rest state depends on (the model's numbers record key, its numbers,
        the start, the solver's settings and code)

    Returns
    -------
    dict or None
        The stored value; None where none is (or the entry failed its check).
    """
    return load_table(REST_STATES, key)


def record_rest_state(key: str, value: dict) -> None:
    """Record a solved rest state under ``key`` in the cache (a failed write is let go).

    Parameters
    ----------
    key : str
        As :func:`recorded_rest_state`
    value : dict
        JSON value: the states and parameters (as ``float.hex`` text), the residual and
        the solver's counts
    """
    store_table(REST_STATES, key, value)
