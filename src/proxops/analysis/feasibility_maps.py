"""Monte Carlo feasibility maps of the tumbling-target approach (Iskender 2026 §9-10.5).

1. Initial conditions (§9.1): 15 values of y_B in [20, 300] m times 13 values of x_B in
   [-0.95 tan(30 deg) y_B, +0.95 tan(30 deg) y_B], z_B = 0, zero body-frame velocity.
2. Closed loop (§9.2): the ``los`` system (J2 truth, quaternion target, body-frame MPC in
   its Monte Carlo configuration, 400 s), one run per (w_t, a_max, IC), run as a campaign
   (:func:`proxops.analysis.campaign.run_campaign`: local process pool or Dask, Parquet
   rows written as runs finish, ``resume`` completes an interrupted campaign).
3. Classification (§9.3): feasible = no corridor violation above 1e-3 m, the QP never
   infeasible, no early termination. A run that raised is not feasible and is counted
   separately (``n_error``).
4. Interpolation (§9.4) onto the analytical grid: natural-neighbour (Sibson) inside the
   convex hull of the ICs, nearest neighbour outside. scipy has no natural-neighbour
   interpolant; :func:`natural_neighbour` computes exact Sibson coordinates from the
   Delaunay triangulation (scipy.spatial.Delaunay) with the Bowyer-Watson cavity of each
   query, compiled with numba. The binary map is the interpolant >= 0.5.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numba
import numpy as np
import pandas as pd
from scipy.spatial import Delaunay, cKDTree

from proxops.analysis.reach import (PAPER_A_MAX_MPS2, PAPER_OMEGAS_DEG_S, BodyGrid, analyse_combo, certified_mask,
                                   viable_points)
from proxops.constraints.los_corridor import LosCorridor
from proxops.core.memo import memo_get
from proxops.errors import input_error
from proxops.systems.los import default_scenario, is_feasible_run
from proxops.analysis.campaign import run_campaign, load_campaign

MC_Y_RANGE_M = (20.0, 300.0)
MC_N_Y = 15
MC_N_X = 13
MC_FILL = 0.95  # x_B spans +-0.95 tan(alpha_c) y_B
MC_DURATION_S = 400.0
VIOLATION_TOLERANCE_M = 1e-3  # §9.3 (the rule itself: proxops.systems.los.is_feasible_run)
POSITION_KEY = "chaser.initial_body_position_m"
OMEGA_KEY = "target.tumble_rate_deg_s"
A_MAX_KEY = "chaser.a_max_mps2"


def mc_initial_positions(
    half_angle_rad: float = math.radians(30.0),
    y_range_m: tuple[float, float] = MC_Y_RANGE_M,
    n_y: int = MC_N_Y,
    n_x: int = MC_N_X,
    fill: float = MC_FILL,
) -> np.ndarray:
    """§9.1 structured IC grid, (n_y * n_x, 3) body-frame positions (m), y slow, x fast."""
    if n_y < 1 or n_x < 1 or int(n_y) != n_y or int(n_x) != n_x:
        raise input_error("mc grid", (n_y, n_x), "n_y and n_x must be whole numbers >= 1")
    if not (0.0 < fill <= 1.0):
        raise input_error("mc fill", fill, "must be in (0, 1]")
    ys = np.linspace(y_range_m[0], y_range_m[1], int(n_y))
    out = []
    for y in ys:
        half = fill * math.tan(half_angle_rad) * y
        for x in np.linspace(-half, half, int(n_x)):
            out.append((x, y, 0.0))
    return np.array(out)


# --------------------------------------------------------------------------------------
# campaign
# --------------------------------------------------------------------------------------
def mc_scenario(
    omegas_deg_s=PAPER_OMEGAS_DEG_S,
    a_max_mps2=PAPER_A_MAX_MPS2,
    positions: np.ndarray | None = None,
    duration_s: float = MC_DURATION_S,
    truth: str = "j2",
    seed: int = 0,
) -> dict:
    """Scenario data of the §9 campaign: the ``los`` system in its Monte Carlo configuration
    with the grid (w_t x a_max x IC) declared as dispersion grid axes (last axis fastest)."""

    positions = mc_initial_positions() if positions is None else np.asarray(positions, float)
    sc = default_scenario(
        sim={"duration_s": float(duration_s), "dt_s": 1.0, "seed": int(seed)},
        truth={"model": truth},
        chaser={"initial_velocity_frame": "body", "initial_velocity_mps": [0.0, 0.0, 0.0]},
        mpc={"config": "monte-carlo", "constraint_mode": "hard"},
    )
    data = sc.model_dump(mode="json", exclude_none=True)
    data["name"] = "reach-mc"
    data["description"] = "Iskender 2026 §9 feasibility sweep"
    data["dispersions"] = {
        OMEGA_KEY: {"grid": [float(w) for w in omegas_deg_s]},
        A_MAX_KEY: {"grid": [float(a) for a in a_max_mps2]},
        POSITION_KEY: {"grid": [[float(c) for c in p] for p in positions]},
    }
    return data


def run_mc(
    out: str | Path | None,
    omegas_deg_s=PAPER_OMEGAS_DEG_S,
    a_max_mps2=PAPER_A_MAX_MPS2,
    positions: np.ndarray | None = None,
    duration_s: float = MC_DURATION_S,
    workers: int | None = None,
    scheduler=None,
    resume: bool = False,
    progress: bool = True,
    truth: str = "j2",
) -> "McRun":
    """Run (or with ``resume`` complete) the §9 campaign. See :func:`outcome_table` for the table."""

    data = mc_scenario(omegas_deg_s, a_max_mps2, positions, duration_s, truth)
    res = run_campaign(data, workers=workers, scheduler=scheduler, out=out, resume=resume, progress=progress)
    return McRun(outcome_table(res.table), float(res.wall_time_s), int(res.new_runs))


class McRun(NamedTuple):
    """table: one row per run (all runs in the folder); wall_time_s and new_runs: this call only."""

    table: pd.DataFrame
    wall_time_s: float
    new_runs: int


def classify_rows(table: pd.DataFrame) -> np.ndarray:
    """§9.3 rule on campaign rows: :func:`proxops.systems.los.is_feasible_run` (the rule of
    ``LosSystem.success``) on the ``metric.*`` columns; a run that raised is infeasible."""

    def col(name, default):
        return table[name] if name in table else pd.Series(default, index=table.index)

    viol = pd.to_numeric(col("metric.los_violations", np.nan), errors="coerce").to_numpy()
    vmax = pd.to_numeric(col("metric.max_violation_m", np.nan), errors="coerce").to_numpy()
    qp_bad = col("metric.qp_infeasible", True).to_numpy()
    outcome = col("metric.outcome", "").fillna("").astype(str).to_numpy()
    ran = col("outcome", "error").astype(str).to_numpy() != "error"
    rule = np.array([is_feasible_run(*row) for row in zip(viol, vmax, qp_bad, outcome)], dtype=bool)
    return ran & rule


def outcome_table(table: pd.DataFrame) -> pd.DataFrame:
    """Campaign rows -> columns omega_deg_s, a_max_mps2, x_m, y_m, z_m, feasible, outcome,
    los_violations, max_violation_m, error, run_wall_s (one row per run)."""
    out = pd.DataFrame(
        {
            "run_id": table["run_id"].to_numpy(),
            "omega_deg_s": table["disp." + OMEGA_KEY].astype(float).to_numpy(),
            "a_max_mps2": table["disp." + A_MAX_KEY].astype(float).to_numpy(),
            "x_m": table[f"disp.{POSITION_KEY}[0]"].astype(float).to_numpy(),
            "y_m": table[f"disp.{POSITION_KEY}[1]"].astype(float).to_numpy(),
            "z_m": table[f"disp.{POSITION_KEY}[2]"].astype(float).to_numpy(),
            "feasible": classify_rows(table),
            "outcome": table.get("metric.outcome", pd.Series("", index=table.index)).fillna("").astype(str).to_numpy(),
            "error": table["outcome"].astype(str).to_numpy() == "error",
        }
    )
    for src, dst in (("metric.los_violations", "los_violations"), ("metric.max_violation_m", "max_violation_m"),
                     ("metric.sim_time_s", "sim_time_s"), ("run_wall_s", "run_wall_s")):
        out[dst] = pd.to_numeric(table[src], errors="coerce").to_numpy() if src in table else np.nan
    return out.sort_values("run_id").reset_index(drop=True)


# --------------------------------------------------------------------------------------
# natural-neighbour interpolation onto the analytical grid
# --------------------------------------------------------------------------------------
@numba.njit(cache=True)
def _circumcentre(ax, ay, bx, by, cx, cy):  # pragma: no cover - compiled
    bx -= ax
    by -= ay
    cx -= ax
    cy -= ay
    d = 2.0 * (bx * cy - by * cx)
    b2 = bx * bx + by * by
    c2 = cx * cx + cy * cy
    return ax + (cy * b2 - by * c2) / d, ay + (bx * c2 - cx * b2) / d


@numba.njit(cache=True)
def _sibson_coordinates(pts, simplices, neighbors, cc, r2, queries, start):  # pragma: no cover - compiled
    """Sibson coordinates of queries inside the hull (start = containing simplex, >= 0), as the area
    each natural neighbour loses (unnormalised): for query iq, sites ``site[ptr[iq]:ptr[iq + 1]]`` with
    areas ``area[...]`` in the order they are summed; ``hit[iq]`` >= 0 when q is on that data site,
    ``first[iq]`` the first vertex of the containing simplex (the value when all areas vanish).
    They do not depend on the values: :func:`_sibson_apply` interpolates any values with them."""
    n_q = queries.shape[0]
    hit_out = np.full(n_q, -1, np.int64)
    first = np.empty(n_q, np.int64)
    ptr = np.zeros(n_q + 1, np.int64)
    cap = 8 * n_q + 16
    site = np.empty(cap, np.int64)
    area_out = np.empty(cap)
    nnz = 0
    stamp = np.zeros(simplices.shape[0], np.int64)
    stack = np.empty(simplices.shape[0], np.int64)
    conf = np.empty(simplices.shape[0], np.int64)
    max_e = 3 * simplices.shape[0]
    ea = np.empty(max_e, np.int64)
    eb = np.empty(max_e, np.int64)
    ex = np.empty(max_e)
    ey = np.empty(max_e)
    px = np.empty(max_e + 2)
    py = np.empty(max_e + 2)
    ang = np.empty(max_e + 2)
    for iq in range(n_q):
        qx, qy = queries[iq, 0], queries[iq, 1]
        # q on a data site: its value
        t0 = start[iq]
        first[iq] = simplices[t0, 0]
        hit = -1
        for k in range(3):
            v = simplices[t0, k]
            if (pts[v, 0] - qx) ** 2 + (pts[v, 1] - qy) ** 2 <= 1e-18 * (1.0 + qx * qx + qy * qy):
                hit = v
        if hit >= 0:
            hit_out[iq] = hit
            ptr[iq + 1] = nnz
            continue
        # Bowyer-Watson cavity: triangles whose circumcircle contains q
        tag = iq + 1
        n_conf = 0
        top = 0
        stack[top] = t0
        top += 1
        stamp[t0] = tag
        while top > 0:
            top -= 1
            t = stack[top]
            conf[n_conf] = t
            n_conf += 1
            for k in range(3):
                nb = neighbors[t, k]
                if nb >= 0 and stamp[nb] != tag:
                    if (qx - cc[nb, 0]) ** 2 + (qy - cc[nb, 1]) ** 2 < r2[nb]:
                        stamp[nb] = tag
                        stack[top] = nb
                        top += 1
        # cavity boundary edges and the new circumcentres (vertices of q's new Voronoi cell)
        n_e = 0
        for i in range(n_conf):
            t = conf[i]
            for k in range(3):
                nb = neighbors[t, k]
                if nb < 0 or stamp[nb] != tag:
                    a = simplices[t, (k + 1) % 3]
                    b = simplices[t, (k + 2) % 3]
                    ea[n_e] = a
                    eb[n_e] = b
                    ex[n_e], ey[n_e] = _circumcentre(qx, qy, pts[a, 0], pts[a, 1], pts[b, 0], pts[b, 1])
                    n_e += 1
        if nnz + n_e > cap:  # grow the entry arrays
            cap = 2 * (nnz + n_e)
            site_new = np.empty(cap, np.int64)
            area_new = np.empty(cap)
            site_new[:nnz] = site[:nnz]
            area_new[:nnz] = area_out[:nnz]
            site, area_out = site_new, area_new
        # stolen area per natural neighbour v = area of the convex polygon V_q ∩ V_v, whose vertices
        # are the old circumcentres of the conflicting triangles around v and the two new ones on edges at v
        for i in range(n_e):
            v = ea[i]
            m = 0
            for j in range(n_conf):
                t = conf[j]
                if simplices[t, 0] == v or simplices[t, 1] == v or simplices[t, 2] == v:
                    px[m] = cc[t, 0]
                    py[m] = cc[t, 1]
                    m += 1
            for j in range(n_e):
                if ea[j] == v or eb[j] == v:
                    px[m] = ex[j]
                    py[m] = ey[j]
                    m += 1
            mx = 0.0
            my = 0.0
            for j in range(m):
                mx += px[j]
                my += py[j]
            mx /= m
            my /= m
            for j in range(m):
                ang[j] = math.atan2(py[j] - my, px[j] - mx)
            order = np.argsort(ang[:m])
            area = 0.0
            for j in range(m):
                a_i = order[j]
                b_i = order[(j + 1) % m]
                area += px[a_i] * py[b_i] - px[b_i] * py[a_i]
            site[nnz] = v
            area_out[nnz] = 0.5 * abs(area)
            nnz += 1
        ptr[iq + 1] = nnz
    return hit_out, first, ptr, site[:nnz].copy(), area_out[:nnz].copy()


@numba.njit(cache=True)
def _sibson_apply(vals, hit, first, ptr, site, area):  # pragma: no cover - compiled
    """Sibson interpolation of ``vals`` (per site) with the coordinates of :func:`_sibson_coordinates`:
    sum(area_v vals_v) / sum(area_v), summed in the coordinates' order."""
    n_q = hit.shape[0]
    out = np.empty(n_q)
    for iq in range(n_q):
        if hit[iq] >= 0:
            out[iq] = vals[hit[iq]]
            continue
        num = 0.0
        den = 0.0
        for e in range(ptr[iq], ptr[iq + 1]):
            num += area[e] * vals[site[e]]
            den += area[e]
        out[iq] = num / den if den > 0.0 else vals[first[iq]]
    return out


