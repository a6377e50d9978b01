"""PIQP adapter: sparse QP / LP by a proximal interior-point method.

Problem (PIQP's native form, piqp >= 0.5)::

    minimize    1/2 x' P x + c' x
    subject to  A x = b
                h_l <= G x <= h_u
                x_lb <= x <= x_ub

``setup`` builds one ``piqp.SparseSolver``; ``update`` passes new vectors and, when
the sparsity pattern is unchanged, new matrix values in place, so PIQP reuses its
memory, ordering and symbolic factorisation. PIQP 0.7 is an interior-point method
with no primal/dual warm start (upstream PR #39 adds it): every solve restarts from
PIQP's own initial point, which is what interior-point methods do well. If a matrix
update changes the sparsity pattern, the solver is set up again
(``info["rebuilt"] = True``). Only the upper triangle of P is used (PIQP convention).
Scale the variables (issue #4: u in units of u_max, positions in km) for speed.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from proxops.errors import input_error
from proxops.solvers import _util
from proxops.solvers.base import SolverAdapter
from proxops.solvers.feasibility import farkas_margin
from proxops.solvers.forms import QuadraticProgram
from proxops.solvers.result import SolverResult, SolveStatus, error_message, failed_result

# piqp.Status values (docs/_common/status_code_table.md of PREDICT-EPFL/piqp).
STATUS_MAP = {
    "PIQP_SOLVED": SolveStatus.OPTIMAL,
    "PIQP_MAX_ITER_REACHED": SolveStatus.MAX_ITER,
    "PIQP_PRIMAL_INFEASIBLE": SolveStatus.INFEASIBLE,
    "PIQP_DUAL_INFEASIBLE": SolveStatus.UNBOUNDED,
    "PIQP_NUMERICS": SolveStatus.NUMERICAL_ERROR,
    "PIQP_UNSOLVED": SolveStatus.NUMERICAL_ERROR,
    "PIQP_INVALID_SETTINGS": SolveStatus.NUMERICAL_ERROR,
}

_MATRICES = ("P", "A", "G")
# QuadraticProgram field -> PIQP name (A_eq rows are PIQP's equalities, the rows of A its G rows)
_FORM_NAMES = {"P": "P", "q": "c", "A_eq": "A", "b_eq": "b", "A": "G", "bl": "h_l", "bu": "h_u",
               "lb": "x_lb", "ub": "x_ub"}
_VECTORS = ("c", "b", "h_l", "h_u", "x_lb", "x_ub")


@njit(cache=True)
def _has_nonfinite(a) -> int:
    for v in a:
        if not math.isfinite(v):
            return 1
    return 0


@njit(cache=True)
def _has_nan(a) -> int:
    for v in a:
        if v != v:
            return 1
    return 0


@njit(cache=True)
def _scan_fast(A, G, c, b, h_l, h_u, x_lb, x_ub, free_now, free_out):
    """One pass over the data of :meth:`PiqpQP.update_fast` (matrix values and vectors as stored): what
    ``BadData.check`` of each field, ``_check_crossed`` and ``_free_variables`` compute separately.
    Returns (bad, crossed, at, n_free, same_free, shifted): ``bad`` bit k set when field k (A, G, c, b,
    h_l, h_u, x_lb, x_ub) holds NaN (or inf in A, G, c, b); ``crossed`` 1 for the first h_l > h_u at
    row ``at``, else 2 for the first x_lb > x_ub, else 0; ``free_out[:n_free]`` the variables not fixed by
    a finite x_lb == x_ub (in order); ``same_free`` whether they equal ``free_now``; ``shifted`` whether
    a fixed variable sits at a nonzero value."""
    bad = (_has_nonfinite(A) | _has_nonfinite(G) << 1 | _has_nonfinite(c) << 2 | _has_nonfinite(b) << 3
           | _has_nan(h_l) << 4 | _has_nan(h_u) << 5 | _has_nan(x_lb) << 6 | _has_nan(x_ub) << 7)
    crossed, at = 0, -1
    for r in range(h_l.shape[0]):
        if h_l[r] > h_u[r]:
            crossed, at = 1, r
            break
    if crossed == 0:
        for r in range(x_lb.shape[0]):
            if x_lb[r] > x_ub[r]:
                crossed, at = 2, r
                break
    n_free = 0
    shifted = False
    for j in range(x_lb.shape[0]):
        lo = x_lb[j]
        if lo == x_ub[j] and math.isfinite(lo):
            if lo != 0.0:
                shifted = True
        else:
            free_out[n_free] = j
            n_free += 1
    same = n_free == free_now.shape[0]
    if same:
        for q in range(n_free):
            if free_out[q] != free_now[q]:
                same = False
                break
    return bad, crossed, at, n_free, same, shifted


def _on_pattern(d: dict, key: str, m) -> bool:
    """``m`` is None or carries the read-only index arrays the stored matrix ``d[key]`` was last refilled
    from (:func:`_util.refill_same_pattern`): its values may be copied in place."""
    if m is None:
        return True
    src = getattr(d[key], "_pattern_source", None)
    return src is not None and src[0] is m.indices and src[1] is m.indptr
_NO_FREE = np.empty(0, dtype=np.int64)


_KEPT: dict = {}  # (role, pattern, free set) -> (slots, matrix) of _kept, shared by every PiqpQP of the process


def _kept(role: str, M, free: np.ndarray):
    """``_util.keep_columns(M, free)`` (and rows ``free`` for P): the same entries in the same order, from
    index maps cached per (role, sparsity pattern, free set) across solvers (a shrinking-horizon MPC sets
    up one problem per node, the same ones in every run of a campaign). The matrix returned is refilled by
    the next call with the same key: PIQP copies it in ``setup`` / ``update``."""
    digest = getattr(M, "_kept_digest", None)
    if digest is None:  # the stored matrices keep their pattern (refilled in place) or are replaced
        digest = M._kept_digest = hash((M.shape, M.indptr.tobytes(), M.indices.tobytes()))
    key = (role, digest, free.tobytes())
    hit = _KEPT.get(key)
    if hit is None:
        probe = type(M)((np.arange(M.nnz, dtype=float), M.indices, M.indptr), shape=M.shape)
        R = _util.keep_columns(probe, free, rows=free if role == "P" else None)
        if len(_KEPT) >= 512:
            _KEPT.clear()
        hit = _KEPT[key] = (R.data.astype(np.intp), R)
    slots, R = hit
    np.take(M.data, slots, out=R.data, mode="clip")  # slots in range: no buffered copy (mode "raise" makes one)
    return R


class PiqpQP(SolverAdapter):
    """Persistent PIQP sparse solver for ``min 1/2 x'Px + c'x s.t. Ax = b, h_l <= Gx <= h_u, x_lb <= x <= x_ub``.

    Settings: ``max_iter``, ``eps_abs``, ``eps_rel``, ``verbose``; ``settings`` passes
    native ``piqp.Settings`` attributes (e.g. ``preconditioner_iter``, ``kkt_solver``).

    Infeasibility certificate (``certify_after`` iterations, ``certify_margin`` row units): PIQP 0.7
    often runs to ``max_iter`` on an infeasible problem instead of reporting it (its iterate then
    sits at a least-violation point with growing duals). With ``certify_after`` set, ``solve`` first
    stops after that many iterations; when PIQP has not finished, its duals are checked as a Farkas
    certificate (:func:`proxops.solvers.feasibility.farkas_margin`): if they prove that every x within
    the bounds violates some row by more than ``certify_margin``, the result is INFEASIBLE
    (``raw_status`` "farkas_certificate", ``info["infeasibility_margin"]``); otherwise PIQP solves
    again with the full ``max_iter`` (PIQP restarts from its own initial point, so this solve is
    bit-identical to one without the early stop) and its duals are checked once more if it still
    does not finish. Solves that converge within ``certify_after`` iterations are unchanged.

    Fixed variables (``drop_fixed``): PIQP 0.7 has no presolve, and a variable held by
    ``x_lb == x_ub`` stays in its KKT system as a pair of active bounds (a shrinking-horizon MPC fixes
    its past inputs this way). With ``drop_fixed`` those variables are removed from the problem PIQP
    sees (their values moved into c, b, h_l, h_u) and put back in ``x``; the factorisation then has
    only the free variables (srf-vbar: 0.74 ms instead of 2.9 ms per solve on average, and PIQP itself
    reports the infeasible problems it otherwise runs to ``max_iter`` on). While the set of fixed
    variables is unchanged, updates stay in place; a new set is a new set-up (``info["rebuilt"]``).
    The objective is evaluated on the full ``x``; the row duals are PIQP's (the bound duals of
    dropped variables are not computed).
    """

    name = "piqp"
    forms = (QuadraticProgram,)

    def __init__(self, *, max_iter: int | None = None, eps_abs: float | None = None,
                 eps_rel: float | None = None, verbose: bool = False, settings: dict | None = None,
                 certify_after: int | None = None, certify_margin: float = 0.0, drop_fixed: bool = False):
        self._piqp = _util.import_solver("piqp", "piqp")
        self._drop_fixed = bool(drop_fixed)
        self._free = None  # indices of the variables PIQP sees (None: all of them)
        self._shifted = False  # with _free: a fixed variable is nonzero (PIQP's objective then lacks its terms)
        if certify_after is not None and not int(certify_after) >= 1:
            raise input_error("certify_after", certify_after, "must be an iteration count >= 1 (or None)")
        if not (certify_margin >= 0.0 and math.isfinite(certify_margin)):
            raise input_error("certify_margin", certify_margin, "must be finite and >= 0 (row units)")
        self._certify_after = None if certify_after is None else int(certify_after)
        self._certify_margin = float(certify_margin)
        native = dict(settings or {})
        if max_iter is not None:
            native["max_iter"] = int(max_iter)
        if eps_abs is not None:
            native["eps_abs"] = float(eps_abs)
        if eps_rel is not None:
            native["eps_rel"] = float(eps_rel)
        native["verbose"] = bool(verbose)
        self._native = self._native_settings(native, {k for k in dir(self._piqp.Settings) if not k.startswith("_")},
                                             "piqp")
        self._solver = None
        self._data: dict | None = None

    # ------------------------------------------------------------------ set-up
    def _setup_form(self, problem: QuadraticProgram) -> None:
        """Set up a :class:`QuadraticProgram`: A_eq/b_eq become PIQP's equality rows and the rows of A
        its ``h_l <= G x <= h_u`` rows, as they are (rows of A with bl == bu are NOT moved: the row
        structure stays fixed so ``update`` keeps PIQP's factorisation; :func:`solve_qp` splits them
        for one-off solves)."""
        pr = problem
        self.setup_native(pr.P, pr.q, pr.A_eq, pr.b_eq, pr.A, pr.bl, pr.bu, pr.lb, pr.ub)

    def _native_fields(self) -> dict:
        return _FORM_NAMES

    def _update_form(self, **fields) -> None:
        self.update_native(**{_FORM_NAMES[k]: v for k, v in fields.items()})

    def warm_start(self, x=None, y=None) -> bool:
        """PIQP 0.7 has no primal/dual warm start (upstream PR #39): nothing is used; returns False."""
        return False

    def setup_native(self, P, c, A=None, b=None, G=None, h_l=None, h_u=None, x_lb=None, x_ub=None) -> None:
        """Set up the problem in PIQP's form. P may be None (LP); A/b and G/(h_l, h_u) come in pairs.

        Matrices may be dense or scipy.sparse; vectors allow +-inf in h_l, h_u, x_lb,
        x_ub (an infinite side is no constraint). Shape errors raise ProxopsInputError;
        NaN data makes ``solve`` return NUMERICAL_ERROR. ``update`` then takes these names.
        """
        self._native_setup_done()
        c = _util.cost_vector("c", c)
        n = c.shape[0]
        p = _util.rows_of("A", A)
        m = _util.rows_of("G", G)
        if A is None and b is not None:
            raise input_error("b", "given without A", "pass A with b (equality rows A x = b)")
        if G is None and (h_l is not None or h_u is not None):
            raise input_error("h_l/h_u", "given without G", "pass G with h_l/h_u")
        self.n, self.p, self.m = n, p, m
        self._bad = _util.BadData()
        d = {
            "P": _util.csc_matrix("P", P, (n, n), upper=True, allow_nonfinite=True),
            "A": _util.csc_matrix("A", A, (p, n), allow_nonfinite=True),
            "G": _util.csc_matrix("G", G, (m, n), allow_nonfinite=True),
            "c": c,
            "b": _util.vector("b", b, p, fill=0.0 if p == 0 else None, allow_nan=True),
            "h_l": _util.vector("h_l", h_l, m, fill=-np.inf, allow_inf=True, allow_nan=True),
            "h_u": _util.vector("h_u", h_u, m, fill=np.inf, allow_inf=True, allow_nan=True),
            "x_lb": _util.vector("x_lb", x_lb, n, fill=-np.inf, allow_inf=True, allow_nan=True),
            "x_ub": _util.vector("x_ub", x_ub, n, fill=np.inf, allow_inf=True, allow_nan=True),
        }
        for key, value in d.items():
            self._bad.check(key, value, allow_inf=key in ("h_l", "h_u", "x_lb", "x_ub"))
        self._data = d
        self._build()
        self._rebuilt = False

    def _build(self, free=False, shifted: bool | None = None) -> None:
        """(Re)create the PIQP solver from the stored data (``free``: the free set when the caller just
        computed it after checking the bounds, else both are done here; ``shifted``: whether a fixed
        variable is nonzero, when the caller knows)."""
        if free is False:
            self._check_crossed()
            free = self._free_variables()
        self._solver_error = None
        self._rebuilt = True
        self._solver = None  # release the previous factorisation before allocating the next one
        try:
            solver = self._piqp.SparseSolver()
            for key, value in self._native.items():
                setattr(solver.settings, key, value)
            self._free = free
            r = self._piqp_data(("P", "c", "A", "b", "G", "h_l", "h_u", "x_lb", "x_ub"),
                                None if free is None else shifted)
            solver.setup(
                r["P"], r["c"],
                r["A"] if self.p else None, r["b"] if self.p else None,
                r["G"] if self.m else None, r["h_l"] if self.m else None, r["h_u"] if self.m else None,
                r["x_lb"], r["x_ub"],
            )
        except Exception as exc:
            self._solver = None
            self._solver_error = error_message(exc)
            return
        self._solver = solver

    def _free_variables(self) -> np.ndarray | None:
        """Indices of the variables that are not fixed by ``x_lb == x_ub`` (finite), with
        ``drop_fixed``; None when every variable is free (or none is: PIQP needs one)."""
        if not self._drop_fixed:
            return None
        d = self._data
        fixed = (d["x_lb"] == d["x_ub"]) & np.isfinite(d["x_lb"])
        if not fixed.any() or fixed.all():
            return None
        return np.flatnonzero(~fixed)

    def _piqp_data(self, keys, shifted: bool | None = None) -> dict:
        """The stored data named ``keys`` as PIQP gets them: without the fixed variables when
        ``_free`` is set (their values moved to the right-hand sides: c += P_sym[:, fixed] x_fixed,
        b -= A x_fixed, h -= G x_fixed). ``shifted`` (whether a fixed value is nonzero) when the caller
        computed it from the stored bounds; recorded for :meth:`solve`."""
        d, free = self._data, self._free
        if free is None:
            return {k: d[k] for k in keys}
        x_fixed = None
        if shifted is None:
            x_fixed = d["x_lb"].copy()
            x_fixed[free] = 0.0
            shifted = bool(np.any(x_fixed))
        self._shifted = shifted
        if shifted and x_fixed is None:
            x_fixed = d["x_lb"].copy()
            x_fixed[free] = 0.0
        out = {}
        for k in keys:
            v = d[k]
            if k in ("P", "A", "G"):
                out[k] = _kept(k, v, free)
            elif k == "c":
                out[k] = (v + _util.symmetric_upper_product(d["P"], x_fixed))[free] if shifted else v[free]
            elif k == "b":
                out[k] = v - d["A"] @ x_fixed if shifted and self.p else v
            elif k in ("h_l", "h_u"):
                out[k] = v - d["G"] @ x_fixed if shifted and self.m else v
            else:  # x_lb, x_ub
                out[k] = v[free]
        return out

    def _check_crossed(self) -> None:
        self._check_crossed_pairs((("h_l", "h_u", "G row"), ("x_lb", "x_ub", "bound of x")))

    # ------------------------------------------------------------------ update
    def update_native(self, *, P=None, c=None, A=None, b=None, G=None, h_l=None, h_u=None,
                      x_lb=None, x_ub=None) -> None:
        """Change data in place (same sizes, PIQP's names). A matrix with a new sparsity pattern
        triggers a full set-up (reported as ``info["rebuilt"]`` on the next result)."""
        if self._data is None:
            raise input_error("PiqpQP.update", "called before setup", "call setup() first")
        d = self._data
        shapes = {"P": (self.n, self.n), "A": (self.p, self.n), "G": (self.m, self.n)}
        sizes = {"c": self.n, "b": self.p, "h_l": self.m, "h_u": self.m, "x_lb": self.n, "x_ub": self.n}
        given = {"P": P, "A": A, "G": G, "c": c, "b": b, "h_l": h_l, "h_u": h_u, "x_lb": x_lb, "x_ub": x_ub}
        changed, rebuild = {}, False
        for key, value in given.items():
            if value is None:
                continue
            if key in _MATRICES:
                new = _util.refill_same_pattern(d[key], value) if key != "P" else None
                if new is None:
                    new = _util.csc_matrix(key, value, shapes[key], upper=key == "P", allow_nonfinite=True)
                    if not _util.same_pattern(new, d[key]):
                        rebuild = True
            else:
                new = _util.vector(key, value, sizes[key], allow_inf=key not in ("c", "b"), allow_nan=True)
            d[key] = new
            if self._bad.check(key, new, allow_inf=key in ("h_l", "h_u", "x_lb", "x_ub")):
                changed[key] = new
        self._apply(changed, rebuild)

    def update_fast(self, *, c=None, A=None, b=None, G=None, h_l=None, h_u=None, x_lb=None, x_ub=None,
                    **others) -> None:
        """Trusted :meth:`update_native` for a loop that owns its data layout (the srf MPC's per-node data):
        vectors are float64 1-D arrays of the right sizes, kept as given (not copied: the caller does not
        write them afterwards); A and G are canonical CSC matrices on the stored pattern, passed with the
        same read-only index arrays every time (:func:`_util.refill_same_pattern`). NaN data and crossed
        bounds are still caught, and PIQP gets the calls :meth:`update_native` would make. Anything else
        (P, another pattern, a first update) takes :meth:`update_native`."""
        d = self._data
        mats = ("A", "G")
        fast = d is not None and not others and _on_pattern(d, "A", A) and _on_pattern(d, "G", G)
        if not fast:
            self.update_native(c=c, A=A, b=b, G=G, h_l=h_l, h_u=h_u, x_lb=x_lb, x_ub=x_ub, **others)
            return
        given = {}
        for key, value in (("A", A), ("G", G), ("c", c), ("b", b), ("h_l", h_l), ("h_u", h_u), ("x_lb", x_lb),
                           ("x_ub", x_ub)):
            if value is None:
                continue
            if key in mats:
                d[key].data[:] = value.data
                value = d[key]
            d[key] = value
            given[key] = value
        # one jitted pass for the NaN checks, crossed bounds and the free set of the stored data (_scan_fast);
        # any bad field (now or before) takes the per-field checks of update_native's path
        free_out = np.empty(self.n, dtype=np.intp)
        bad, crossed, at, n_free, same, shifted = _scan_fast(
            d["A"].data, d["G"].data, d["c"], d["b"], d["h_l"], d["h_u"], d["x_lb"], d["x_ub"],
            _NO_FREE if self._free is None else self._free, free_out)
        if bad or self._bad.fields:
            changed = {k: v for k, v in given.items()
                       if self._bad.check(k, v, allow_inf=k in ("h_l", "h_u", "x_lb", "x_ub"))}
            self._apply(changed, False)
            return
        self._crossed = None if not crossed else (
            f"h_l > h_u on G row {at}" if crossed == 1 else f"x_lb > x_ub on bound of x {at}")
        free = False
        rebuild = False
        if self._drop_fixed and ("x_lb" in given or "x_ub" in given):
            free = None if n_free in (0, self.n) else free_out[:n_free]
            if (free is None) != (self._free is None) or (free is not None and not same):
                rebuild = True  # another set of fixed variables: another problem for PIQP
            elif free is not None:
                given.update(dict.fromkeys(("c", "b", "h_l", "h_u"), None))  # the fixed values may have moved
        if rebuild or self._solver is None:
            self._build(free, shifted)
            return
        self._pass(given)

    def _apply(self, changed: dict, rebuild: bool) -> None:
        """Pass the stored fields named in ``changed`` to PIQP (in place), or set it up again when the
        pattern or the set of fixed variables changed."""
        self._check_crossed()
        if self._bad.fields:
            return  # solve() reports NUMERICAL_ERROR; data are passed once they are finite again
        free = False
        if self._drop_fixed and ("x_lb" in changed or "x_ub" in changed):
            free = self._free_variables()
            if (free is None) != (self._free is None) or (free is not None and not np.array_equal(free, self._free)):
                rebuild = True  # another set of fixed variables: another problem for PIQP
            elif free is not None:
                changed.update(dict.fromkeys(("c", "b", "h_l", "h_u"), None))  # the fixed values may have moved
        if rebuild or self._solver is None:
            self._build(free)
            return
        self._pass(changed)

    def _pass(self, changed: dict) -> None:
        """Hand the stored fields named in ``changed`` to PIQP's in-place update."""
        if not changed:
            return
        changed = self._piqp_data(tuple(changed))
        kwargs = {k: v for k, v in changed.items() if not ((k in ("A", "b") and not self.p)
                                                            or (k in ("G", "h_l", "h_u") and not self.m))}
        # piqp's update names the bounds x_l / x_u (setup takes them positionally)
        kwargs = {{"x_lb": "x_l", "x_ub": "x_u"}.get(k, k): v for k, v in kwargs.items()}
        try:
            self._solver.update(**kwargs)
        except Exception as exc:
            self._solver_error = error_message(exc)

    # ------------------------------------------------------------------ solve
    def _solve_certified(self):
        """PIQP's solve with the early Farkas check (class doc): (raw status, certified margin or
        None, iterations spent in an abandoned first attempt)."""
        solver = self._solver
        first = self._certify_after
        full = solver.settings.max_iter
        if first is None or first >= full:
            raw = solver.solve()
            return raw, self._certified(raw), 0
        solver.settings.max_iter = first
        try:
            raw = solver.solve()
        finally:
            solver.settings.max_iter = full
        if getattr(raw, "name", "") != "PIQP_MAX_ITER_REACHED":
            return raw, None, 0
        margin = self._certified(raw)
        if margin is not None:
            return raw, margin, 0
        spent = int(solver.result.info.iter)
        raw = solver.solve()
        return raw, self._certified(raw), spent

    def _certified(self, raw) -> float | None:
        """Farkas margin of PIQP's current duals when it ran out of iterations and they prove
        infeasibility by more than ``certify_margin``; else None."""
        if self._certify_after is None or getattr(raw, "name", "") != "PIQP_MAX_ITER_REACHED":
            return None
        d, res = self._data, self._solver.result
        margin = farkas_margin(d["A"] if self.p else None, d["b"] if self.p else None,
                               d["G"] if self.m else None, d["h_l"] if self.m else None,
                               d["h_u"] if self.m else None, d["x_lb"], d["x_ub"],
                               np.array(res.y), np.array(res.z_l), np.array(res.z_u))
        return margin if margin > self._certify_margin else None

    def solve(self) -> SolverResult:
        """Solve the current problem and return a :class:`SolverResult`."""
        blocked = self._blocked("crossed_bounds")
        if blocked is not None:
            return blocked
        if self._solver is None:
            return failed_result(self.name, "piqp solver was not set up")
        rebuilt, self._rebuilt = self._rebuilt, False
        try:
            t0 = time.perf_counter()
            raw, margin, spent = self._solve_certified()
            wall = time.perf_counter() - t0
            res = self._solver.result
            info = res.info
            x = np.array(res.x, dtype=float)
            objective = float(info.primal_obj)
            if self._free is not None:  # put the dropped (fixed) variables back
                x_full = self._data["x_lb"].copy()
                x_full[self._free] = x
                x = x_full
                if self._shifted:  # a fixed variable is nonzero: PIQP's objective lacks the fixed terms
                    d = self._data
                    objective = float(d["c"] @ x + 0.5 * x @ _util.symmetric_upper_product(d["P"], x))
            iterations = spent + int(info.iter)
            dual = {"y": np.array(res.y), "z_l": np.array(res.z_l), "z_u": np.array(res.z_u)}
        except Exception as exc:
            return failed_result(self.name, error_message(exc), rebuilt=rebuilt)
        extra = {"primal_res": float(info.primal_res), "dual_res": float(info.dual_res)}
        if margin is not None:
            return self._result(SolveStatus.INFEASIBLE, None, math.nan, iterations, wall,
                                {"raw_status": "farkas_certificate", "rebuilt": rebuilt, "dual": dual,
                                 "infeasibility_margin": margin, **extra})
        raw_name = raw.name if hasattr(raw, "name") else str(raw)
        return self._result(STATUS_MAP.get(raw_name, SolveStatus.NUMERICAL_ERROR), x, objective, iterations, wall,
                            {"raw_status": raw_name, "rebuilt": rebuilt, "dual": dual, **extra})
