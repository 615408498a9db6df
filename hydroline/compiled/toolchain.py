"""The tool chain of the compiled core: the system C compiler, its flags for this machine, and
the cache of compiled libraries (each verified against its build record before it is loaded,
the least recently used pruned beyond :data:`MAX_LIBRARIES`).

Compiler: ``$CC``, else ``cc``/``gcc``/``clang`` on the PATH; without one,
:func:`load_library` raises :class:`CompilerUnavailable`.
"""
from __future__ import annotations

import contextlib
import ctypes
import errno
import functools
import hashlib
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from typing import TYPE_CHECKING

from ..cache import cache_dir, discard_entry, least_recently_used, mark_used

if TYPE_CHECKING:   # (the background builder imports this module without NumPy)
    from .generated import GeneratedModel

__all__ = ["CompilerUnavailable", "LibraryPending", "build_in_background", "build_from_file",
           "compiler", "available", "CFLAGS", "NATIVE_FLAGS",
           "PORTABLE_ENV", "native_flags", "build_settings", "library_location", "library_check",
           "load_library", "prune_libraries", "MAX_LIBRARIES", "BDF_SOURCE", "QUICK_LEVEL",
           "quick_location", "many_runs", "QUICK_WAIT", "BACKGROUND_NICENESS", "nicer",
           "quick_units", "JACOBIAN_LEVEL"]

#: Flags for the system compiler (no -ffast-math: the integrator relies on IEEE semantics;
#: -fno-math-errno only lets sqrt compile to one instruction; -ffp-contract=fast lets a*b+c
#: be one fused multiply-add, rounded once, which ISO C mode otherwise forbids: 0.86x the CPU
#: of an integration, mostly in the sparse back-solves, same error, benchmarks/README.md).
#: The library is built for this machine's CPU (``-march=native``, dropped where the compiler
#: refuses it, or where ``$HYDROLINE_PORTABLE_BUILD`` is set to anything but ``0``: see
#: :func:`native_flags`), so the cache key includes the CPU model and the flags.
CFLAGS = ["-O3", "-fno-math-errno", "-ffp-contract=fast", "-shared", "-fPIC", "-std=c99"]
NATIVE_FLAGS = ["-march=native"]
#: Optimisation level of the quick library a background build makes first (in a third of
#: the time of ``-O3``: 0.4 s against 1.2 s on the default rig; its runs take ~8x the CPU
#: of the ``-O3`` library's, still ~4x less than CVODES's): the runs of a command that
#: start while the build goes on (a layout's, a fit's) use it until the ``-O3`` library is
#: there (:func:`load_library`), which then replaces it. The same source and the same
#: other flags: its results agree with the ``-O3`` library's to the integrator's rounding.
QUICK_LEVEL = "-O0"
#: Environment variable that asks for a portable build (no ``-march=native``: baseline x86-64,
#: no fused multiply-add on that target), e.g. for a cache shared by different CPUs
PORTABLE_ENV = "HYDROLINE_PORTABLE_BUILD"
#: Longest a process waits, in all, for the quick library of a background build, once one
#: of its runs went on without it (:func:`load_library`), [s]
QUICK_WAIT = 1.5
#: Niceness of the background build (:func:`build_in_background`): it uses the CPU that the
#: command's own processes leave (on two cores a cold ``hydroline simulate`` with its figure,
#: or a layout study, is three processes with the build); a run that needs its quick library
#: waits for it, and the build then has that CPU, [-]
BACKGROUND_NICENESS = 10
#: Optimisation level of the Jacobian's translation unit in a quick build
#: (:func:`quick_units`): it is evaluated once per factorisation, and at ``-O1`` (its level
#: in the ``-O3`` library, ``HL_RARELY_CALLED``) it is the largest unit, 0.43 s of the
#: default rig's ~1.0 s at ``-O1``; at ``-O0`` 0.15 s, for ~3 ms more of a fit's run (35 ms)
JACOBIAN_LEVEL = "-O0"
#: Translation units of the optimised (``-O3``) build too (:func:`quick_units`), compiled
#: side by side: 30 modes per section, the Jacobian 1.5 s at ``-O1`` (2.5 s at ``-O3`` with
#: its ``O1`` attribute as one file), f, the other functions and the integrator 0.5, 0.7 and
#: 0.75 s: on two cores the first build's wall ~2 s instead of ~3.7 s. Part of the cache key
#: (:func:`build_settings`): a library built as one file has another machine code
UNITS_OF_THE_BUILD = 4
#: Optimisation level of the Jacobian's unit in the optimised build: its level there as one
#: file (``HL_RARELY_CALLED``, ``optimize("O1")``), [-]
OPTIMISED_JACOBIAN_LEVEL = "-O1"
BDF_SOURCE = Path(__file__).with_name("bdf.c")
_LIBS: dict = {}
#: Library (its path) -> the first run of this process that went on without it while its
#: background build ran (:func:`load_library`)
_PENDING: dict = {}
#: Library (its path) -> how long this process has waited for its quick build, [s]
_WAITED: dict = {}
#: Inside :func:`many_runs`: a first run waits for the quick build too
_MANY_RUNS = False
#: :func:`many_runs`' work to do while a run waits for a quick library
_MEANWHILE: list = []
#: :func:`many_runs`' optimisation level for the quick builds started within it (None:
#: :data:`QUICK_LEVEL`)
_QUICK_ASKED: list = [None]
#: True while :func:`many_runs`' work meanwhile is done (a run waits for a quick build): a
#: background build started by that work is niced, and its first run goes on without it
_IN_MEANWHILE: list = [False]
#: Libraries (their paths) whose background build this process started niced inside
#: :func:`many_runs` (by its work meanwhile: a layout study's 0 m length)
_UNAWAITED: set = set()
#: Most compiled libraries kept in the cache directory (one per network structure and
#: machine, ~0.1-0.3 MB each): beyond it the least recently used are removed after a build
#: (a removed one is compiled again when its structure comes back), [-]
MAX_LIBRARIES = 200


