"""The native model: a network's compiled library with its constants (:class:`NativeModel`,
found by its record or written as C and built, :func:`native_model`) and one integrator
instance in C (:class:`NativeSolver`).
"""
from __future__ import annotations

import ctypes
import time

import numpy as np

from ..cache import builds_in_background, cache_dir
from .records import (definition_key, forget_record, known_model, known_numbers_model,
                      known_structure, model_fingerprint, numbers_key, remember_model,
                      remember_numbers_model, remember_structure, structure_record_key)
from .toolchain import CompilerUnavailable, library_check, library_location, load_library

__all__ = ["native_model", "NativeModel", "NativeSolver", "needs_build"]


class _RecordMismatch(Exception):
    """A model or structure record of the cache does not fit the model it was found for: the
    record is discarded and the model built without records."""



def _ptr(a):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


class NativeModel:
    """A network's compiled library and its constants.

    Attributes
    ----------
    generated : GeneratedModel
        Source, hash key, constants, sizes
    lib : ctypes.CDLL
        The loaded library
    library_path : Path
        Where the library is cached
    build_time : float
        Seconds spent generating (and, on a cache miss, compiling)
    found_by : str
        "definition", "graph", "structure" or "generated" (below)

    Parameters
    ----------
    network : Network
        The assembled model (:class:`hydroline.engine.Network`)
    wait : bool
        Compile a library not built yet here and now (False: in a background
        process, raising :class:`~hydroline.compiled.toolchain.LibraryPending`)
    """

    def __init__(self, network, wait: bool = True):
        tic = time.perf_counter()
        self.network = network
        key, found, full, record = self._locate(network)
        self._remember(key, found)   # (before a build, which may be a background one)
        try:
            self._load(full, record is not None, wait)
        except _RecordMismatch as e:   # a record that does not fit: without records
            forget_record(record, key, why=str(e))
            key, found, full, record = self._locate(network, records=False)
            self._remember(key, found)
            self._load(full, False, wait)
        self.n, self.n_signals = int(self._sizes[0]), int(self._sizes[3])
        # (the dense Jacobian's row and column indices, each component's state block, and
        # the order limits found, by Jacobian: made on first use)
        self._jac_index = self._blocks = None
        self._limits_seen: dict = {}
        #: How the model was found: "numbers" (the record of its structure, whose C takes
        #: the components' numbers at run time, found before any graph was built),
        #: "definition" (its record, found before any graph was built), "graph" (the record
        #: of its graph's fingerprint, where the network cannot describe itself),
        #: "structure" (a known structure: constants read from the graph) or "generated" (C
        #: written)
        self.found_by = found
        self.build_time = time.perf_counter() - tic

    @property
    def numbers_record_key(self) -> str | None:
        """Key of the record of this model's structure, whose C takes the components'
        numbers at run time (:func:`~hydroline.compiled.records.numbers_key`); None where the
        network gives none.

        Returns
        -------
        str or None
            ``"numbers:<hex digest>"``, or None.
        """
        return self._numbers_key

    def _remember(self, key, found: str) -> None:
        """Record the model found or made (:meth:`_locate`): under its numbers key where its
        C takes the numbers (one record for all of them), else under its own key."""
        if self._numbers is not None and self._numbers_key is not None:
            remember_numbers_model(self._numbers_key, self.generated, self._numbers,
                                   self.library_path)
        elif found != "numbers":
            remember_model(key, self.generated, self.library_path)

    def _locate(self, network, records: bool = True):
        """Find the model's record (``records``), else generate its C; sets ``generated``
        and ``library_path``. Returns (key of its model record, how it was found, the
        library's source or a callable that makes it, the record used as (table kind, key)
        or None)."""
        # its structure's record, where its C takes the numbers at run time; else the
        # model's record: under its definition (known before any graph is built) where the
        # network can describe itself, else under its graph's fingerprint; also where the
        # graph was built before (components changed since would not be in it)
        #: (numbers and scales at the start of the constants, where a graph just built
        #: takes them at run time: its record is written under its numbers key)
        self._numbers = None
        key = self._numbers_key = numbers_key(network)
        gen, tag = known_numbers_model(key, network) if records else (None, None)
        found, record = "numbers", ("models", key)
        if gen is None:
            key = definition_key(network)
            gen, tag = known_model(key, network) if records else (None, None)
            found, record = "definition", ("models", key)
        if gen is None:   # not known: build the graph
            from . import codegen

            if getattr(network, "has_graph", True):
                # (a graph made before a component changed is not recorded under the
                # network's definition or numbers key: it may not be the changed one's)
                key = self._numbers_key = None
            model = network.compile()
            if key is None:
                key, found = model_fingerprint(model), "graph"
                record = ("models", key)
                gen, tag = known_model(key, network) if records else (None, None)
            if gen is None:   # other numbers: is the structure known?
                functions = codegen.scaled_functions(model)
                record = ("structures", structure_record_key(functions))
                gen, tag = (known_structure(functions, record[1], network) if records
                            else (None, None))
                found = "structure"
                if gen is None:   # a new structure: write its C
                    found, record = "generated", None
                    gen = codegen.generate(model, functions)
                    path, full = library_location(gen)
                    remember_structure(functions, gen, path)
                if functions[0].n_in() == 4:
                    self._numbers = functions[0].nnz_in(3)
        self.generated = gen
        if tag is not None:          # known: its C is regenerated only to rebuild a library
            path = cache_dir() / f"hl_{tag}.so"

            def full():
                from . import codegen

                made, source = library_location(codegen.generate(network.compile()))
                if made != path:
                    raise _RecordMismatch(f"it names the library {path.name}, which is not "
                                          f"this model's")
                return source
        self.library_path = path
        return key, found, full, record

    def _load(self, full, from_record: bool, wait: bool = True) -> None:
        """Load (or build) the library and check that it fits the model's sizes; a misfit
        of a model found by its record is that record's fault (:class:`_RecordMismatch`)."""
        self.cache_hit = self.library_path.exists()
        self.lib = load_library(self.library_path, full, wait, run=id(self.network))
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
        jnz : ndarray
            Nonzeros, [1/s]

        Returns
        -------
        ndarray
            The Jacobian, n x n, [1/s].
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
        jnz : ndarray
            Nonzeros of the scaled Jacobian, [1/s]

        Returns
        -------
        tuple
            (h_1, ..., h_5), [s] (inf: no limit)
        """
        from .stability import block_gather, cut_blocks, eigenvalues_of_blocks, order_step_limits

        g = self.generated
        if self._blocks is None:      # per network: the blocks and where they lie in jnz
            net = self.network
            blocks = [sl for sl in (net.state_slice(c.name) for c in net.components)
                      if sl.stop - sl.start >= 2]
            self._blocks = (blocks, block_gather(g.jac_colind, g.jac_row, blocks))
        blocks, gather = self._blocks
        if not (blocks and g.jac_nnz):
            return (np.inf,) * 5
        key = jnz.tobytes()
        limits = self._limits_seen.get(key)
        if limits is None:
            # per run: the blocks cut out of the nonzeros in one gather (as the dense
            # Jacobian's diagonal blocks), their eigenvalues and the limits
            limits = order_step_limits(eigenvalues_of_blocks(cut_blocks(jnz, gather)))
            if len(self._limits_seen) >= 64:
                self._limits_seen.clear()
            self._limits_seen[key] = limits
        return limits

    def solver(self, p=None, rtol: float = 1e-7, atol: float = 1e-8, max_step: float = 0.0,
               fixed_step: float = 0.0, max_order: int = 5, newton_coef: float = 0.1,
               order_limits: bool = True, method: str = "bdf"):
        """A fresh :class:`NativeSolver` with runtime parameters p (network defaults if None).

        Parameters
        ----------
        p : ndarray
            Runtime parameters, [SI] (the network's when None)
        rtol : float
            Relative tolerance, [-]
        atol : float
            Absolute tolerance on the scaled states, [-]
        max_step : float
            Largest step, [s] (0: none)
        fixed_step : float
            > 0: fixed-step BDF without error control, [s]
        max_order : int
            Highest BDF order (1-5)
        newton_coef : float
            Newton tolerance relative to the error-test tolerance, [-]
        order_limits : bool
            Keep each NDF order 3-5 below the step where the model's
            lightly damped fast modes would make it unstable
            (:mod:`.stability`; False: the orders are chosen by accuracy
            alone, as before)
        method : str
            "bdf": the variable-order NDF/BDF; "radau": Radau IIA of order 5;
            "auto": one of them by the model's modes at the first step
            (:class:`NativeSolver`)

        Returns
        -------
        NativeSolver
            A fresh solver with these settings.
        """
        return NativeSolver(self, p, rtol, atol, max_step, fixed_step, max_order, newton_coef,
                            order_limits, method)


class NativeSolver:
    """One integrator instance in C (state kept between calls, for chunked/streamed runs).

    Parameters
    ----------
    model : NativeModel
        The compiled library and its constants
    p : ndarray
        Runtime parameters, [SI]
    rtol : float
        Relative tolerance, [-]
    atol : float
        Absolute tolerance on the scaled states (fraction of each state's
        typical magnitude), [-]
    max_step : float
        Largest step, [s] (0: none)
    fixed_step : float
        > 0: fixed-step BDF of order max_order without error control, [s]
    max_order : int
        Highest BDF order (1-5)
    newton_coef : float
        Newton convergence tolerance relative to the error-test tolerance, [-]
    order_limits : bool
        Stability limits of the NDF orders 3-5 on the model's fast modes
        (:mod:`.stability`), set before the first step (BDF only)
    method : str
        "bdf" (the default): the variable-order NDF/BDF of ``bdf.c``;
        "radau": the three-stage Radau IIA collocation method of order 5
        (L-stable: no order limits; no fixed-step mode); "auto": Radau IIA
        at ``RADAU_TOLERANCE_FACTOR`` times the tolerances where the model's
        modes hold the NDF order 3 below ``RADAU_BELOW`` (decided before
        the first step, :attr:`chosen_method`), else the BDF
    """

    #: Most steps one :meth:`advance` call may take before it gives up (a stalled run returns
    #: control instead of hanging in C, where Ctrl-C cannot reach it).
    max_steps_per_call = 5_000_000

    #: Integration methods of the C core, name -> its number in ``hl_set_method``
    METHODS = {"bdf": 0, "radau": 1}

    #: method="auto" takes Radau IIA where the NDF order 3 is unstable above this step on the
    #: model's modes (:mod:`.stability`), [s]: there the BDF's steps are held at order 2 or at
    #: that limit, where Radau's are set by accuracy. Measured (benchmarks/README.md, "Radau
    #: IIA by default"): Radau's CPU against the BDF's 1.08x at 158 us (the default rig), 1.0x
    #: at 51-53 us, 0.78x at 33 us (20 modes), 0.62x at 22 us (30 modes)
    RADAU_BELOW = 40e-6

    #: method="auto" runs Radau IIA at this times the given rtol and atol: where its error
    #: matches the BDF's at the given ones (BDF 1e-6 against Radau 1e-4, the worst metric: the
    #: 0.3 m hose 0.44 and 0.43 %; 30 modes per section 4.2 and 0.017 %), [-]
    RADAU_TOLERANCE_FACTOR = 100.0

    #: The loosest absolute tolerance (on the scaled states, its tolerance factor applied)
    #: :meth:`relax` gives Radau IIA, [-]: the piston's velocity (scale 1 m/s) then keeps
    #: errors below 1e-5 m/s, a tenth of the friction's regularisation velocity (1e-4 m/s).
    #: Relaxed like the BDF's, "auto"'s Radau (already 100x) went to 3e-4: the velocity on its
    #: stop jittered across the friction's steep slope, the Newton iteration kept failing and
    #: the 30-mode run took 1 995 steps against 1 230 not relaxed (capped: 1 060); 5.5e-5
    #: still 1 300 (benchmarks/README.md, "Radau IIA after the stop").
    RADAU_RELAXED_ATOL_MAX = 1e-5

    #: :data:`RADAU_RELAXED_ATOL_MAX` where the model declares ceilings on its states'
    #: absolute tolerances (``Network.state_atol_ceilings``: the Stribeck friction's holds
    #: the piston velocity at a tenth of its regularisation velocity), [-]. The 30-mode run
    #: after the stop (benchmarks/README.md, "Per-state tolerance ceilings"): 828 steps
    #: against 1 060 at 1e-5 for every state; uncapped (3e-4) 837, the return port 0.59 %
    #: of its excursion off a tight reference against 0.29 % here.
    RADAU_RELAXED_ATOL_MAX_WITH_CEILINGS = 1e-4

    def __init__(self, model: NativeModel, p, rtol, atol, max_step, fixed_step, max_order,
                 newton_coef, order_limits: bool = True, method: str = "bdf"):
        if not (rtol > 0 and atol > 0):
            raise ValueError(f"rtol and atol must be > 0 [-], got {rtol!r} and {atol!r}")
        if method not in self.METHODS and method != "auto":
            raise ValueError(f"method must be one of {', '.join(self.METHODS)} or auto, got "
                             f"{method!r}")
        if method == "radau" and fixed_step > 0:
            raise ValueError("fixed_step is a mode of the BDF method only (method='bdf')")
        if method == "auto" and (fixed_step > 0 or not order_limits):
            method = "bdf"          # (the choice reads the order limits; fixed step: the BDF's)
        self.method = method
        # the method stepping (method="auto": "bdf" until the first step decides) and the
        # factor its tolerances take over the given ones
        self.chosen_method = "bdf" if method == "auto" else method
        self._tolerance_factor = 1.0
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
        self._limits = () if order_limits and not fixed_step > 0 and method != "radau" else None
        self._start = None
        self._jnz = None                                  # (scaled_jacobian's buffer)
        self._h = lib.hl_new()
        self._settings = (max_step, fixed_step, int(max_order), newton_coef)
        self.rtol, self.atol = float(rtol), float(atol)
        self._done = np.zeros(1, dtype=np.intc)      # (hl_advance's count of rows written)
        lib.hl_setup(self._h, self.p.ctypes.data, self._c.ctypes.data, self._scale.ctypes.data,
                     rtol, atol, *self._settings)
        lib.hl_set_max_steps(self._h, self.max_steps_per_call)
        lib.hl_set_method(self._h, self.METHODS[self.chosen_method])
        # the states' ceilings on their absolute tolerances, scaled (inf: none)
        ceilings = np.asarray(getattr(net, "state_atol_ceilings", ()), dtype=float)
        self._ceilings = bool(ceilings.size) and bool(np.isfinite(ceilings).any())
        if self._ceilings:
            self._atol_ceilings = np.ascontiguousarray(ceilings / self._scale)
            lib.hl_set_atol_ceilings(self._h, self._atol_ceilings.ctypes.data)

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
        p : ndarray
            Runtime parameters, [SI]
        """
        p = self._checked_parameters(p)
        if p.tobytes() == self.p.tobytes():
            return
        self.p = p
        self._lib.hl_set_parameters(self._h, self.p.ctypes.data)

    def set_tolerances(self, rtol: float, atol: float) -> None:
        """Use other tolerances from the next step on, keeping the step size, the order and
        the history of the run in progress (e.g. looser once every metric's window has ended).

        Parameters
        ----------
        rtol : float
            Relative tolerance, [-]
        atol : float
            Absolute tolerance on the scaled states, [-]
        """
        if not (rtol > 0 and atol > 0):
            raise ValueError(f"rtol and atol must be > 0 [-], got {rtol!r} and {atol!r}")
        self.rtol, self.atol = float(rtol), float(atol)
        # (hl_setup sets numbers and settings only; the run's state stays; it clears the
        # order limits, set again here)
        k = self._tolerance_factor
        self._lib.hl_setup(self._h, self.p.ctypes.data, self._c.ctypes.data,
                           self._scale.ctypes.data, k * self.rtol, k * self.atol, *self._settings)
        if self._limits and self.chosen_method == "bdf":
            arr = np.ascontiguousarray(self._limits, dtype=float)
            self._lib.hl_set_order_limits(self._h, arr.ctypes.data)

    def relax(self, rtol: float, atol: float) -> None:
        """Looser tolerances for the rest of the run, from the next step on (step size, order
        and history kept): where no metric looks any more, after the piston's stop that ends
        the metrics window (:func:`hydroline.scenarios.simulate`'s ``after_stop_rtol``).

        The BDF takes both. Radau IIA takes ``rtol``, and ``atol`` up to
        ``RADAU_RELAXED_ATOL_MAX`` (after its tolerance factor; never tighter than its
        absolute tolerance before), ``RADAU_RELAXED_ATOL_MAX_WITH_CEILINGS`` where the
        model declares ceilings on its states' absolute tolerances (which hold in both
        methods whatever ``atol`` is).

        Parameters
        ----------
        rtol : float
            Relative tolerance, [-]
        atol : float
            Absolute tolerance on the scaled states (the BDF's), [-]
        """
        if self.chosen_method == "radau":
            cap = (self.RADAU_RELAXED_ATOL_MAX_WITH_CEILINGS if self._ceilings
                   else self.RADAU_RELAXED_ATOL_MAX) / self._tolerance_factor
            atol = self.atol if cap <= self.atol else min(atol, cap)
        self.set_tolerances(rtol, atol)

    def start(self, t0: float, x0, t_bound: float):
        """Begin a segment [t0, t_bound] from x0 (order 1; inputs may jump at t0).

        Parameters
        ----------
        t0 : float
            Segment start, [s]
        x0 : ndarray
            States there, [SI]
        t_bound : float
            Segment end, [s]
        """
        x0 = np.ascontiguousarray(np.asarray(x0, dtype=float))
        if x0.shape != (self.model.n,):
            raise ValueError(f"initial state x0 must have {self.model.n} entries, got {x0.size}")
        if not (t_bound > t0):
            raise ValueError(f"segment end t_bound must be after t0 [s], got {t0!r}, {t_bound!r}")
        self._lib.hl_init(self._h, float(t0), x0.ctypes.data, float(t_bound))
        self._t_bound = float(t_bound)
        self._start = (float(t0), x0)

    def _set_order_limits(self, t0: float, x0) -> None:
        """Cap each NDF order's step where it would be unstable on the model's lightly damped
        fast modes (:meth:`NativeModel.order_limits`, from the Jacobian at (t0, x0)); kept for
        the solver's life (a hose's modes are linear)."""
        self._limits = self.model.order_limits(self.scaled_jacobian_nonzeros(t0, x0))
        if self.method == "auto" and self._limits[2] < self.RADAU_BELOW:
            self._use_radau(t0, x0)
            return
        arr = np.ascontiguousarray(self._limits, dtype=float)
        self._lib.hl_set_order_limits(self._h, arr.ctypes.data)

    def _use_radau(self, t0: float, x0) -> None:
        """method="auto" chose Radau IIA: its tolerances, and the segment started again with
        it (before its first step)."""
        self.chosen_method = "radau"
        self._lib.hl_set_method(self._h, self.METHODS["radau"])
        self._tolerance_factor = self.RADAU_TOLERANCE_FACTOR
        self.set_tolerances(self.rtol, self.atol)
        self._lib.hl_init(self._h, float(t0), x0.ctypes.data, float(self._t_bound))

    @property
    def order_limits(self) -> tuple:
        """Largest step of each order 1-5, [s] (inf: none), set before the first step, from
        the Jacobian at that segment's start (empty before; None in fixed-step mode)."""
        return self._limits

    def advance(self, t_out, signals: bool = True, table: bool = False, out=None):
        """Integrate through the output times (ascending, within the segment).

        Parameters
        ----------
        t_out : ndarray
            Output times, [s]
        signals : bool
            Also return every signal at those times
        table : bool
            One array, signals then states, instead of a pair
        out : ndarray
            Where to write the rows: C-contiguous float64, one row per output
            time of (signals then) states, e.g. a slice of a run's whole table
            (no array made, nothing copied afterwards); None: a new array, [SI]

        Returns
        -------
        X : ndarray
            States, [n_out, n_states], [SI]; with ``table=True`` the only result:
            one array [n_out, n_signals + n_states] (signals first), [SI]
        Y : ndarray
            Signals, [n_out, n_signals], [SI] (None if not asked)
        """
        # (a run calls this once per block of rows: ~10 times for a sweep's variant; its
        # checks and pointers are kept to a few array operations)
        t_out = np.ascontiguousarray(t_out, dtype=float)
        if self._t_bound is None:
            raise RuntimeError("call start(t0, x0, t_bound) before advance()")
        rows = len(t_out)
        if self._limits == () and rows and t_out[-1] > self._start[0]:
            self._set_order_limits(*self._start)   # once per solver, before its first step
        slack = 1e-9 * max(1.0, abs(self._t_bound))   # grid times rounded onto the segment end
        if rows and (t_out[-1] > self._t_bound + slack
                     or (rows > 1 and (t_out[1:] < t_out[:-1]).any())):
            raise ValueError(f"output times must ascend and lie within the segment "
                             f"(t_bound = {self._t_bound:g} s)")
        n, ny = self.model.n, self.model.n_signals
        ld = (ny if signals else 0) + n
        if out is None:
            block = np.empty((rows, ld))
        else:
            block = out
            flags = getattr(out, "flags", None)
            if not (isinstance(out, np.ndarray) and out.dtype == np.float64
                    and out.shape == (rows, ld) and flags.c_contiguous and flags.writeable):
                raise ValueError(f"out must be a writeable C-contiguous float64 array of shape "
                                 f"{(rows, ld)}")
        X = block[:, ld - n:]
        Y = block[:, :ny] if signals else None
        done = self._done
        done[0] = 0
        # (X and Y are column ranges of block: their first elements' addresses, rows ld apart)
        address = block.ctypes.data
        rc = self._lib.hl_advance(self._h, rows, t_out.ctypes.data, address + 8 * (ld - n),
                                  address if signals else None, done.ctypes.data, ld)
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
        if done[0] != rows:
            raise RuntimeError(f"compiled integrator stopped after {int(done[0])} of "
                               f"{rows} output times")
        if not np.all(np.isfinite(X)):
            raise RuntimeError("compiled integrator produced non-finite states")
        return block if table else (X, Y)

    def state(self):
        """Current (x [SI], t [s]).

        Returns
        -------
        x : ndarray
            States, [SI].
        t : float
            Time, [s].
        """
        x = np.empty(self.model.n)
        t = ctypes.c_double()
        self._lib.hl_get_state(self._h, _ptr(x), ctypes.byref(t))
        return x, t.value

    def stats(self) -> dict:
        """Steps, f and Jacobian evaluations, LU factorizations, rejected steps, ...

        Returns
        -------
        dict
            Counter name -> count.
        """
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
        t : float
            Time, [s]
        x : ndarray
            States, [SI]
        out : ndarray
            Array to fill, [1/s] (made when None)

        Returns
        -------
        ndarray
            The nonzeros, [1/s].
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
        t : float
            Time, [s]
        x : ndarray
            States, [SI]

        Returns
        -------
        ndarray
            The Jacobian, n x n, [1/s].
        """
        self._jnz = self.scaled_jacobian_nonzeros(t, x, self._jnz)
        return self.model.dense_jacobian(self._jnz)

    def signals(self, t: float, x) -> np.ndarray:
        """Every signal at (t, x) from the compiled code, in ``network.signal_names`` order,
        [SI]. Ends the segment in progress (:meth:`start` begins the next); :meth:`stats`
        counts the start's two evaluations of f.

        Parameters
        ----------
        t : float
            Time, [s]
        x : ndarray
            States, [SI]

        Returns
        -------
        ndarray
            Signal values, [SI].
        """
        self.start(t, x, t + max(1.0, abs(t)))
        _, y = self.advance([t])       # an output at the segment's start: no step taken
        return y[0]

    def rhs(self, t: float, x) -> np.ndarray:
        """dx/dt at (t, x) from the compiled code, [SI/s].

        Parameters
        ----------
        t : float
            Time, [s]
        x : ndarray
            States, [SI]

        Returns
        -------
        ndarray
            dx/dt, [SI/s].
        """
        x = np.ascontiguousarray(np.asarray(x, dtype=float))
        if x.shape != (self.model.n,):
            raise ValueError(f"state x must have {self.model.n} entries, got {x.size}")
        dx = np.empty(self.model.n)
        self._lib.hl_rhs(self._h, float(t), x.ctypes.data, dx.ctypes.data)
        return dx



def needs_build(network) -> bool:
    """Whether running ``network`` on the compiled core would first write and compile a new
    library (its definition and its structure unknown to the cache, or the library missing):
    what a command estimates before a run. Looked up as :class:`NativeModel` does, without
    writing C; the CasADi graph is built (on ``network``) where the definition is unknown.

    Parameters
    ----------
    network : Network
        The assembled model

    Returns
    -------
    bool
        True when the first run will compile (seconds to minutes, by the model's size)
    """
    if network.__dict__.get("_native_model") is not None:
        return False
    _, tag = known_numbers_model(numbers_key(network), network)
    if tag is None:
        _, tag = known_model(definition_key(network), network)
    if tag is None:
        model = network.compile()
        _, tag = known_model(model_fingerprint(model), network)
        if tag is None:
            from . import codegen

            functions = codegen.scaled_functions(model)
            _, tag = known_structure(functions, structure_record_key(functions), network)
    return tag is None or not library_check(cache_dir() / f"hl_{tag}.so")[0]


def native_model(network, wait: bool | None = None) -> NativeModel:
    """The network's :class:`NativeModel`, built once per network object.

    Parameters
    ----------
    network : Network
        The assembled model
    wait : bool
        Compile a library not built yet here and now; False: start its
        build in a background process and raise ``LibraryPending`` (the
        caller goes on without it); None: False where
        :func:`builds_in_background`, else True

    Raises
    ------
    CompilerUnavailable
        No C compiler, or it failed
    UnsupportedOperation
        The graph holds an operation the C writer does not know
    LibraryPending
        Not ``wait``: the library is being built in the background

    Returns
    -------
    NativeModel
        The loaded model.
    """
    nm = network.__dict__.get("_native_model")
    if nm is None:
        nm = NativeModel(network, wait=not builds_in_background() if wait is None else wait)
        network.__dict__["_native_model"] = nm
    return nm
