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

Cache directory: ``$HYDROLINE_CACHE_DIR``, else ``$XDG_CACHE_HOME/hydroline``, else
``~/.cache/hydroline``. Compiler: ``$CC``, else ``cc``/``gcc``/``clang`` on the PATH.
Without a compiler :func:`native_model` raises :class:`CompilerUnavailable` and
:func:`hydroline.engine.integrate` falls back to CasADi's CVODES.
"""
from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..cache import cache_dir  # noqa: F401  (re-exported)
from ..cache import (discard_entry, discard_table, least_recently_used, load_table, mark_used,
                     source_tag, store_table)
from .generated import GeneratedModel, UnsupportedOperation  # noqa: F401  (re-exported)

__all__ = ["native_model", "NativeModel", "NativeSolver", "CompilerUnavailable", "cache_dir",
           "available", "CFLAGS", "native_flags", "model_fingerprint", "definition_key",
           "prune_libraries", "MAX_LIBRARIES", "needs_build"]

#: :mod:`.codegen`'s functions, re-exported; imported (and CasADi with them) on first use: a
#: model whose record is known is loaded without them.
_FROM_CODEGEN = ("generate", "scaled_functions", "structure_key", "constant_positions",
                 "constants_at")


def __getattr__(name):
    if name in _FROM_CODEGEN:
        from . import codegen

        return getattr(codegen, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

#: Flags for the system compiler (no -ffast-math: the integrator relies on IEEE semantics;
#: -fno-math-errno only lets sqrt compile to one instruction; -ffp-contract=fast lets a*b+c
#: be one fused multiply-add, rounded once, which ISO C mode otherwise forbids: 0.86x the CPU
#: of an integration, mostly in the sparse back-solves, same error, benchmarks/README.md).
#: The library is built for this machine's CPU (``-march=native``, dropped where the compiler
#: refuses it, or where ``$HYDROLINE_PORTABLE_BUILD`` is set to anything but ``0``: see
#: :func:`native_flags`), so the cache key includes the CPU model and the flags.
CFLAGS = ["-O3", "-fno-math-errno", "-ffp-contract=fast", "-shared", "-fPIC", "-std=c99"]
NATIVE_FLAGS = ["-march=native"]
#: Environment variable that asks for a portable build (no ``-march=native``: baseline x86-64,
#: no fused multiply-add on that target), e.g. for a cache shared by different CPUs
PORTABLE_ENV = "HYDROLINE_PORTABLE_BUILD"
_BDF_SOURCE = Path(__file__).with_name("bdf.c")
_LIBS: dict = {}
#: Most compiled libraries kept in the cache directory (one per network structure and
#: machine, ~0.1-0.3 MB each): beyond it the least recently used are removed after a build
#: (a removed one is compiled again when its structure comes back), [-]
MAX_LIBRARIES = 200


class CompilerUnavailable(RuntimeError):
    """No working C compiler: the compiled core cannot be built on this machine."""


class _RecordMismatch(Exception):
    """A model or structure record of the cache does not fit the model it was found for: the
    record is discarded and the model built without records."""


def _compiler() -> str | None:
    cc = os.environ.get("CC")
    if cc and shutil.which(cc):
        return shutil.which(cc)
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


def available() -> bool:
    """True when a C compiler is on the PATH (the compiled core can be built)."""
    return _compiler() is not None


@functools.lru_cache(maxsize=None)
def _cpu_id() -> str:
    """This CPU's model and instruction-set flags: ``-march=native`` code built on one CPU may
    not run on another (a cache on a shared home directory), so both enter the cache key."""
    keep = ("model name", "flags", "features", "cpu model", "isa")
    lines = []
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                key = line.split(":", 1)[0].strip().lower()
                if key in keep and line not in lines:
                    lines.append(line)
                elif not line.strip() and lines:
                    break    # the first processor's block is enough
    except OSError:
        pass
    return "".join(lines) or (platform.machine() + platform.processor())


@functools.lru_cache(maxsize=None)
def _bdf_source() -> str:
    return _BDF_SOURCE.read_text()


def native_flags() -> list[str]:
    """The CPU-specific compiler flags of a build: :data:`NATIVE_FLAGS`, or none when
    ``$HYDROLINE_PORTABLE_BUILD`` is set (and not ``0``). Read at each build, so a process
    can build both kinds; their libraries and records have separate cache keys."""
    portable = os.environ.get(PORTABLE_ENV, "").strip() not in ("", "0")
    return [] if portable else list(NATIVE_FLAGS)


def _build_settings() -> str:
    """What a library's machine code depends on besides its source: the compiler flags, the
    platform and this CPU."""
    return " ".join(CFLAGS + native_flags()) + sys.platform + _cpu_id()


def _library_key(full: str) -> str:
    """A library's cache key: SHA-256 (hex) of its source and the build settings; its file is
    named by the first 32 digits, its build record holds all 64."""
    return hashlib.sha256((full + _build_settings()).encode()).hexdigest()


def _library_path(gen: GeneratedModel) -> tuple[Path, str]:
    full = gen.source + "\n" + _bdf_source()
    return cache_dir() / f"hl_{_library_key(full)[:32]}.so", full


def _digest(path: Path) -> tuple[int, str]:
    """(size [bytes], SHA-256) of a file."""
    data = path.read_bytes()
    return len(data), hashlib.sha256(data).hexdigest()


def _record_path(path: Path) -> Path:
    return path.with_suffix(".sha256")


def _library_check(path: Path) -> tuple[bool, str]:
    """Whether the cached library at ``path`` is the file its build recorded (size, SHA-256,
    and the key it was built for, of which its name is the start). Checked before the
    library is loaded: a truncated, overwritten or foreign file mapped into the process
    would crash it (SIGBUS, SIGSEGV) instead of raising.

    Returns (True, "") when it is; (False, "") when there is nothing to check (no library;
    no record, or a record of the format before keys: a quiet miss); (False, why) when it
    fails its record (to be said in a warning)."""
    try:
        size = path.stat().st_size
        fields = _record_path(path).read_text().split()
    except (OSError, UnicodeDecodeError):
        return False, ""
    if len(fields) == 2:
        return False, ""
    if len(fields) != 3 or not fields[0].isdigit():
        return False, "its build record is damaged"
    if fields[2][:32] != path.stem[3:]:
        return False, "its build record was made for another library"
    try:
        if int(fields[0]) != size or _digest(path) != (size, fields[1]):
            return False, "its content does not match its build record's size and SHA-256"
    except OSError:
        return False, ""
    return True, ""


def _discard(path: Path) -> None:
    for p in (path, _record_path(path)):
        try:
            p.unlink()
        except OSError:
            pass


def _compile(cc: str, full: str, path: Path) -> None:
    """Compile the library source into ``path`` and record its size, hash and key next to it
    (atomic renames; one builder per key at a time; a cached file that fails verification is
    rebuilt)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    lock = open(path.with_suffix(".lock"), "w")
    try:
        try:
            import fcntl
            fcntl.flock(lock, fcntl.LOCK_EX)    # other processes wait for this build
        except ImportError:                     # no fcntl (Windows): concurrent builds are harmless
            pass
        if _library_check(path)[0]:             # built by another process meanwhile
            return
        _discard(path)                          # damaged or unrecorded: build it anew
        with tempfile.TemporaryDirectory(dir=path.parent) as tmp:
            src = Path(tmp) / "model.c"
            src.write_text(full)
            out = Path(tmp) / "model.so"
            proc = subprocess.run([cc, *CFLAGS, *native_flags(), "-o", str(out), str(src),
                                   "-lm"], capture_output=True, text=True)
            if proc.returncode != 0 and native_flags():   # a compiler without -march=native
                proc = subprocess.run([cc, *CFLAGS, "-o", str(out), str(src), "-lm"],
                                      capture_output=True, text=True)
            if proc.returncode != 0:
                raise CompilerUnavailable(f"C compiler failed: {proc.stderr.strip()[:2000]}")
            size, digest = _digest(out)
            record = Path(tmp) / "model.sha256"
            record.write_text(f"{size} {digest} {_library_key(full)}\n")
            os.replace(record, _record_path(path))   # the record first: a reader that sees the
            os.replace(out, path)                     # library can always verify it
    finally:
        lock.close()