class CompilerUnavailable(RuntimeError):
    """No working C compiler: the compiled core cannot be built on this machine.

    Parameters
    ----------
    *args : str
        The message: what failed.
    **kwargs : dict
        None taken (as ``RuntimeError``).
    """


class LibraryPending(RuntimeError):
    """The library is being built in a background process (:func:`build_in_background`):
    this run goes on without it.

    Parameters
    ----------
    message : str
        What is being built
    path : Path
        The library
    """

    def __init__(self, message: str, path=None):
        super().__init__(message)
        self.path = path


def compiler() -> str | None:
    """The C compiler's path: ``$CC``, else ``cc``/``gcc``/``clang`` on the PATH; None
    without one.

    Returns
    -------
    str or None
        The compiler's path, or None.
    """
    cc = os.environ.get("CC")
    if cc and shutil.which(cc):
        return shutil.which(cc)
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


def available() -> bool:
    """True when a C compiler is on the PATH (the compiled core can be built).

    Returns
    -------
    bool
        True when a compiler is found.
    """
    return compiler() is not None


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
    return BDF_SOURCE.read_text()


def native_flags() -> list[str]:
    """The CPU-specific compiler flags of a build: :data:`NATIVE_FLAGS`, or none when
    ``$HYDROLINE_PORTABLE_BUILD`` is set (and not ``0``). Read at each build, so a process
    can build both kinds; their libraries and records have separate cache keys.

    Returns
    -------
    list of str
        The flags (empty for a portable build).
    """
    portable = os.environ.get(PORTABLE_ENV, "").strip() not in ("", "0")
    return [] if portable else list(NATIVE_FLAGS)


