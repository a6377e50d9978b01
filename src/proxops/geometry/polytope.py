"""Convex 2-D sections of polyhedra by support-function LPs (shared by reach, cortex and hybrid).

:class:`ConvexSection` is the projection P = {p in R^2 : exists u, A [p; u] <= b, lb <= [p; u] <= ub}
onto its first two variables: inner (support points) and outer (supporting half-planes) polygons
from warm-started support LPs (DAQP, HiGHS as fallback, by default; any LP solver by name), and exact
point membership (HiGHS).
Units are the caller's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from proxops.errors import ProxopsError
from proxops.solvers import LinearProgram, SolveStatus, make_solver


@dataclass
class SectionPolygon:
    """Result of :meth:`ConvexSection.polygon`.

    vertices (k, 2): support points (feasible, so conv(vertices) is an inner bound);
    directions (k, 2) unit vectors and support (k,) values: the outer bound
    {p : directions @ p <= support}; empty when the section is empty; n_lp: LPs solved."""

    vertices: np.ndarray
    directions: np.ndarray
    support: np.ndarray
    n_lp: int
    empty: bool = False

    def ordered_vertices(self) -> np.ndarray:
        """Vertices of conv(support points) counter-clockwise (for plotting); may be < 3."""
        if self.empty:
            return np.zeros((0, 2))
        pts = np.unique(np.round(self.vertices, 9), axis=0)
        if len(pts) < 3:
            return pts
        try:
            hull = ConvexHull(pts)
        except QhullError:
            return pts
        return pts[hull.vertices]


class ConvexSection:
    """The convex set P = {p in R^2 : exists u, A [p; u] <= b, lb <= [p; u] <= ub} (p = first 2 variables).

    ``polygon`` computes support points in many directions; ``contains`` classifies query points
    exactly (inner hull / outer half-planes / one feasibility LP per point in between).

    Support LPs differ only in their cost. Small ones (at most ``SUPPORT_DAQP_MAX_VARIABLES``
    variables) run on :class:`proxops.solvers.DaqpQP` in its LP mode (H = 0, proximal-point
    iterations with ``eps_prox`` > 0), warm-started from the previous direction's working set:
    ~0.02 ms per LP against HiGHS's ~0.15-0.3 ms fixed cost per ``run()`` even hot-started
    (benchmarks/bench_closed_loop.py). Larger ones, and any direction DAQP does not
    settle as optimal (infeasible included), are solved by the hot-started HiGHS model
    (``n_highs`` counts those; ``n_lp`` counts every support and feasibility LP). Point
    feasibility LPs (bounds change per point) run on HiGHS too."""

    # small LPs re-solved from the last basis: presolve only adds overhead (0.07 ms per solve)
    HOT_SETTINGS = {"presolve": "off", "solver": "simplex"}
    # DAQP's proximal weight for LPs (H = 0): any value > 0 converges to an LP optimum; on the reach
    # section (1 deg/s, 0.1 m/s^2; 48 directions) the support values agree with HiGHS to 1e-10 for
    # 1e-4..1 (3.7-4.8 DAQP iterations per LP)
    SUPPORT_EPS_PROX = 1e-2
    # dense active set: a 20-step reach section (42 variables, 63 rows) takes ~4 iterations per
    # direction, but a 400-step one (802 x 802) up to 3 300 iterations and 4.6 s per direction
    # (HiGHS: < 1 s), so larger LPs stay on HiGHS
    SUPPORT_DAQP_MAX_VARIABLES = 200

    def __init__(self, A: np.ndarray, b: np.ndarray, lb: np.ndarray, ub: np.ndarray,
                 support_solver: str | None = "daqp", lp_solver: str = "highs"):
        """``support_solver``: LP solver of the support LPs up to ``SUPPORT_DAQP_MAX_VARIABLES``
        variables (None: all on ``lp_solver``); ``lp_solver``: LP solver of the larger support LPs,
        the retries and the point-feasibility LPs. Any LP name of :func:`proxops.solvers.make_solver`
        ("highs", "daqp", "piqp", "clarabel")."""
        self.A = np.asarray(A, float)
        self.b = np.asarray(b, float)
        self.lb = np.asarray(lb, float)
        self.ub = np.asarray(ub, float)
        self.n_var = self.A.shape[1]
        self.lp_solver = lp_solver
        self._current = (np.zeros(self.n_var), self.lb.copy(), self.ub.copy())
        self.lp = self._lp_solver(*self._current, hot=True)
        self.n_lp = 0
        self.n_retry = 0  # cold re-solves after numerical trouble
        self.n_highs = 0  # support LPs the support solver left to lp_solver (counted in n_lp)
        self.support_lp = None
        if support_solver is not None and self.n_var <= self.SUPPORT_DAQP_MAX_VARIABLES:
            settings = {"settings": {"eps_prox": self.SUPPORT_EPS_PROX}} if support_solver == "daqp" else {}
            self.support_lp = make_solver(self._form(*self._current), support_solver, **settings)
            self._support_cost = self.support_lp.native_name("c")  # the lean update_fast path of that solver
        self._poly: SectionPolygon | None = None

    def _form(self, c, lb, ub) -> LinearProgram:
        return LinearProgram(c=c, A=self.A, ru=self.b, lb=lb, ub=ub)

    def _lp_solver(self, c, lb, ub, hot: bool):
        """An ``lp_solver`` adapter set up with cost c and bounds lb, ub (HiGHS: ``HOT_SETTINGS`` when
        ``hot``, its defaults otherwise)."""
        settings = {"settings": self.HOT_SETTINGS} if hot and self.lp_solver == "highs" else {}
        return make_solver(self._form(c, lb, ub), self.lp_solver, **settings)

    def set_box(self, lo: np.ndarray, hi: np.ndarray) -> None:
        """Change the bounds of p (the first 2 variables)."""
        self.lb[:2], self.ub[:2] = lo, hi
        self._set(lb=self.lb.copy(), ub=self.ub.copy())
        if self.support_lp is not None:
            self.support_lp.update(lb=self.lb, ub=self.ub)
        self._poly = None

    def support_point(self, direction: np.ndarray) -> tuple[SolveStatus, np.ndarray | None]:
        """(status, argmax d.p over P); the point is None unless the status is OPTIMAL."""
        c = np.zeros(self.n_var)
        c[:2] = -np.asarray(direction, float)
        if self.support_lp is not None:
            self.support_lp.update_fast(**{self._support_cost: c})  # a fresh array: DAQP keeps a pointer to f
            res = self.support_lp.solve()
            if res.status is SolveStatus.OPTIMAL:
                self.n_lp += 1
                return res.status, res.x[:2].copy()
        self.n_highs += 1
        self._set(c=c)
        res = self._solve()
        if res.status is not SolveStatus.OPTIMAL:
            return res.status, None
        return res.status, res.x[:2].copy()

    def _solve(self):
        """Solve the current LP; on numerical trouble (neither optimal nor infeasible) rebuild the
        solver cold (HiGHS: with presolve) and solve again (HiGHS hot starts can stall on long horizons)."""
        res = self.lp.solve()
        self.n_lp += 1
        if res.status in (SolveStatus.OPTIMAL, SolveStatus.INFEASIBLE):
            return res
        res = self._lp_solver(*self._current, hot=False).solve()
        self.n_lp += 1
        self.n_retry += 1
        self.lp = self._lp_solver(*self._current, hot=True)
        return res

    def _set(self, c=None, lb=None, ub=None) -> None:
        """Change the LP's cost and/or variable bounds (kept for cold re-solves)."""
        c0, lb0, ub0 = self._current
        self._current = (c0 if c is None else c, lb0 if lb is None else lb, ub0 if ub is None else ub)
        self.lp.update(**{k: v for k, v in (("c", c), ("lb", lb), ("ub", ub)) if v is not None})

    def polygon(self, n_directions: int = 48, refine_tol: float = 0.05, max_rounds: int = 6) -> SectionPolygon:
        """Support points in n_directions evenly spread directions, then bisect the angular gaps whose
        outer corner lies more than ``refine_tol`` (units of p) outside the inner edge."""
        angles = list(np.linspace(0.0, 2 * np.pi, int(n_directions), endpoint=False))
        pts: dict[float, np.ndarray] = {}
        self.n_failed = 0
        for ang in angles:
            status, p = self.support_point([math.cos(ang), math.sin(ang)])
            if status is SolveStatus.INFEASIBLE:
                self._poly = SectionPolygon(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), self.n_lp, empty=True)
                return self._poly
            if p is None:
                self.n_failed += 1  # numerical failure twice: leave the direction out (bounds stay valid)
                continue
            pts[ang] = p
        if not pts:
            raise ProxopsError("every support LP failed numerically; the section could not be computed")
        for _ in range(max_rounds):
            keys = sorted(pts)
            new = []
            for i, a0 in enumerate(keys):
                a1 = keys[(i + 1) % len(keys)]
                gap = (a1 - a0) % (2 * np.pi)
                if gap < 1e-4:
                    continue
                # plain floats: the same arithmetic as 2-vectors, without numpy's per-call overhead
                c0, s0, c1, s1 = math.cos(a0), math.sin(a0), math.cos(a1), math.sin(a1)
                (p0x, p0y), (p1x, p1y) = pts[a0].tolist(), pts[a1].tolist()
                h0, h1 = c0 * p0x + s0 * p0y, c1 * p1x + s1 * p1y
                # corner of the two supporting lines; how far it sticks out beyond the chord p0-p1
                det = c0 * s1 - s0 * c1
                if abs(det) < 1e-12:
                    continue
                cx, cy = (h0 * s1 - h1 * s0) / det, (c0 * h1 - c1 * h0) / det
                mid = a0 + 0.5 * gap
                cm, sm = math.cos(mid), math.sin(mid)
                if cm * cx + sm * cy - max(cm * p0x + sm * p0y, cm * p1x + sm * p1y) > refine_tol:
                    new.append(mid % (2 * np.pi))
            if not new:
                break
            for ang in new:
                _, p = self.support_point([math.cos(ang), math.sin(ang)])
                if p is not None:
                    pts[ang] = p
        keys = sorted(pts)
        dirs = np.array([[np.cos(a), np.sin(a)] for a in keys])
        verts = np.array([pts[a] for a in keys])
        self._poly = SectionPolygon(verts, dirs, np.einsum("ij,ij->i", dirs, verts), self.n_lp)
        return self._poly

    def _point_feasible(self, p: np.ndarray) -> bool:
        """One feasibility LP with p fixed (bounds are restored by :meth:`contains`)."""
        lb, ub = self.lb.copy(), self.ub.copy()
        lb[:2] = ub[:2] = p
        self._set(lb=lb, ub=ub)
        return self._solve().status is SolveStatus.OPTIMAL

    def contains(self, points: np.ndarray, tol: float = 1e-9) -> tuple[np.ndarray, int]:
        """Exact membership of points (m, 2) in P; returns (mask, number of per-point LPs).

        Points in the closed hull of the support points are feasible (convex combinations of
        feasible points); points beyond a supporting half-plane are not; the rest get an LP."""
        q = np.asarray(points, float)
        poly = self._poly or self.polygon()
        if poly.empty:
            return np.zeros(len(q), bool), 0
        inner_hp, outer_hp = self._halfplanes(tol)
        outside = np.any(q @ outer_hp[:, :2].T > outer_hp[:, 2], axis=1)
        inner = np.zeros(len(q), bool) if inner_hp is None else np.all(q @ inner_hp[:, :2].T <= inner_hp[:, 2], axis=1)
        return self._settle(q, inner & ~outside, ~outside & ~inner)

    def contains_grid(self, x: np.ndarray, y: np.ndarray, tol: float = 1e-9) -> tuple[np.ndarray, int]:
        """:meth:`contains` for the rectangular grid x (nx,) by y (ny,), row-major (y slow) -> ((ny*nx,), n_lp).

        Convexity makes each grid row an x-interval, so only O(ny * edges) work is done."""
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        poly = self._poly or self.polygon()
        if poly.empty:
            return np.zeros(x.size * y.size, bool), 0
        inner_hp, outer_hp = self._halfplanes(tol)
        X = np.broadcast_to(x, (y.size, x.size))
        lo_o, hi_o = row_intervals(outer_hp, y)
        outside = (X < lo_o[:, None]) | (X > hi_o[:, None])
        if inner_hp is None:
            inner = np.zeros_like(outside)
        else:
            lo_i, hi_i = row_intervals(inner_hp, y)
            inner = (X >= lo_i[:, None]) & (X <= hi_i[:, None])
        Yg = np.broadcast_to(y[:, None], X.shape)
        q = np.column_stack([X.ravel(), Yg.ravel()])
        return self._settle(q, (inner & ~outside).ravel(), (~outside & ~inner).ravel())

    def _halfplanes(self, tol: float) -> tuple[np.ndarray | None, np.ndarray]:
        """([a_x, a_y, b] rows) of the inner hull (None if degenerate) and of the outer bound, tol added to b."""
        poly = self._poly
        scale = 1.0 + np.abs(poly.vertices).max()
        outer = np.column_stack([poly.directions, poly.support + tol * scale])
        try:
            eq = ConvexHull(np.unique(np.round(poly.vertices, 9), axis=0)).equations
            inner = np.column_stack([eq[:, :2], -eq[:, 2] + tol * scale])
        except (QhullError, ValueError):
            inner = None  # degenerate (segment or point): everything undecided goes to the LP
        return inner, outer

    def _settle(self, q: np.ndarray, mask: np.ndarray, undecided: np.ndarray) -> tuple[np.ndarray, int]:
        idx = np.flatnonzero(undecided)
        mask = mask.copy()
        if idx.size:
            self._set(c=np.zeros(self.n_var))
            for i in idx:
                mask[i] = self._point_feasible(q[i, :2])
            self._set(lb=self.lb, ub=self.ub)
        return mask, int(idx.size)


def row_intervals(halfplanes: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x-interval [lo, hi] per y of {p : a_x x + a_y y <= b for all rows} (empty: lo > hi)."""
    ax, ay, b = halfplanes[:, 0], halfplanes[:, 1], halfplanes[:, 2]
    rhs = b[None, :] - ay[None, :] * y[:, None]  # (ny, m): a_x x <= rhs
    lo = np.full(y.size, -np.inf)
    hi = np.full(y.size, np.inf)
    pos, neg, zero = ax > 1e-12, ax < -1e-12, np.abs(ax) <= 1e-12
    if pos.any():
        hi = np.min(rhs[:, pos] / ax[pos], axis=1)
    if neg.any():
        lo = np.max(rhs[:, neg] / ax[neg], axis=1)
    if zero.any():
        bad = np.any(rhs[:, zero] < 0.0, axis=1)
        lo = np.where(bad, np.inf, lo)
        hi = np.where(bad, -np.inf, hi)
    return lo, hi