def prune_libraries(max_libraries: int | None = None) -> int:
    """Remove the least recently used compiled libraries (``hl_*.so`` with their build record
    and lock file) beyond ``max_libraries``, down to 90 % of it (the newest always stays;
    :func:`hydroline.cache.least_recently_used`, as the cache's tables). Errors are ignored
    (another process may prune at the same time; a library still loaded elsewhere stays
    usable there, and is compiled again when next needed).

    Parameters
    ----------
    max_libraries : int   Libraries kept at most, [-] (:data:`MAX_LIBRARIES` when None)

    Returns
    -------
    int  Libraries removed, [-]
    """
    keep = MAX_LIBRARIES if max_libraries is None else max(int(max_libraries), 0)
    libs = []
    try:
        with os.scandir(cache_dir()) as it:
            for e in it:
                if e.name.startswith("hl_") and e.name.endswith(".so"):
                    try:
                        libs.append((e.stat().st_mtime, Path(e.path)))
                    except OSError:
                        continue
    except OSError:
        return 0
    removed = 0
    for path in least_recently_used(libs, keep, at_least=1):   # (the newest stays)
        try:
            path.unlink()
        except OSError:
            continue
        removed += 1
        _LIBS.pop(str(path), None)
        for other in (_record_path(path), path.with_suffix(".lock")):
            try:
                other.unlink()
            except OSError:
                pass
    return removed


