"""CasADi NLP adapter: IPOPT or fatrop through ``casadi.nlpsol`` with the shared result.

Problem (CasADi's ``nlpsol`` form)::

    minimize    f(x, p)
    subject to  lbg <= g(x, p) <= ubg
                lbx <= x <= ubx

``setup(problem)`` builds the solver once (``expand``: SX evaluation) and evaluates it on
preallocated buffers (``Function.buffer``); ``update(p=, lbx=, ubx=, lbg=, ubg=)`` writes
new data in place, ``warm_start(x=, lam_g=, lam_x=)`` the initial guess (primal and, for
IPOPT, multipliers); values not given keep their last setting. ``solve()`` returns a
:class:`SolverResult` whose status comes from :data:`STATUS_MAP` on CasADi's
``return_status`` (``raw_status``); ``info`` holds ``lam_g``, ``lam_x`` (copies) and
``success``. Solver evaluation errors are a NUMERICAL_ERROR status (``raw_status`` "error").
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from proxops.errors import input_error
from proxops.solvers import _util
from proxops.solvers.result import SolverResult, SolveStatus

NLP_SOLVERS = ("ipopt", "fatrop")

# IPOPT ApplicationReturnStatus names as CasADi reports them (stats()["return_status"]);
# fatrop's own codes are mapped through ``success`` (any unknown failure is NUMERICAL_ERROR).
STATUS_MAP = {
    "Solve_Succeeded": SolveStatus.OPTIMAL,
    "Solved_To_Acceptable_Level": SolveStatus.OPTIMAL_INACCURATE,
    "Feasible_Point_Found": SolveStatus.OPTIMAL_INACCURATE,
    "Infeasible_Problem_Detected": SolveStatus.INFEASIBLE,
    "Diverging_Iterates": SolveStatus.UNBOUNDED,
    "Maximum_Iterations_Exceeded": SolveStatus.MAX_ITER,
    "Maximum_CpuTime_Exceeded": SolveStatus.TIME_LIMIT,
    "Maximum_WallTime_Exceeded": SolveStatus.TIME_LIMIT,
    "Search_Direction_Becomes_Too_Small": SolveStatus.NUMERICAL_ERROR,
    "User_Requested_Stop": SolveStatus.NUMERICAL_ERROR,
    "Restoration_Failed": SolveStatus.NUMERICAL_ERROR,
    "Error_In_Step_Computation": SolveStatus.NUMERICAL_ERROR,
    "Not_Enough_Degrees_Of_Freedom": SolveStatus.NUMERICAL_ERROR,
    "Invalid_Problem_Definition": SolveStatus.NUMERICAL_ERROR,
    "Invalid_Option": SolveStatus.NUMERICAL_ERROR,
    "Invalid_Number_Detected": SolveStatus.NUMERICAL_ERROR,
    "Unrecoverable_Exception": SolveStatus.NUMERICAL_ERROR,
    "NonIpopt_Exception_Thrown": SolveStatus.NUMERICAL_ERROR,
    "Insufficient_Memory": SolveStatus.NUMERICAL_ERROR,
    "Internal_Error": SolveStatus.NUMERICAL_ERROR,
}


def status_of(stats: dict) -> SolveStatus:
    """Shared status of one nlpsol call from its ``stats()`` (``success`` first, then the table)."""
    raw = str(stats.get("return_status", ""))
    if stats.get("success", False):
        return SolveStatus.OPTIMAL_INACCURATE if STATUS_MAP.get(raw) is SolveStatus.OPTIMAL_INACCURATE \
            else SolveStatus.OPTIMAL
    status = STATUS_MAP.get(raw, SolveStatus.NUMERICAL_ERROR)
    return SolveStatus.NUMERICAL_ERROR if status.ok else status


@dataclass
class NonlinearProgram:
    """``min f(x, p) s.t. lbg <= g(x, p) <= ubg, lbx <= x <= ubx`` with CasADi expressions.

    x, f, g, p: CasADi SX/MX (p may be None); bounds: arrays (+-inf allowed), None = free;
    equality: per row of g, True for equality rows (fatrop's structure detection needs it).
    """

    x: object
    f: object
    g: object
    p: object = None
    lbx: np.ndarray | None = None
    ubx: np.ndarray | None = None
    lbg: np.ndarray | None = None
    ubg: np.ndarray | None = None
    equality: list | None = None


class Buffered:
    """A CasADi Function evaluated on preallocated numpy arrays (``Function.buffer``).

    ``__call__`` copies the given inputs (by position or by name; unset inputs keep their
    last value) into the buffers, evaluates, and returns the output arrays by name. The
    outputs are overwritten by the next call: copy what must be kept."""

    def __init__(self, fn):
        self.fn = fn
        self.buffer, self._evaluate = fn.buffer()
        self.names_in = fn.name_in()
        self.inputs = {name: np.zeros(fn.nnz_in(i)) for i, name in enumerate(self.names_in)}
        self.outputs = {name: np.zeros(fn.nnz_out(i)) for i, name in enumerate(fn.name_out())}
        for i, name in enumerate(self.names_in):
            self.buffer.set_arg(i, memoryview(self.inputs[name]))
        for i, name in enumerate(fn.name_out()):
            self.buffer.set_res(i, memoryview(self.outputs[name]))

    def __call__(self, *args, **kwargs) -> dict:
        for name, value in zip(self.names_in, args):
            self.inputs[name][:] = value
        for name, value in kwargs.items():
            self.inputs[name][:] = value
        self._evaluate()
        if self.buffer.ret() != 0:
            raise RuntimeError(f"evaluation of {self.fn.name()} failed (return code {self.buffer.ret()})")
        return self.outputs

    def stats(self) -> dict:
        return self.buffer.stats()


class CasadiNLP:
    """Persistent CasADi NLP solver (``solver`` "ipopt" or "fatrop").

    ``options``: the plugin's own options (e.g. IPOPT ``max_iter``, ``tol``, warm-start
    settings); ``nlpsol_options``: CasADi nlpsol options (``expand`` and ``print_time`` are
    set; fatrop gets ``structure_detection="auto"`` and the problem's ``equality``);
    ``label`` names the CasADi function.
    """

    def __init__(self, solver: str = "ipopt", *, options: dict | None = None,
                 nlpsol_options: dict | None = None, label: str = "nlp"):
        if solver not in NLP_SOLVERS:
            raise input_error("solver", solver, f"allowed: {', '.join(NLP_SOLVERS)}")
        self.name = solver
        self._ca = _util.import_solver("casadi", "casadi")
        self.options = dict(options or {})
        self.nlpsol_options = dict(nlpsol_options or {})
        self.label = label
        self._fn: Buffered | None = None

    # ------------------------------------------------------------------ set-up
    def setup(self, problem: NonlinearProgram) -> None:
        """Build the nlpsol for ``problem`` and set its bounds."""
        if not isinstance(problem, NonlinearProgram):
            raise input_error("CasadiNLP.setup", type(problem).__name__, "pass a NonlinearProgram")
        nlp = {"x": problem.x, "f": problem.f, "g": problem.g}
        if problem.p is not None:
            nlp["p"] = problem.p
        opts = {}
        if self.name == "fatrop":
            opts = {"structure_detection": "auto", "equality": list(problem.equality or [])}
        opts.update(self.nlpsol_options)
        opts.update({"expand": True, "print_time": False, self.name: self.options})
        self._fn = Buffered(self._ca.nlpsol(self.label, self.name, nlp, opts))
        self.n = self._fn.inputs["x0"].size
        self.m = self._fn.inputs["lbg"].size
        self.update(lbx=problem.lbx if problem.lbx is not None else -np.inf,
                    ubx=problem.ubx if problem.ubx is not None else np.inf,
                    lbg=problem.lbg if problem.lbg is not None else -np.inf,
                    ubg=problem.ubg if problem.ubg is not None else np.inf)

    @property
    def inputs(self) -> dict:
        """The solver's input buffers by name (x0, p, lbx, ubx, lbg, ubg, lam_x0, lam_g0)."""
        return self._fn.inputs

    def update(self, *, p=None, lbx=None, ubx=None, lbg=None, ubg=None) -> None:
        """Write parameters and bounds into the input buffers (values kept until changed)."""
        if self._fn is None:
            raise input_error("CasadiNLP.update", "called before setup", "call setup() first")
        for key, value in (("p", p), ("lbx", lbx), ("ubx", ubx), ("lbg", lbg), ("ubg", ubg)):
            if value is not None:
                self._fn.inputs[key][:] = value

    def warm_start(self, x=None, lam_g=None, lam_x=None) -> bool:
        """Initial guess of the next solve: primal ``x`` and multipliers (used by IPOPT with
        ``warm_start_init_point``; fatrop takes the primal guess). Returns True."""
        if self._fn is None:
            raise input_error("CasadiNLP.warm_start", "called before setup", "call setup() first")
        for key, value in (("x0", x), ("lam_g0", lam_g), ("lam_x0", lam_x)):
            if value is not None:
                self._fn.inputs[key][:] = value
        return True

    # ------------------------------------------------------------------ solve
    def solve(self) -> SolverResult:
        """Run the solver from the current buffers and return a :class:`SolverResult`."""
        if self._fn is None:
            raise input_error("CasadiNLP.solve", "called before setup", "call setup() first")
        t0 = time.perf_counter()
        try:
            out = self._fn()
        except RuntimeError as exc:  # evaluation errors -> a status, never a crash
            return SolverResult(SolveStatus.NUMERICAL_ERROR, None, math.nan, 0, time.perf_counter() - t0,
                                self.name, {"raw_status": "error", "error": str(exc), "success": False})
        wall = time.perf_counter() - t0
        stats = self._fn.stats()
        status = status_of(stats)
        return SolverResult(
            status=status,
            x=out["x"].copy(),
            objective=float(out["f"][0]) if out["f"].size else math.nan,
            iterations=int(stats.get("iter_count", 0) or 0),
            solve_time_s=wall,
            solver=self.name,
            info={"raw_status": str(stats.get("return_status", "failed")), "success": bool(stats.get("success", False)),
                  "lam_g": out["lam_g"].copy(), "lam_x": out["lam_x"].copy()},
        )