def build_settings() -> str:
    """What a library's machine code depends on besides its source: the compiler flags, the
    platform and this CPU.

    Returns
    -------
    str
        Flags, platform and CPU identifier, as one text.
    """
    return (" ".join(CFLAGS + native_flags()) + f" units {UNITS_OF_THE_BUILD} jacobian "
            f"{OPTIMISED_JACOBIAN_LEVEL}" + sys.platform + _cpu_id())


def _library_key(full: str) -> str:
    """A library's cache key: SHA-256 (hex) of its source and the build settings; its file is
    named by the first 32 digits, its build record holds all 64."""
    return hashlib.sha256((full + build_settings()).encode()).hexdigest()


def library_location(gen: GeneratedModel) -> tuple[Path, str]:
    """Where a generated model's library is cached, and the library's whole source (the
    model's C with the integrator).

    Parameters
    ----------
    gen : GeneratedModel
        The model's C source (:func:`hydroline.compiled.codegen.generate`)

    Returns
    -------
    tuple
        (path of the library in the cache directory, its source)
    """
    full = gen.source + "\n" + _bdf_source()
    return cache_dir() / f"hl_{_library_key(full)[:32]}.so", full


def quick_location(path: Path) -> Path:
    """Where the quick library (:data:`QUICK_LEVEL`) of the library at ``path`` is kept.

    Parameters
    ----------
    path : Path
        The library in the cache directory (:func:`library_location`)

    Returns
    -------
    Path
        Its quick build's file, named after it (its build record holds the same key).
    """
    return path.with_name(f"{path.stem}_quick.so")


def _digest(path: Path) -> tuple[int, str]:
    """(size [bytes], SHA-256) of a file."""
    data = path.read_bytes()
    return len(data), hashlib.sha256(data).hexdigest()


def _record_path(path: Path) -> Path:
    return path.with_suffix(".sha256")


def library_check(path: Path) -> tuple[bool, str]:
    """Whether the cached library at ``path`` is the file its build recorded (size, SHA-256,
    and the key it was built for, of which its name is the start). Checked before the
    library is loaded: a truncated, overwritten or foreign file mapped into the process
    would crash it (SIGBUS, SIGSEGV) instead of raising.

    Parameters
    ----------
    path : Path
        The library in the cache directory

    Returns
    -------
    tuple
        (True, "") when it is; (False, "") when there is nothing to check (no library;
        no record, or a record of the format before keys: a quiet miss); (False, why)
        when it fails its record (to be said in a warning)
    """
    try:
        size = path.stat().st_size
        fields = _record_path(path).read_text().split()
    except (OSError, UnicodeDecodeError):
        return False, ""
    if len(fields) == 2:
        return False, ""
    if len(fields) != 3 or not fields[0].isdigit():
        return False, "its build record is damaged"
    if fields[2][:32] != path.stem[3:].removesuffix("_quick"):
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
    (atomic renames; one builder per key at a time, a build in the background included; a
    cached file that fails verification is rebuilt)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    lock = open(path.with_suffix(".lock"), "w")
    try:
        try:
            import fcntl
            fcntl.flock(lock, fcntl.LOCK_EX)    # other processes wait for this build
        except ImportError:                     # no fcntl (Windows): concurrent builds are harmless
            pass
        _compile_locked(cc, full, path)
    finally:
        lock.close()


#: How the background builder (:func:`build_in_background`, ``python -c``) imports its work:
#: this module without running the package's ``__init__``, which imports the model's modules
#: and NumPy (0.1 s of CPU, ~0.15 s of wall, before the quick build's compiler starts, which a
#: fit's first run and a layout's second wait for).
BUILDER_IMPORTS = ("import importlib.util\nimport sys\n"
                   "package = importlib.util.find_spec('hydroline.compiled')\n"
                   "sys.modules[package.name] = importlib.util.module_from_spec(package)\n"
                   "from hydroline.compiled.toolchain import build_from_file, nicer\n")