def _build(path: Path, full) -> ctypes.CDLL:
    """Load the model's library from the cache, compiling it on a miss.

    The cached file is verified against the size, hash and key recorded at its build before
    it is loaded; one that fails (truncated, overwritten, another library, a damaged record)
    is discarded with one :class:`~hydroline.cache.CacheWarning` naming it and rebuilt. Any
    failure to compile, store or load it (no compiler, a cache directory that cannot be
    written) raises :class:`CompilerUnavailable`, so callers can fall back to another solver.
    ``full`` is the library source, or a callable that makes it (only a rebuild needs it).
    """
    if str(path) in _LIBS:
        return _LIBS[str(path)]
    cc = _compiler()
    verified = False
    for attempt in (0, 1):
        try:
            verified, why = _library_check(path)
            if not verified:
                if why:
                    discard_entry(path, _record_path(path), why=why)
                if cc is None:
                    raise CompilerUnavailable("no C compiler found (set CC, or install gcc)")
                _compile(cc, full() if callable(full) else full, path)
                prune_libraries()               # a library more: the oldest beyond the bound go
            else:
                mark_used(path)                 # (a library's last use, for the pruning)
            lib = ctypes.CDLL(str(path))
            _declare(lib)
            break
        except (OSError, AttributeError) as e:   # AttributeError: a symbol is missing
            if attempt == 0 and path.is_file() and cc is not None:
                if verified:    # a cached library that passes its record but not the loader
                    discard_entry(path, _record_path(path), why=f"it cannot be loaded: {e}")
                else:
                    _discard(path)
                continue        # build it anew
            raise CompilerUnavailable(f"compiled library unusable at {path}: {e}") from None
    _LIBS[str(path)] = lib
    return lib


def _declare(lib):
    dp = ctypes.POINTER(ctypes.c_double)
    llp = ctypes.POINTER(ctypes.c_longlong)
    vp = ctypes.c_void_p
    lib.hl_sizes.argtypes = [llp]
    lib.hl_new.restype = vp
    lib.hl_free.argtypes = [vp]
    lib.hl_setup.argtypes = [vp, dp, dp, dp, ctypes.c_double, ctypes.c_double, ctypes.c_double,
                             ctypes.c_double, ctypes.c_int, ctypes.c_double]
    lib.hl_set_parameters.argtypes = [vp, dp]
    lib.hl_init.argtypes = [vp, ctypes.c_double, dp, ctypes.c_double]
    lib.hl_advance.argtypes = [vp, ctypes.c_int, dp, dp, dp, ctypes.POINTER(ctypes.c_int),
                               ctypes.c_longlong]
    lib.hl_get_state.argtypes = [vp, dp, dp]
    lib.hl_stats.argtypes = [vp, llp]
    lib.hl_reset_stats.argtypes = [vp]
    # called in tight loops (steady state): raw addresses, no per-call pointer objects
    lib.hl_rhs.argtypes = [vp, ctypes.c_double, vp, vp]
    lib.hl_scaled_jacobian.argtypes = [vp, ctypes.c_double, vp, vp]
    lib.hl_last_nonfinite.argtypes = [vp]
    lib.hl_set_max_steps.argtypes = [vp, ctypes.c_longlong]
    lib.hl_set_order_limits.argtypes = [vp, dp]


def _ptr(a):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