_GEOMETRY_CACHE: dict = {}  # (sites, queries) -> nearest site per query, inside mask, Sibson coordinates


def _interpolation_geometry(sites: np.ndarray, q: np.ndarray):
    """What :func:`natural_neighbour` needs that does not depend on the values: the nearest site of
    every query, the queries inside the hull of the sites and their Sibson coordinates (None when
    there is no 2-D hull or no query inside it). Memoised: the §9 maps interpolate 20 combinations
    on the same IC sites and grid (read-only arrays, shared)."""

    def make():
        _, idx = cKDTree(sites).query(q)
        if sites.shape[0] < 3:
            return idx, None, None
        try:
            tri = Delaunay(sites)
        except Exception:  # collinear sites: no 2-D hull, nearest neighbour everywhere
            return idx, None, None
        start = tri.find_simplex(q)
        inside = start >= 0
        if not inside.any():
            return idx, None, None
        simp = tri.simplices.astype(np.int64)
        P = tri.points
        a, b, c = P[simp[:, 0]], P[simp[:, 1]], P[simp[:, 2]]
        cc = np.empty((len(simp), 2))
        for i in range(len(simp)):
            cc[i] = _circumcentre(a[i, 0], a[i, 1], b[i, 0], b[i, 1], c[i, 0], c[i, 1])
        r2 = np.sum((cc - a) ** 2, axis=1)
        coords = _sibson_coordinates(np.ascontiguousarray(P), simp, tri.neighbors.astype(np.int64), cc, r2,
                                     np.ascontiguousarray(q[inside]), start[inside].astype(np.int64))
        return idx, inside, coords

    key = (sites.shape, sites.tobytes(), q.shape, q.tobytes())
    return memo_get(_GEOMETRY_CACHE, key, make, read_only=True, max_entries=4)