def build_in_background(path: Path, full) -> bool:
    """Start building a library in a process of its own (detached: it goes on after this
    process ends) unless a build of it is running; the caller goes on without
    it (CVODES) and a later run loads it. The builder holds the library's lock until the
    library and its record are in place, so that a process that needs the library waits for
    that build (:func:`load_library`) instead of starting its own.

    Parameters
    ----------
    path : Path
        The library in the cache directory (:func:`library_location`)
    full : str or callable
        Its source, or a callable that makes it

    Returns
    -------
    bool
        True when a build is running (started here or by another process); False when
        none could be started (no compiler, no ``fcntl`` to hand the lock over, the cache
        directory not writable) or the library is there already
    """
    cc = compiler()
    try:
        import fcntl
    except ImportError:
        return False
    if cc is None:
        return False
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        lock = open(path.with_suffix(".lock"), "w")
    except OSError:
        return False
    try:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return True                         # another process is building it
        if library_check(path)[0]:
            return False                        # built meanwhile
        source = path.with_suffix(".c")
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".c.tmp")
        with os.fdopen(fd, "w") as f:
            f.write(full() if callable(full) else full)
        os.replace(tmp, source)
        # (niced first thing, unless a run of this process waits for its quick library, and
        # before the library itself in any case: a preexec_fn would make subprocess fork this
        # whole process)
        awaited = _MANY_RUNS and not _IN_MEANWHILE[0]   # (a run of this process waits)
        code = BUILDER_IMPORTS + ("if sys.argv[5] != 'awaited':\n    nicer()\n"
                                  "build_from_file(sys.argv[1], sys.argv[2], sys.argv[3], "
                                  "sys.argv[4], between=nicer)\n")
        # (the child inherits the locked descriptor: the lock is its until it exits)
        subprocess.Popen([sys.executable, "-c", code, cc, str(source), str(path),
                          _QUICK_ASKED[0] or QUICK_LEVEL, "awaited" if awaited else "later"],
                         stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL, pass_fds=(lock.fileno(),),
                         start_new_session=True, close_fds=True)
        if _MANY_RUNS and not awaited:
            _UNAWAITED.add(str(path))
        return True
    except (OSError, ValueError, subprocess.SubprocessError):
        return False
    finally:
        lock.close()


def nicer() -> None:
    """Lower this process's priority to :data:`BACKGROUND_NICENESS`, where the system allows
    it (the background builder does before its ``-O3`` build, and before its quick build
    unless a run waits for that one). Where the process leads a session of its own (the
    builder does) and the kernel schedules a session's processes as one group
    (``/proc/self/autogroup``), that group is niced too: a niceness ranks a process only
    against its own group's, and the builder's group would otherwise get as much CPU as the
    command's (which holds the command and its figure process). Called again, it changes
    nothing."""
    try:
        os.setpriority(os.PRIO_PROCESS, 0,
                       max(os.getpriority(os.PRIO_PROCESS, 0), BACKGROUND_NICENESS))
    except (AttributeError, OSError):
        pass
    try:
        if os.getsid(0) != os.getpid():
            return
    except (AttributeError, OSError):
        return
    for attempt in (0, 1):
        try:
            with open("/proc/self/autogroup", "w") as f:
                f.write(f"{BACKGROUND_NICENESS}\n")
            return
        except OSError as e:     # EAGAIN: one change a 0.1 s on the machine, unprivileged
            if e.errno != errno.EAGAIN or attempt:
                return
            time.sleep(0.11)