class NativeModel:
    """A network's compiled library and its constants.

    Attributes
    ----------
    generated : GeneratedModel   Source, hash key, constants, sizes
    lib : ctypes.CDLL            The loaded library
    library_path : Path          Where the library is cached
    build_time : float           Seconds spent generating (and, on a cache miss, compiling)
    found_by : str               "definition", "graph", "structure" or "generated" (below)

    Parameters
    ----------
    network : Network   The assembled model (:class:`hydroline.engine.Network`)
    """

    def __init__(self, network):
        tic = time.perf_counter()
        self.network = network
        key, found, full, record = self._locate(network)
        try:
            self._load(full, record is not None)
        except _RecordMismatch as e:   # a record that does not fit: without records
            discard_table(*record, why=str(e))
            _MODELS.pop(key, None)
            _STRUCTURES.pop(record[1], None)
            key, found, full, record = self._locate(network, records=False)
            self._load(full, False)
        self.n, self.n_signals = int(self._sizes[0]), int(self._sizes[3])
        # (the dense Jacobian's row and column indices, each component's state block, and
        # the order limits found, by Jacobian: made on first use)
        self._jac_index = self._blocks = None
        self._limits_seen: dict = {}
        _remember_model(key, self.generated, self.library_path)
        #: How the model was found: "definition" (its record, found before any graph was
        #: built), "graph" (the record of its graph's fingerprint, where the network cannot
        #: describe itself), "structure" (a known structure: constants read from the
        #: graph) or "generated" (C written)
        self.found_by = found
        self.build_time = time.perf_counter() - tic

    def _locate(self, network, records: bool = True):
        """Find the model's record (``records``), else generate its C; sets ``generated``
        and ``library_path``. Returns (key of its model record, how it was found, the
        library's source or a callable that makes it, the record used as (table kind, key)
        or None)."""
        # the model's record: under its definition (known before any graph is built) where
        # the network can describe itself, else under its graph's fingerprint; also where
        # the graph was built before (components changed since would not be in it)
        key = definition_key(network)
        gen, tag = _known_model(key, network) if records else (None, None)
        found, record = "definition", ("models", key)
        if gen is None:   # not known: build the graph
            from . import codegen

            if getattr(network, "has_graph", True):
                key = None
            model = network.compile()
            if key is None:
                key, found = model_fingerprint(model), "graph"
                record = ("models", key)
                gen, tag = _known_model(key, network) if records else (None, None)
            if gen is None:   # other numbers: is the structure known?
                functions = codegen.scaled_functions(model)
                record = ("structures", _structure_record_key(functions))
                gen, tag = (_known_structure(functions, record[1], network) if records
                            else (None, None))
                found = "structure"
                if gen is None:   # a new structure: write its C
                    found, record = "generated", None
                    gen = codegen.generate(model, functions)
                    path, full = _library_path(gen)
                    _remember_structure(functions, gen, path)
        self.generated = gen
        if tag is not None:          # known: its C is regenerated only to rebuild a library
            path = cache_dir() / f"hl_{tag}.so"

            def full():
                from . import codegen

                made, source = _library_path(codegen.generate(network.compile()))
                if made != path:
                    raise _RecordMismatch(f"it names the library {path.name}, which is not "
                                          f"this model's")
                return source
        self.library_path = path
        return key, found, full, record

    def _load(self, full, from_record: bool) -> None:
        """Load (or build) the library and check that it fits the model's sizes; a misfit
        of a model found by its record is that record's fault (:class:`_RecordMismatch`)."""
        self.cache_hit = self.library_path.exists()
        self.lib = _build(self.library_path, full)
        sizes = (ctypes.c_longlong * 7)()
        self.lib.hl_sizes(sizes)
        g = self.generated
        if tuple(sizes)[:5] != (g.n_states, max(g.n_parameters, 1), max(len(g.constants), 1),
                                max(g.n_signals, 1), max(g.jac_nnz, 1)):
            if from_record:
                raise _RecordMismatch(f"the library it names, {self.library_path.name}, does "
                                      f"not fit the model")
            raise CompilerUnavailable(f"compiled library at {self.library_path} does not fit "
                                      f"the model (sizes {tuple(sizes)[:5]})")
        self._sizes = tuple(sizes)

    def dense_jacobian(self, jnz) -> np.ndarray:
        """The Jacobian as a dense matrix from its nonzeros (``generated.jac_colind`` /
        ``jac_row`` order, as :meth:`NativeSolver.scaled_jacobian_nonzeros` gives them).

        Parameters
        ----------
        jnz : ndarray   Nonzeros, [1/s]
        """
        g = self.generated
        if self._jac_index is None:
            self._jac_index = (np.asarray(g.jac_row, dtype=np.intp),
                               np.repeat(np.arange(self.n), np.diff(g.jac_colind)))
        J = np.zeros((self.n, self.n))
        J[self._jac_index] = jnz[:g.jac_nnz]
        return J

    def order_limits(self, jnz) -> tuple:
        """Largest step of each NDF order 1-5 on this model's fast modes (:mod:`.stability`),
        from the eigenvalues of each component's own block of the scaled Jacobian with
        nonzeros ``jnz`` (remembered by those numbers).

        Parameters
        ----------
        jnz : ndarray   Nonzeros of the scaled Jacobian, [1/s]

        Returns
        -------
        tuple  (h_1, ..., h_5), [s] (inf: no limit)
        """
        from .stability import block_eigenvalues, order_step_limits

        if self._blocks is None:
            net = self.network
            self._blocks = [sl for sl in (net.state_slice(c.name) for c in net.components)
                            if sl.stop - sl.start >= 2]
        if not (self._blocks and self.generated.jac_nnz):
            return (np.inf,) * 5
        key = jnz.tobytes()
        limits = self._limits_seen.get(key)
        if limits is None:
            limits = order_step_limits(block_eigenvalues(self.dense_jacobian(jnz), self._blocks))
            if len(self._limits_seen) >= 64:
                self._limits_seen.clear()
            self._limits_seen[key] = limits
        return limits

    def solver(self, p=None, rtol: float = 1e-7, atol: float = 1e-8, max_step: float = 0.0,
               fixed_step: float = 0.0, max_order: int = 5, newton_coef: float = 0.1,
               order_limits: bool = True):
        """A fresh :class:`NativeSolver` with runtime parameters p (network defaults if None).

        Parameters
        ----------
        p : ndarray           Runtime parameters, [SI] (the network's when None)
        rtol : float          Relative tolerance, [-]
        atol : float          Absolute tolerance on the scaled states, [-]
        max_step : float      Largest step, [s] (0: none)
        fixed_step : float    > 0: fixed-step BDF without error control, [s]
        max_order : int       Highest BDF order (1-5)
        newton_coef : float   Newton tolerance relative to the error-test tolerance, [-]
        order_limits : bool   Keep each NDF order 3-5 below the step where the model's
                              lightly damped fast modes would make it unstable
                              (:mod:`.stability`; False: the orders are chosen by accuracy
                              alone, as before)
        """
        return NativeSolver(self, p, rtol, atol, max_step, fixed_step, max_order, newton_coef,
                            order_limits)


