"""A second SOCP solver: a :class:`ConicProblem` solved as a smooth NLP by IPOPT (CasADi).

Clarabel is the one conic solver shipped; this adapter exists so a SOCP consumer can be run on a
second, independent engine by name (``make_solver(form, "ipopt")``: cross-checks, not speed). Each
cone row block of ``A x + s = b`` becomes constraints on ``s = b - A x``: zero rows ``s = 0``,
nonneg rows ``s >= 0``, a second-order cone ``s_0 >= ||s_1..k||`` the smooth pair ``s_0 >= 0``,
``s_0^2 - ||s_1..k||^2 >= 0`` (the same set). Where the optimum sits at a cone's apex (e.g. a zero
impulse) the constraint gradients vanish and IPOPT converges slowly (hundreds of iterations) but to
the same optimum within its tolerances (``tol``, ``constr_viol_tol``: 1e-9 here). The values of A
(in the set-up sparsity pattern), b and q are NLP parameters, so ``update`` changes them in place;
P or a new pattern of A set the NLP up again (``info["rebuilt"]``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from proxops.errors import input_error
from proxops.solvers import _util
from proxops.solvers.base import SolverAdapter
from proxops.solvers.casadi_nlp import CasadiNLP, NonlinearProgram
from proxops.solvers.forms import ConicProblem
from proxops.solvers.result import SolverResult

DEFAULT_OPTIONS = {"print_level": 0, "sb": "yes", "tol": 1e-9, "constr_viol_tol": 1e-9, "max_iter": 3000,
                   "mu_strategy": "adaptive"}  # monotone mu: "infeasible" on the degenerate CP_g with plume rows (N = 5)


class IpoptSOCP(SolverAdapter):
    """Persistent IPOPT solver for ``min 1/2 x'Px + q'x s.t. A x + s = b, s in K`` (zero, nonneg, soc
    cones; module doc). ``options``: IPOPT options over :data:`DEFAULT_OPTIONS`."""

    name = "ipopt"
    forms = (ConicProblem,)

    def __init__(self, *, options: dict | None = None):
        self._ca = _util.import_solver("casadi", "casadi")
        self._options = {**DEFAULT_OPTIONS, **(options or {})}
        self._data: dict | None = None
        self._nlp: CasadiNLP | None = None

    def _setup_form(self, problem: ConicProblem) -> None:
        self.setup_native(problem.P, problem.q, problem.A, problem.b, problem.cones)

    def _native_fields(self) -> dict:
        return {k: k for k in ("P", "q", "A", "b")}

    def setup_native(self, P, q, A, b, cones) -> None:
        """The problem in Clarabel's native form (cones: (kind, dim) with kind zero / nonneg / soc)."""
        self._native_setup_done()
        q = _util.vector("q", q, np.size(q))
        n = q.shape[0]
        m = _util.rows_of("A", A)
        cones = [(str(k), int(d)) for k, d in cones]
        if sum(d for _, d in cones) != m or any(k not in ("zero", "nonneg", "soc") for k, _ in cones):
            raise input_error("cones", cones, f"kinds zero/nonneg/soc with dimensions adding up to the {m} rows of A")
        self.n, self.m, self.cones = n, m, cones
        self._data = {"P": _util.csc_matrix("P", P, (n, n), upper=True), "q": q,
                      "A": _util.csc_matrix("A", A, (m, n)), "b": _util.vector("b", b, m)}
        self._build()

    def _build(self) -> None:
        ca, d = self._ca, self._data
        A = d["A"]
        x = ca.SX.sym("x", self.n)
        a_val = ca.SX.sym("a", A.nnz)
        b = ca.SX.sym("b", self.m)
        q = ca.SX.sym("q", self.n)
        A_sym = ca.SX(ca.Sparsity(self.m, self.n, A.indptr.tolist(), A.indices.tolist()), a_val)
        s = b - ca.mtimes(A_sym, x)
        Pu = d["P"]
        P_full = (Pu + sp.triu(Pu, 1).T).tocsc()
        f = ca.dot(q, x)
        if P_full.nnz:
            P_dm = ca.DM(ca.Sparsity(self.n, self.n, P_full.indptr.tolist(), P_full.indices.tolist()), P_full.data)
            f = f + 0.5 * ca.dot(x, ca.mtimes(P_dm, x))
        g, lbg, ubg, row = [], [], [], 0
        for kind, dim in self.cones:
            blk = s[row:row + dim]
            if kind == "soc":
                g += [blk[0], blk[0] ** 2 - ca.sumsqr(blk[1:])]
                lbg += [0.0, 0.0]
                ubg += [np.inf, np.inf]
            else:
                g.append(blk)
                lbg += [0.0] * dim
                ubg += [0.0 if kind == "zero" else np.inf] * dim
            row += dim
        self._nlp = CasadiNLP("ipopt", options=self._options, label="ipopt_socp")
        self._nlp.setup(NonlinearProgram(x=x, f=f, g=ca.vertcat(*g), p=ca.vertcat(a_val, b, q),
                                         lbg=np.array(lbg), ubg=np.array(ubg)))
        self._push()
        self._rebuilt = True

    def _push(self) -> None:
        d = self._data
        self._nlp.update(p=np.concatenate([d["A"].data, d["b"], d["q"]]))

    def update_native(self, *, P=None, q=None, A=None, b=None) -> None:
        """Change data in place (same sizes and cones); P or a new sparsity pattern of A rebuilds."""
        if self._data is None:
            raise input_error("IpoptSOCP.update", "called before setup", "call setup() first")
        d = self._data
        rebuild = False
        if P is not None:
            d["P"] = _util.csc_matrix("P", P, (self.n, self.n), upper=True)
            rebuild = True
        if A is not None:
            new = _util.csc_matrix("A", A, (self.m, self.n))
            rebuild |= not _util.same_pattern(new, d["A"])
            d["A"] = new
        if q is not None:
            d["q"] = _util.vector("q", q, self.n)
        if b is not None:
            d["b"] = _util.vector("b", b, self.m)
        if rebuild:
            self._build()
        else:
            self._push()

    def update_fast(self, *, b=None, A_values=None, **others) -> None:
        """As :meth:`proxops.solvers.ClarabelSOCP.update_fast`: ``b`` and the values of A in the set-up
        pattern (canonical CSC order), trusted; other native fields go to :meth:`update_native`."""
        if others:
            self.update_native(**others)
        d = self._data
        if b is not None:
            d["b"] = np.array(b, dtype=float)
        if A_values is not None:
            d["A"].data[:] = A_values
        self._push()

    def warm_start(self, x=None, y=None) -> bool:
        """A primal starting point for IPOPT (it moves it into the interior first). True."""
        if self._nlp is None:
            raise input_error("IpoptSOCP.warm_start", "called before setup", "call setup() first")
        return self._nlp.warm_start(x=None if x is None else _util.vector("x", x, self.n))

    def solve(self) -> SolverResult:
        if self._nlp is None:
            raise input_error("IpoptSOCP.solve", "called before setup", "call setup() first")
        res = self._nlp.solve()
        rebuilt, self._rebuilt = self._rebuilt, False
        return self._result(res.status, res.x, res.objective, res.iterations, res.solve_time_s,
                            {**res.info, "rebuilt": rebuilt})