def build_from_file(cc: str, source: str, path: str, quick_level: str = QUICK_LEVEL,
                    between=None) -> None:
    """The background builder's work (:func:`build_in_background`, in its own process, the
    library's lock inherited): compile ``source`` into the library ``path`` with its record,
    its quick build (:data:`QUICK_LEVEL`) first, for the runs that start meanwhile, removed
    once the library is there (the process started at :data:`BACKGROUND_NICENESS`); errors
    are dropped (a run that needs the library builds it then).

    Parameters
    ----------
    cc : str
        The C compiler
    source : str
        The library's source file (removed afterwards)
    path : str
        The library in the cache directory
    quick_level : str
        The quick build's optimisation level (:func:`many_runs`)
    between : callable
        Called after the quick build, before the library's (the background
        builder: :func:`nicer`)
    """
    try:
        full = Path(source).read_text()
        if not library_check(Path(path))[0]:
            try:
                _compile_locked(cc, full, Path(path), quick_level=quick_level)
            except CompilerUnavailable:
                pass                    # (the library itself may still build)
        if between is not None:
            between()
        _compile_locked(cc, full, Path(path))
        _discard(quick_location(Path(path)))   # (a process that loaded it keeps its copy)
        prune_libraries()               # a library more: the oldest beyond the bound go
    except (OSError, CompilerUnavailable):
        pass
    finally:
        try:
            os.unlink(source)
        except OSError:
            pass


#: A function definition of the generated C (:func:`hydroline.compiled.codegen.generate`):
#: its first line (a one-line function, ``hl_sign``, is not one); it ends at a line that
#: holds ``}`` alone
GENERATED_FUNCTION = re.compile(r"^(?:HL_RARELY_CALLED )?static (?:void|int) (hl_\w+)\([^)]*\) \{\n",
                                re.M)


def quick_units(full: str, level: str,
                jacobian_level: str = JACOBIAN_LEVEL) -> list[tuple[str, str]]:
    """The translation units of a build, the quick one's and the optimised one's
    (:data:`UNITS_OF_THE_BUILD`), compiled side by side (on two cores a build's wall is
    about half their sum, not the sum): the model's f, its Jacobian (at ``jacobian_level``),
    its other functions (the signals, the sparse LU), and the
    integrator (:data:`BDF_SOURCE`), each with the generated header and tables, the
    functions of the other units declared. Default rig at ``-O1``: 0.13, 0.15, 0.20 and
    0.29 s of CPU. A source not laid out as the generated C is (no f or Jacobian found,
    not ending in the integrator's source) is one unit.

    Parameters
    ----------
    full : str
        The library's source (:func:`library_location`)
    level : str
        The build's optimisation level, e.g. ``"-O1"`` (a quick build's)
    jacobian_level : str
        The Jacobian's (:data:`JACOBIAN_LEVEL`; the optimised build's: its own ``level``)

    Returns
    -------
    list of tuple
        (source, optimisation level) of each unit
    """
    integrator = _bdf_source()
    model = full[:len(full) - len(integrator)]
    if not full.endswith(integrator):
        return [(full, level)]
    functions = []                                  # (start, end, name, declaration)
    for match in GENERATED_FUNCTION.finditer(model):
        end = model.find("\n}\n", match.end()) + 3
        if end < 3 or (functions and match.start() < functions[-1][1]):
            return [(full, level)]
        declaration = match.group(0).split("static ", 1)[1][:-len(" {\n")]
        functions.append((match.start(), end, match.group(1), declaration))
    names = [name for _, _, name, _ in functions]
    if "hl_f" not in names or "hl_jac" not in names:
        return [(full, level)]

    def unit(own, tail=""):
        """The model's C with the functions in ``own`` defined, the others declared."""
        parts, at = [], 0
        for start, end, name, declaration in functions:
            parts.append(model[at:start])
            parts.append(model[start:end].split("static ", 1)[1] if name in own
                         else declaration + ";\n")
            at = end
        return "".join(parts) + model[at:] + tail

    others = set(names) - {"hl_f", "hl_jac"}
    return [(unit({"hl_f"}), level), (unit({"hl_jac"}), jacobian_level),
            (unit(others), level), (unit(set(), integrator), level)]


#: Flags of a unit's compile: its calls to another unit's functions go straight there, not
#: through the shared library's procedure linkage table (no other library may replace them)
UNIT_FLAGS = ["-fno-semantic-interposition"]