class NativeSolver:
    """One integrator instance in C (state kept between calls, for chunked/streamed runs).

    Parameters
    ----------
    model : NativeModel The compiled library and its constants
    p : ndarray         Runtime parameters, [SI]
    rtol : float        Relative tolerance, [-]
    atol : float        Absolute tolerance on the scaled states (fraction of each state's
                        typical magnitude), [-]
    max_step : float    Largest step, [s] (0: none)
    fixed_step : float  > 0: fixed-step BDF of order max_order without error control, [s]
    max_order : int     Highest BDF order (1-5)
    newton_coef : float Newton convergence tolerance relative to the error-test tolerance, [-]
    order_limits : bool Stability limits of the NDF orders 3-5 on the model's fast modes
                        (:mod:`.stability`), set before the first step
    """

    #: Most steps one :meth:`advance` call may take before it gives up (a stalled run returns
    #: control instead of hanging in C, where Ctrl-C cannot reach it).
    max_steps_per_call = 5_000_000

    def __init__(self, model: NativeModel, p, rtol, atol, max_step, fixed_step, max_order,
                 newton_coef, order_limits: bool = True):
        if not (rtol > 0 and atol > 0):
            raise ValueError(f"rtol and atol must be > 0 [-], got {rtol!r} and {atol!r}")
        self.model = model
        lib = model.lib
        self._lib = lib
        net = model.network
        p = net.parameter_values if p is None else p
        self.p = self._checked_parameters(p)
        c = model.generated.constants
        self._c = np.ascontiguousarray(c if c.size else np.zeros(1))
        self._scale = np.ascontiguousarray(np.asarray(net.state_scales, dtype=float))
        self._t_bound = None
        # () : not yet set (before the first step); None: none (fixed step, or not asked)
        self._limits = () if order_limits and not fixed_step > 0 else None
        self._start = None
        self._jnz = None                                  # (scaled_jacobian's buffer)
        self._h = lib.hl_new()
        lib.hl_setup(self._h, _ptr(self.p), _ptr(self._c), _ptr(self._scale), rtol, atol,
                     max_step, fixed_step, int(max_order), newton_coef)
        lib.hl_set_max_steps(self._h, self.max_steps_per_call)

    def _checked_parameters(self, p) -> np.ndarray:
        p = np.atleast_1d(np.array(p, dtype=float))   # a copy: the caller may change its own
        n_p = len(self.model.network.parameter_values)
        if p.shape != (n_p,):
            raise ValueError(f"parameter vector p must have {n_p} entries, got {p.size}")
        return p if p.size else np.zeros(1)

    def __del__(self):
        h, self._h = getattr(self, "_h", None), None
        if h:
            self._lib.hl_free(h)

    def set_parameters(self, p):
        """Use other runtime parameters from the next step on (a sampled controller's hold);
        the same numbers as now change nothing (callers may pass p at every segment).

        Parameters
        ----------
        p : ndarray   Runtime parameters, [SI]
        """
        p = self._checked_parameters(p)
        if p.tobytes() == self.p.tobytes():
            return
        self.p = p
        self._lib.hl_set_parameters(self._h, _ptr(self.p))

    def start(self, t0: float, x0, t_bound: float):
        """Begin a segment [t0, t_bound] from x0 (order 1; inputs may jump at t0).

        Parameters
        ----------
        t0 : float        Segment start, [s]
        x0 : ndarray      States there, [SI]
        t_bound : float   Segment end, [s]
        """
        x0 = np.ascontiguousarray(np.asarray(x0, dtype=float))
        if x0.shape != (self.model.n,):
            raise ValueError(f"initial state x0 must have {self.model.n} entries, got {x0.size}")
        if not (t_bound > t0):
            raise ValueError(f"segment end t_bound must be after t0 [s], got {t0!r}, {t_bound!r}")
        self._lib.hl_init(self._h, float(t0), _ptr(x0), float(t_bound))
        self._t_bound = float(t_bound)
        self._start = (float(t0), x0)

    def _set_order_limits(self, t0: float, x0) -> None:
        """Cap each NDF order's step where it would be unstable on the model's lightly damped
        fast modes (:meth:`NativeModel.order_limits`, from the Jacobian at (t0, x0)); kept for
        the solver's life (a hose's modes are linear)."""
        self._limits = self.model.order_limits(self.scaled_jacobian_nonzeros(t0, x0))
        arr = np.ascontiguousarray(self._limits, dtype=float)
        self._lib.hl_set_order_limits(self._h, _ptr(arr))

    @property
    def order_limits(self) -> tuple:
        """Largest step of each order 1-5, [s] (inf: none), set before the first step, from
        the Jacobian at that segment's start (empty before; None in fixed-step mode)."""
        return self._limits

    def advance(self, t_out, signals: bool = True, table: bool = False, out=None):
        """Integrate through the output times (ascending, within the segment).

        Parameters
        ----------
        t_out : ndarray   Output times, [s]
        signals : bool    Also return every signal at those times
        table : bool      One array, signals then states, instead of a pair
        out : ndarray     Where to write the rows: C-contiguous float64, one row per output
                          time of (signals then) states, e.g. a slice of a run's whole table
                          (no array made, nothing copied afterwards); None: a new array, [SI]

        Returns
        -------
        (X, Y) : states [n_out, n_states] and signals [n_out, n_signals] (None if not asked), SI;
                 with ``table=True`` one array [n_out, n_signals + n_states] (signals first)
        """
        t_out = np.ascontiguousarray(np.asarray(t_out, dtype=float))
        if self._t_bound is None:
            raise RuntimeError("call start(t0, x0, t_bound) before advance()")
        if self._limits == () and t_out.size and t_out[-1] > self._start[0]:
            self._set_order_limits(*self._start)   # once per solver, before its first step
        slack = 1e-9 * max(1.0, abs(self._t_bound))   # grid times rounded onto the segment end
        if t_out.size and (t_out[-1] > self._t_bound + slack or np.any(np.diff(t_out) < 0)):
            raise ValueError(f"output times must ascend and lie within the segment "
                             f"(t_bound = {self._t_bound:g} s)")
        n, ny = self.model.n, self.model.n_signals
        ld = (ny if signals else 0) + n
        if out is None:
            block = np.empty((len(t_out), ld))
        else:
            block = out
            if not (isinstance(out, np.ndarray) and out.dtype == np.float64
                    and out.shape == (len(t_out), ld) and out.flags.c_contiguous
                    and out.flags.writeable):
                raise ValueError(f"out must be a writeable C-contiguous float64 array of shape "
                                 f"{(len(t_out), ld)}")
        X = block[:, ld - n:]
        Y = block[:, :ny] if signals else None
        done = ctypes.c_int(0)
        rc = self._lib.hl_advance(self._h, len(t_out), _ptr(t_out), _ptr(X),
                                  _ptr(Y) if signals else None, ctypes.byref(done), ld)
        if rc != 0:
            x, t = self.state()
            names = self.model.network.state_names
            bad = self._lib.hl_last_nonfinite(self._h)
            why = {-1: "step size fell below the resolution of t",
                   -2: "singular iteration matrix",
                   -3: "Newton iteration failed in fixed-step mode",
                   -4: f"the derivative of state {names[bad] if 0 <= bad < len(names) else bad!r} "
                       f"is not finite (NaN or inf) there",
                   -5: f"no progress after {self.max_steps_per_call} steps"}
            raise RuntimeError(f"compiled integrator failed at t = {t:.6g} s: {why.get(rc, rc)}")
        if done.value != len(t_out):
            raise RuntimeError(f"compiled integrator stopped after {done.value} of "
                               f"{len(t_out)} output times")
        if not np.all(np.isfinite(X)):
            raise RuntimeError("compiled integrator produced non-finite states")
        return block if table else (X, Y)

    def state(self):
        """Current (x [SI], t [s])."""
        x = np.empty(self.model.n)
        t = ctypes.c_double()
        self._lib.hl_get_state(self._h, _ptr(x), ctypes.byref(t))
        return x, t.value

    def stats(self) -> dict:
        """Steps, f and Jacobian evaluations, LU factorizations, rejected steps, ..."""
        s = (ctypes.c_longlong * 7)()
        self._lib.hl_stats(self._h, s)
        keys = ("nsteps", "nfevals", "njevals", "nlu", "nrejected", "nnewton_fail", "ndense_lu")
        return {k: int(v) for k, v in zip(keys, s)}

    def reset_stats(self):
        """Set the counters of :meth:`stats` to zero."""
        self._lib.hl_reset_stats(self._h)

    def scaled_jacobian_nonzeros(self, t: float, x, out=None) -> np.ndarray:
        """d(dz/dt)/dz at (t, x) in the scaled states z = x/scale: the nonzeros in the
        compressed-column order of ``model.generated.jac_colind`` / ``jac_row``, [1/s].

        Parameters
        ----------
        t : float         Time, [s]
        x : ndarray       States, [SI]
        out : ndarray     Array to fill, [1/s] (made when None)
        """
        x = np.ascontiguousarray(np.asarray(x, dtype=float))
        if x.shape != (self.model.n,):
            raise ValueError(f"state x must have {self.model.n} entries, got {x.size}")
        g = self.model.generated
        if out is None or len(out) < max(g.jac_nnz, 1):
            out = np.empty(max(g.jac_nnz, 1))
        self._lib.hl_scaled_jacobian(self._h, float(t), x.ctypes.data, out.ctypes.data)
        return out[:g.jac_nnz]

    def scaled_jacobian(self, t: float, x) -> np.ndarray:
        """d(dz/dt)/dz at (t, x), dense, in the scaled states z = x/scale, [1/s].

        Parameters
        ----------
        t : float         Time, [s]
        x : ndarray       States, [SI]
        """
        self._jnz = self.scaled_jacobian_nonzeros(t, x, self._jnz)
        return self.model.dense_jacobian(self._jnz)

    def signals(self, t: float, x) -> np.ndarray:
        """Every signal at (t, x) from the compiled code, in ``network.signal_names`` order,
        [SI]. Ends the segment in progress (:meth:`start` begins the next); :meth:`stats`
        counts the start's two evaluations of f.

        Parameters
        ----------
        t : float       Time, [s]
        x : ndarray     States, [SI]
        """
        self.start(t, x, t + max(1.0, abs(t)))
        _, y = self.advance([t])       # an output at the segment's start: no step taken
        return y[0]

    def rhs(self, t: float, x) -> np.ndarray:
        """dx/dt at (t, x) from the compiled code, [SI/s].

        Parameters
        ----------
        t : float       Time, [s]
        x : ndarray     States, [SI]
        """
        x = np.ascontiguousarray(np.asarray(x, dtype=float))
        if x.shape != (self.model.n,):
            raise ValueError(f"state x must have {self.model.n} entries, got {x.size}")
        dx = np.empty(self.model.n)
        self._lib.hl_rhs(self._h, float(t), x.ctypes.data, dx.ctypes.data)
        return dx


