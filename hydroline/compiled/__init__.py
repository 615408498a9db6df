"""The compiled simulation core: a network as C code, built once per machine, run in C.

:func:`native_model` turns an assembled :class:`~hydroline.engine.Network` into a
:class:`NativeModel`: C source for its right-hand side, sparse Jacobian, signals and sparse LU
(:mod:`.codegen`) compiled together with a BDF integrator (``bdf.c``) by the system C
compiler into a shared library. The source holds only the network's structure (its numbers
are passed at run time), so the library is keyed by a hash of the source and kept in a cache
directory: the compile cost (about a second) is paid once per machine and structure, not per
process or per parameter variant.

A model's record (its library, constants and sizes) is kept in the cache directory too, under
:func:`definition_key`: the network's description (components, numbers, wiring, the source of
the code involved), known before its CasADi graph is built. A model seen before is then
loaded without building the graph or importing CasADi; the graph is built for a new model
only (its structure's record then gives the constants without writing C), or where the
network cannot describe itself by value (a component class of another package: its record
is then keyed by the graph's own fingerprint, :func:`model_fingerprint`).

Numbers are parameters: the components' own numbers and the state scales head the constants
array (:func:`~hydroline.compiled.generated.number_prefix`), so networks that differ only in
numbers share one library, recorded under their definition without the numbers
(:func:`numbers_key`). A library not built yet may be built in a background process
(``$HYDROLINE_BACKGROUND_BUILD``, the command line's default) while the run goes on with
CVODES (:class:`LibraryPending`); that build makes a quick ``-O0`` library first, which the
runs that start meanwhile load (:func:`.toolchain.load_library`).

Cache directory: ``$HYDROLINE_CACHE_DIR``, else ``$XDG_CACHE_HOME/hydroline``, else
``~/.cache/hydroline``. Compiler: ``$CC``, else ``cc``/``gcc``/``clang`` on the PATH.
Without a compiler :func:`native_model` raises :class:`CompilerUnavailable` and
:func:`hydroline.engine.integrate` falls back to CasADi's CVODES.

One job a module: :mod:`.toolchain` (the compiler, its flags, the cache of compiled
libraries), :mod:`.native` (the native model and its integrator instance), :mod:`.records`
(the model and structure records), :mod:`.codegen` (the C writer), :mod:`.stability` (the
NDF orders' step limits); their public names are gathered here.
"""
from __future__ import annotations

from ..cache import cache_dir  # noqa: F401  (re-exported)
from .generated import GeneratedModel, UnsupportedOperation  # noqa: F401  (re-exported)
from .native import NativeModel, NativeSolver, native_model, needs_build
from .records import definition_key, model_fingerprint, numbers_key
from .toolchain import (CFLAGS, MAX_LIBRARIES, NATIVE_FLAGS, PORTABLE_ENV, CompilerUnavailable,
                        LibraryPending, available, native_flags, prune_libraries)

__all__ = ["native_model", "NativeModel", "NativeSolver", "CompilerUnavailable", "cache_dir",
           "available", "CFLAGS", "native_flags", "model_fingerprint", "definition_key",
           "prune_libraries", "MAX_LIBRARIES", "needs_build", "NATIVE_FLAGS", "PORTABLE_ENV",
           "numbers_key", "LibraryPending"]

#: :mod:`.codegen`'s functions, re-exported; imported (and CasADi with them) on first use: a
#: model whose record is known is loaded without them.
_FROM_CODEGEN = ("generate", "scaled_functions", "structure_key", "constant_positions",
                 "constants_at")


def __getattr__(name):
    if name in _FROM_CODEGEN:
        from . import codegen

        return getattr(codegen, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