def _compile_units(cc: str, units, flags, folder: Path, out: Path) -> bool:
    """Compile translation units (:func:`quick_units`) side by side into objects and link them
    into the library ``out``; False where any step failed (the caller then compiles the whole
    source as one unit, and says why)."""
    flags = [f for f in flags if f != "-shared" and not f.startswith("-O")]
    sources = []
    for k, (text, _) in enumerate(units):
        sources.append(folder / f"unit{k}.c")
        sources[-1].write_text(text)
    objects = [src.with_suffix(".o") for src in sources]
    for native in ([native_flags(), []] if native_flags() else [[]]):
        try:
            procs = [subprocess.Popen([cc, level, *flags, *native, *UNIT_FLAGS, "-c", "-o",
                                       str(obj), str(src)],
                                      stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL)
                     for (_, level), src, obj in zip(units, sources, objects)]
        except OSError:
            return False
        if [p.wait() for p in procs] == [0] * len(procs):
            break
    else:
        return False
    proc = subprocess.run([cc, "-shared", "-o", str(out), *map(str, objects), "-lm"],
                          capture_output=True)
    return proc.returncode == 0


def _compile_locked(cc: str, full: str, path: Path, quick_level: str | None = None) -> None:
    """:func:`_compile`'s work, the library's lock held by the caller, from
    :func:`quick_units` compiled side by side (``quick_level``, e.g. :data:`QUICK_LEVEL`:
    its quick build at that optimisation level, into :func:`quick_location`)."""
    flags = CFLAGS
    if quick_level:
        flags = [quick_level if f.startswith("-O") else f for f in CFLAGS]
        path = quick_location(path)
    if library_check(path)[0]:             # built by another process meanwhile
        return
    _discard(path)                          # damaged or unrecorded: build it anew
    with tempfile.TemporaryDirectory(dir=path.parent) as tmp:
        out = Path(tmp) / "model.so"
        level = next(f for f in flags if f.startswith("-O"))
        units = quick_units(full, level, JACOBIAN_LEVEL if quick_level
                            else OPTIMISED_JACOBIAN_LEVEL)
        if len(units) < 2 or not _compile_units(cc, units, flags, Path(tmp), out):
            src = Path(tmp) / "model.c"
            src.write_text(full)
            proc = subprocess.run([cc, *flags, *native_flags(), "-o", str(out), str(src),
                                   "-lm"], capture_output=True, text=True)
            if proc.returncode != 0 and native_flags():   # a compiler without -march=native
                proc = subprocess.run([cc, *flags, "-o", str(out), str(src), "-lm"],
                                      capture_output=True, text=True)
            if proc.returncode != 0:
                raise CompilerUnavailable(f"C compiler failed: {proc.stderr.strip()[:2000]}")
        size, digest = _digest(out)
        record = Path(tmp) / "model.sha256"
        record.write_text(f"{size} {digest} {_library_key(full)}\n")
        os.replace(record, _record_path(path))   # the record first: a reader that sees the
        os.replace(out, path)                     # library can always verify it