#: This module's code generation and integrator: a change makes old model records unused.
_CODE_TAG = source_tag(Path(__file__), Path(__file__).with_name("codegen.py"), _BDF_SOURCE)
_MODELS: dict = {}


def model_fingerprint(model) -> str:
    """SHA-256 of a compiled model's CasADi graph (structure and numbers), its state scales
    and this machine's build settings: the same fingerprint means the same C code and the
    same constants, so the code generation can be skipped.

    Parameters
    ----------
    model : CompiledModel   The network's CasADi functions (:class:`hydroline.engine.CompiledModel`)
    """
    scales = np.asarray(model.network.state_scales, dtype=float).tobytes()
    return _hash_parts(model.f.serialize(), model.signals.serialize(), _CODE_TAG,
                       _build_settings(), scales)


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
    network : Network   The assembled model
    """
    describe = getattr(network, "definition_fingerprint", None)
    digest = describe() if describe is not None else None
    if digest is None:
        return None
    return "definition:" + _hash_parts("definition", digest, _CODE_TAG, _build_settings())


def _known_model(fingerprint: str | None, network):
    """(GeneratedModel without its source, library tag) of a model seen before, in this
    process or recorded in the cache directory; (None, None) if unknown. A record that does
    not fit the network (:func:`_misfit`) is discarded with a warning naming its file."""
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


def _structure_record_key(functions) -> str:
    """Key of a structure's record: the graph's listing with constants masked, this module's
    code and the build settings (compiler flags, platform, CPU: the record names a library
    built with them)."""
    settings = hashlib.sha256(_build_settings().encode()).hexdigest()[:16]
    from .codegen import structure_key

    return structure_key(functions) + _CODE_TAG + settings


def _known_structure(functions, key: str, network):
    """(GeneratedModel with this model's constants and no source, library tag) when a model
    of the same structure (record key ``key``, :func:`_structure_record_key`) was generated
    before (this process or recorded on disk): only the constants are read from the graph;
    (None, None) otherwise. A record that does not fit (:func:`_misfit`, its constants'
    positions) is discarded with a warning naming its file."""
    rec = _STRUCTURES.get(key)
    if rec is None:
        rec = load_table("structures", key)
        if rec is None:
            return None, None
        _STRUCTURES[key] = rec
    try:
        from .codegen import constants_at

        constants = constants_at(functions, rec["positions"])
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


def _remember_structure(functions, gen, library_path: Path) -> None:
    from .codegen import constant_positions

    positions = constant_positions(functions)
    if sum(map(len, positions)) != len(gen.constants):   # not the order generate() numbers
        return
    rec = {k: getattr(gen, k) for k in _SCALARS}
    rec.update(jac_colind=np.asarray(gen.jac_colind).tolist(),
               jac_row=np.asarray(gen.jac_row).tolist(), positions=positions,
               n_constants=len(gen.constants), library=library_path.stem[3:])
    key = _structure_record_key(functions)
    _STRUCTURES[key] = rec
    store_table("structures", key, rec)


def _remember_model(fingerprint: str, gen, library_path: Path) -> None:
    tag = library_path.stem[3:]
    if fingerprint in _MODELS:
        return
    _MODELS[fingerprint] = (gen, tag)
    rec = {k: getattr(gen, k) for k in _SCALARS}
    rec.update({k: np.asarray(getattr(gen, k)).tolist() for k in _ARRAYS}, library=tag)
    store_table("models", fingerprint, rec)


def needs_build(network) -> bool:
    """Whether running ``network`` on the compiled core would first write and compile a new
    library (its definition and its structure unknown to the cache, or the library missing):
    what a command estimates before a run. Looked up as :class:`NativeModel` does, without
    writing C; the CasADi graph is built (on ``network``) where the definition is unknown.

    Parameters
    ----------
    network : Network   The assembled model

    Returns
    -------
    bool  True when the first run will compile (seconds to minutes, by the model's size)
    """
    if network.__dict__.get("_native_model") is not None:
        return False
    _, tag = _known_model(definition_key(network), network)
    if tag is None:
        model = network.compile()
        _, tag = _known_model(model_fingerprint(model), network)
        if tag is None:
            from . import codegen

            functions = codegen.scaled_functions(model)
            _, tag = _known_structure(functions, _structure_record_key(functions), network)
    return tag is None or not _library_check(cache_dir() / f"hl_{tag}.so")[0]


def native_model(network) -> NativeModel:
    """The network's :class:`NativeModel`, built once per network object.

    Parameters
    ----------
    network : Network   The assembled model

    Raises
    ------
    CompilerUnavailable   No C compiler, or it failed
    UnsupportedOperation  The graph holds an operation the C writer does not know
    """
    nm = network.__dict__.get("_native_model")
    if nm is None:
        nm = NativeModel(network)
        network.__dict__["_native_model"] = nm
    return nm
