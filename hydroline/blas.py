"""One BLAS thread for hydroline's small dense matrices.

The models' dense matrices are small (58-208 states): a BLAS library's extra threads only spin
against each other and against the other processes of a busy machine (25 steady-state solves
of the default rig took 2.1 s with OpenBLAS's threads on a loaded 2-core machine, against
5 ms with one). A command line process asks for one thread before NumPy loads
(:func:`single_threaded_blas`); a sweep's worker processes are started with it; and inside a
program, where NumPy is loaded already, :func:`one_blas_thread` sets OpenBLAS's thread count
to one for the duration of hydroline's own solves and gives the program's back afterwards.
"""
from __future__ import annotations

import contextlib
import os
import re
import sys

__all__ = ["BLAS_THREAD_VARIABLES", "single_threaded_blas", "blas_thread_variables_set",
           "one_blas_thread", "openblas_controls"]

#: Thread-count variables of the BLAS libraries NumPy and SciPy may be built with.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
#: OpenBLAS's thread-count functions, (set, get), by the names of its builds (NumPy's and
#: SciPy's wheels, a system library)
_OPENBLAS_FUNCTIONS = (("scipy_openblas_set_num_threads64_", "scipy_openblas_get_num_threads64_"),
                       ("scipy_openblas_set_num_threads", "scipy_openblas_get_num_threads"),
                       ("openblas_set_num_threads64_", "openblas_get_num_threads64_"),
                       ("openblas_set_num_threads", "openblas_get_num_threads"))


def single_threaded_blas() -> None:
    """Ask the BLAS library for one thread, unless the user set a count (to take effect, call
    before NumPy is imported)."""
    for name in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(name, "1")


@contextlib.contextmanager
def blas_thread_variables_set():
    """Within: the BLAS thread-count variables this process's environment lacks are set to
    one (processes started meanwhile, e.g. a sweep's workers, get one BLAS thread); removed
    again afterwards (the user's own settings are kept)."""
    added = [name for name in BLAS_THREAD_VARIABLES if name not in os.environ]
    for name in added:
        os.environ[name] = "1"
    try:
        yield
    finally:
        for name in added:
            os.environ.pop(name, None)


#: Modules that load a BLAS library of their own (NumPy's and SciPy's wheels each bring one)
_BLAS_MODULES = ("numpy", "scipy.linalg")
_CONTROLS: dict = {}


def openblas_controls() -> list:
    """(set, get) thread-count functions of every OpenBLAS loaded in this process (found in
    its memory map, Linux), looked up again when another module that brings one has been
    loaded; empty where none is found.

    Returns
    -------
    list
        (set(n), get() -> n) pairs of ctypes functions, one per OpenBLAS
    """
    loaded = tuple(m in sys.modules for m in _BLAS_MODULES)
    if loaded not in _CONTROLS:
        _CONTROLS.clear()
        found = _CONTROLS[loaded] = []
        try:
            import ctypes

            with open("/proc/self/maps") as f:
                paths = sorted(set(re.findall(r"(/\S*openblas\S*\.so\S*)", f.read())))
            for path in paths:
                lib = ctypes.CDLL(path)     # (the library loaded already: its handle)
                for set_name, get_name in _OPENBLAS_FUNCTIONS:
                    if hasattr(lib, set_name) and hasattr(lib, get_name):
                        setter, getter = getattr(lib, set_name), getattr(lib, get_name)
                        setter.argtypes, setter.restype = [ctypes.c_int], None
                        getter.argtypes, getter.restype = [], ctypes.c_int
                        found.append((setter, getter))
                        break
        except (OSError, AttributeError):
            pass
    return _CONTROLS[loaded]


@contextlib.contextmanager
def one_blas_thread():
    """Within: every loaded OpenBLAS runs on one thread; its thread count is given back
    afterwards. NumPy must be loaded (a process that loads it later gets its own settings).
    Where no OpenBLAS is found (another BLAS, another platform) it does nothing."""
    controls = openblas_controls() if "numpy" in sys.modules else []
    saved = []
    for setter, getter in controls:
        n = getter()
        if n != 1:
            setter(1)
            saved.append((setter, n))
    try:
        yield
    finally:
        for setter, n in saved:
            setter(n)