def natural_neighbour(sites: np.ndarray, values: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """Sibson natural-neighbour interpolation at ``queries`` (q, 2); nearest neighbour outside the hull.

    Exact Sibson coordinates (Sibson 1980): the area each site's Voronoi cell loses when the
    query is inserted, from the Bowyer-Watson cavity of the Delaunay triangulation (as in
    Liang & Hale 2010 / MetPy), compiled with numba. The coordinates depend on the sites and
    queries only; they are computed once per (sites, queries) in this process."""
    sites = np.ascontiguousarray(np.asarray(sites, float)[:, :2])
    values = np.asarray(values, float)
    q = np.ascontiguousarray(np.atleast_2d(np.asarray(queries, float))[:, :2])
    if sites.shape[0] != values.shape[0] or sites.shape[0] < 1:
        raise input_error("sites", sites.shape, f"need one value per site (got {values.shape[0]} values)")
    idx, inside, coords = _interpolation_geometry(sites, q)
    out = values[idx].astype(float)
    if inside is not None:
        out[inside] = _sibson_apply(np.ascontiguousarray(values), *coords)
    return out


def inside_hull(sites: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """(q,) True where a query (x, y) lies in the convex hull of the sites (``Delaunay.find_simplex``
    >= 0), where :func:`natural_neighbour` interpolates; all False without a 2-D hull."""
    sites = np.ascontiguousarray(np.asarray(sites, float)[:, :2])
    q = np.ascontiguousarray(np.atleast_2d(np.asarray(queries, float))[:, :2])
    _, inside, _ = _interpolation_geometry(sites, q)
    return np.zeros(len(q), bool) if inside is None else inside.copy()


def natural_neighbour_grid(sites: np.ndarray, values: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """:func:`natural_neighbour` on the grid x (nx,) by y (ny,) -> (ny, nx) (§9.4)."""
    X, Y = np.meshgrid(np.asarray(x, float), np.asarray(y, float))
    return natural_neighbour(sites, values, np.column_stack([X.ravel(), Y.ravel()])).reshape(X.shape)


# --------------------------------------------------------------------------------------
# maps and comparison with the certified regions
# --------------------------------------------------------------------------------------
@dataclass
class FeasibilityMap:
    """MC map of one combination on the analytical grid. value (n,) in [0, 1], mask = value >= 0.5."""

    omega_deg_s: float
    a_max_mps2: float
    value: np.ndarray
    mask: np.ndarray
    sites: np.ndarray
    feasible: np.ndarray

    @property
    def pct_ics_feasible(self) -> float:
        return 100.0 * float(np.mean(self.feasible)) if self.feasible.size else float("nan")


def feasibility_map(outcomes: pd.DataFrame, grid: BodyGrid, omega_deg_s: float, a_max_mps2: float) -> FeasibilityMap:
    """Interpolate one combination's outcomes (rows of :func:`outcome_table`) onto the grid."""
    sel = outcomes[np.isclose(outcomes["omega_deg_s"], omega_deg_s) & np.isclose(outcomes["a_max_mps2"], a_max_mps2)]
    if sel.empty:
        raise input_error("combination", (omega_deg_s, a_max_mps2), "no Monte Carlo runs for it")
    sites = sel[["x_m", "y_m"]].to_numpy()
    feas = sel["feasible"].to_numpy(bool)
    value = natural_neighbour_grid(sites, feas.astype(float), grid.x_m, grid.y_m).ravel()
    return FeasibilityMap(float(omega_deg_s), float(a_max_mps2), value, value >= 0.5, sites, feas)


def certification_check(fmap: FeasibilityMap, grid: BodyGrid, nominal: np.ndarray, sites_nominal: np.ndarray) -> dict:
    """How often Monte Carlo contradicts the nominal certificate (it should be ~never).

    ``nominal`` (n,) grid mask; ``sites_nominal`` (m,) nominal certificate evaluated at the
    ICs themselves. Returns counts and fractions on the grid (interpolated map) and at the ICs."""
    cert = nominal & grid.inside
    n_cert = int(cert.sum())
    bad_grid = int(np.count_nonzero(cert & ~fmap.mask))
    in_hull = inside_hull(fmap.sites, grid.points)  # there the map is interpolated, outside it is extrapolated
    n_cert_hull = int(np.count_nonzero(cert & in_hull))
    bad_hull = int(np.count_nonzero(cert & in_hull & ~fmap.mask))
    n_sites_cert = int(np.count_nonzero(sites_nominal))
    bad_sites = int(np.count_nonzero(sites_nominal & ~fmap.feasible))
    return {
        **_contradictions("nominal_grid_points", n_cert, bad_grid, "frac_nominal_grid_mc_infeasible"),
        **_contradictions("nominal_grid_points_in_ic_hull", n_cert_hull, bad_hull,
                          "frac_nominal_grid_in_ic_hull_mc_infeasible"),
        **_contradictions("nominal_ics", n_sites_cert, bad_sites, "frac_nominal_ics_mc_infeasible"),
        "mc_pct_grid": grid.percent(fmap.mask),
        "mc_pct_ics": fmap.pct_ics_feasible,
    }


def _contradictions(key: str, certified: int, infeasible: int, frac_key: str) -> dict:
    """``{key: certified, key_mc_infeasible: infeasible, frac_key: infeasible / certified (0 if none)}``."""
    return {key: certified, f"{key}_mc_infeasible": infeasible,
            frac_key: infeasible / certified if certified else 0.0}


def certify_combination(fmap: FeasibilityMap, grid: BodyGrid, res) -> dict:
    """:func:`certification_check` of one combination's map against its nominal certificate ``res``
    (:class:`proxops.analysis.reach.ComboResult`), the certificate evaluated at the ICs too."""
    sites = np.column_stack([fmap.sites, np.zeros(len(fmap.sites))])
    sites_nom = certified_mask(LosCorridor(), sites, np.radians(res.omega_deg_s), res.a_max_mps2)
    return certification_check(fmap, grid, res.nominal, sites_nom)


def viability_split(fmap: FeasibilityMap, omega_deg_s: float, a_max_mps2: float, duration_s: float) -> dict:
    """Split certified-but-failed ICs into 'no controller could' and 'the MPC failed' (the N = duration
    LP of :func:`proxops.analysis.reach.viable_points`, one step per second)."""
    sites = np.column_stack([fmap.sites, np.zeros(len(fmap.sites))])
    cert = certified_mask(LosCorridor(), sites, np.radians(omega_deg_s), a_max_mps2)
    viable = viable_points(sites, np.radians(omega_deg_s), a_max_mps2, n_back=int(round(duration_s)))
    bad = cert & ~fmap.feasible
    return {"certified_failed_ics_not_viable": int(np.count_nonzero(bad & ~viable)),
            "certified_failed_ics_viable": int(np.count_nonzero(bad & viable)),
            "mc_feasible_ics_not_viable": int(np.count_nonzero(fmap.feasible & ~viable)),
            "viable_ics": int(viable.sum())}


@dataclass
class SweepSummary:
    """The §9 sweep aggregated: one row per (w_t, a_max) (:func:`certify_combination`, plus
    :func:`viability_split` when asked), the maps and nominal results by combination, and the
    totals over the combinations (counts and fractions, keys as in the rows)."""

    rows: list[dict]
    maps: dict
    results: dict
    totals: dict


def aggregate_sweep(outcomes: pd.DataFrame, grid: BodyGrid, omegas, amaxs, viability: bool = False,
                    duration_s: float = 400.0) -> SweepSummary:
    """Map every combination's Monte Carlo outcomes on ``grid``, compare them with its nominal
    certificate and sum the contradictions over the sweep (``viability``: also split the certified
    ICs that failed by the ``duration_s`` viability LP)."""
    fields: dict = {}  # the grid's ratio fields and per-rate tightenings, shared by the combinations
    rows, maps, results = [], {}, {}
    for w in omegas:
        for a in amaxs:
            res = analyse_combo(grid, w, a, backward=False, cache=fields)
            fmap = feasibility_map(outcomes, grid, w, a)
            maps[(w, a)], results[(w, a)] = fmap, res
            row = {"omega_deg_s": w, "a_max_mps2": a, "nominal_pct": res.pct["nominal"],
                   **certify_combination(fmap, grid, res)}
            if viability:
                row.update(viability_split(fmap, w, a, duration_s))
            rows.append(row)

    def total(key: str) -> int:
        return sum(r[key] for r in rows)

    totals = {}
    for key, frac_key in (("nominal_grid_points", "frac_nominal_grid_mc_infeasible"),
                          ("nominal_grid_points_in_ic_hull", "frac_nominal_grid_in_ic_hull_mc_infeasible"),
                          ("nominal_ics", "frac_nominal_ics_mc_infeasible")):
        totals.update(_contradictions(key, total(key), total(f"{key}_mc_infeasible"), frac_key))
    if viability:
        for key in ("certified_failed_ics_not_viable", "certified_failed_ics_viable", "mc_feasible_ics_not_viable"):
            totals[key] = total(key)
    return SweepSummary(rows, maps, results, totals)


def read_outcomes(out: str | Path) -> pd.DataFrame:
    """Outcome table of a finished (or partial) campaign folder."""

    return outcome_table(load_campaign(out).table)