def prune_libraries(max_libraries: int | None = None) -> int:
    """Remove the least recently used compiled libraries (``hl_*.so`` with their build record
    and lock file) beyond ``max_libraries``, down to 90 % of it (the newest always stays;
    :func:`hydroline.cache.least_recently_used`, as the cache's tables). Errors are ignored
    (another process may prune at the same time; a library still loaded elsewhere stays
    usable there, and is compiled again when next needed).

    Parameters
    ----------
    max_libraries : int
        Libraries kept at most, [-] (:data:`MAX_LIBRARIES` when None)

    Returns
    -------
    int
        Libraries removed, [-]
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


def load_library(path: Path, full, wait: bool = True, run=None) -> ctypes.CDLL:
    """Load the model's library from the cache, compiling it on a miss (without ``wait``: in
    a background process, :func:`build_in_background`, raising :class:`LibraryPending`, or
    returning that build's quick library, :func:`quick_location`, once it is there).

    The cached file is verified against the size, hash and key recorded at its build before
    it is loaded; one that fails (truncated, overwritten, another library, a damaged record)
    is discarded with one :class:`~hydroline.cache.CacheWarning` naming it and rebuilt. Any
    failure to compile, store or load it (no compiler, a cache directory that cannot be
    written) raises :class:`CompilerUnavailable`, so callers can fall back to another solver.

    Parameters
    ----------
    path : Path
        The library in the cache directory (:func:`library_location`)
    full : str or callable
        The library source, or a callable that makes it (only a
        rebuild needs it)
    wait : bool
        Compile a missing library here and now (False: in the
        background, unless none can be started there)
    run : hashable
        Who asks (e.g. the id of a run's model), without ``wait``: the first
        run that asks while the library is being built goes on without it
        (inside :func:`many_runs`, it too waits); a later one (a study's
        next run) waits for its quick build, at most :data:`QUICK_WAIT` in
        all (None: never waits)

    Returns
    -------
    ctypes.CDLL
        The loaded library (or, building in the background, its quick build), its
        functions declared

    Raises
    ------
    LibraryPending
        Without ``wait``: the library is being built in the background
    CompilerUnavailable
        No compiler, or the build or load failed
    """
    if str(path) in _LIBS:
        return _LIBS[str(path)]
    cc = compiler()
    verified = False
    for attempt in (0, 1):
        try:
            verified, why = library_check(path)
            if not verified:
                if why:
                    discard_entry(path, _record_path(path), why=why)
                if cc is None:
                    raise CompilerUnavailable("no C compiler found (set CC, or install gcc)")
                # (every run goes on with CVODES until the library is there, or its quick
                # build: on two cores the runs and the build go on side by side, and a run
                # on CVODES is progress)
                if not wait and attempt == 0 and build_in_background(path, full):
                    quick = _quick_library(path)
                    if quick is None and run is not None and (
                            _PENDING.setdefault(str(path), run) != run
                            or _MANY_RUNS and not _IN_MEANWHILE[0]
                            and str(path) not in _UNAWAITED):
                        quick = _await_quick_library(path)   # (a later run, or a study's)
                    if quick is not None:
                        return quick
                    raise LibraryPending(f"{path.name} is being built in the background", path)
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


@contextlib.contextmanager
def many_runs(meanwhile=(), quick_level=None):
    """Within this context the process makes many runs of one model (a fit, a layout
    study): the quick build of a background build started within runs at the command's
    priority, not niced, and the first run that finds the library being built in the
    background waits for the quick build (:func:`load_library`, at most
    :data:`QUICK_WAIT`) as its later runs do, instead of going on without it. A run on
    CVODES costs more than the wait (a fit's first run 0.6 s of CPU against ~0.5 s for the
    quick build, during which the command's figure process imports Matplotlib), and its
    CPU is taken from the build; a single run (a ``hydroline simulate``) is quicker on
    CVODES than after the wait. A background build started by the work done meanwhile
    (another network, e.g. a layout study's 0 m length) is niced, and its first run goes on
    without it.

    Parameters
    ----------
    meanwhile : sequence of callable
        Work the command does later anyway (an import), done by the first run that waits,
        before it waits: on the CPU the build leaves (an error in it is left to where the
        work is done again)
    quick_level : str
        Optimisation level of the quick build of a background build started within (None:
        :data:`QUICK_LEVEL`): a command of many runs on it (a fit's ~14) gains more from
        quicker runs than it loses waiting longer for the library
    """
    global _MANY_RUNS
    before, _MANY_RUNS = _MANY_RUNS, True
    asked, _QUICK_ASKED[0] = _QUICK_ASKED[0], quick_level
    _MEANWHILE.extend(meanwhile)
    try:
        yield
    finally:
        _MANY_RUNS = before
        _QUICK_ASKED[0] = asked
        del _MEANWHILE[:]


def _await_quick_library(path: Path):
    """The quick build of the library at ``path``, waited for while the background build
    that makes it goes on (this process at most :data:`QUICK_WAIT` in all, per library); the
    library itself where that build ended meanwhile; None when neither came (the run then
    goes on without). Called where a run of this process went on without the library before
    (a study's, a fit's next run): the quick build takes about what one run on CVODES does,
    whose CPU the build, and a figure drawn beside it, would otherwise share."""
    import fcntl

    while _MEANWHILE:   # (the command's own work first, on the CPU the build leaves)
        within, _IN_MEANWHILE[0] = _IN_MEANWHILE[0], True
        try:
            _MEANWHILE.pop(0)()
        except Exception:   # noqa: BLE001  (done again, and said, where it is needed)
            pass
        finally:
            _IN_MEANWHILE[0] = within
    start = time.monotonic()
    try:
        while time.monotonic() - start < QUICK_WAIT - _WAITED.get(str(path), 0.0):
            time.sleep(0.01)
            quick = _quick_library(path)
            if quick is not None:
                return quick
            try:
                with open(path.with_suffix(".lock")) as lock:
                    fcntl.flock(lock, fcntl.LOCK_SH | fcntl.LOCK_NB)   # the build has ended
            except OSError:
                continue                    # still building (or no lock file to read)
            return _loaded(path) if library_check(path)[0] else None
        return None
    finally:
        _WAITED[str(path)] = _WAITED.get(str(path), 0.0) + time.monotonic() - start


def _loaded(path: Path):
    """The library at ``path`` loaded and declared (cached per process), or None where it
    cannot be loaded."""
    try:
        lib = ctypes.CDLL(str(path))
        _declare(lib)
    except (OSError, AttributeError):
        return None
    _LIBS[str(path)] = lib
    return lib


def _quick_library(path: Path):
    """The quick build of the library at ``path`` (:func:`quick_location`), loaded, where the
    background build has made it and it passes its record; else None."""
    quick = quick_location(path)
    if str(quick) in _LIBS:
        return _LIBS[str(quick)]
    if not library_check(quick)[0]:
        return None
    return _loaded(quick)


def _declare(lib):
    dp = ctypes.POINTER(ctypes.c_double)
    llp = ctypes.POINTER(ctypes.c_longlong)
    vp = ctypes.c_void_p
    lib.hl_sizes.argtypes = [llp]
    lib.hl_new.restype = vp
    lib.hl_free.argtypes = [vp]
    # a run's calls (once per block of rows): raw addresses (an array's ``ctypes.data``), no
    # per-call pointer objects (``data_as`` cost ~3 us each, 3-4 a call)
    lib.hl_setup.argtypes = [vp, vp, vp, vp, ctypes.c_double, ctypes.c_double, ctypes.c_double,
                             ctypes.c_double, ctypes.c_int, ctypes.c_double]
    lib.hl_set_parameters.argtypes = [vp, vp]
    lib.hl_init.argtypes = [vp, ctypes.c_double, vp, ctypes.c_double]
    lib.hl_advance.argtypes = [vp, ctypes.c_int, vp, vp, vp, vp, ctypes.c_longlong]
    lib.hl_get_state.argtypes = [vp, dp, dp]
    lib.hl_stats.argtypes = [vp, llp]
    lib.hl_reset_stats.argtypes = [vp]
    # called in tight loops (steady state): raw addresses, no per-call pointer objects
    lib.hl_rhs.argtypes = [vp, ctypes.c_double, vp, vp]
    lib.hl_scaled_jacobian.argtypes = [vp, ctypes.c_double, vp, vp]
    lib.hl_last_nonfinite.argtypes = [vp]
    lib.hl_set_max_steps.argtypes = [vp, ctypes.c_longlong]
    lib.hl_set_order_limits.argtypes = [vp, vp]
    lib.hl_set_method.argtypes = [vp, ctypes.c_int]
    lib.hl_set_atol_ceilings.argtypes = [vp, vp]
