"""SimResult: the time series and events of one closed-loop run, saved as Parquet.

On-disk layout of ``result.save(dir)``::

    dir/steps.parquet   one row per sample: t, x_true_<i>, x_est_<i>, u_cmd_<i>, u_applied_<i>,
                        dv_cum, status, solve_time_s, mode, info_<key>, plant_mode (when any is set)
    dir/events.parquet  t, kind, message
    dir/meta.json       scenario name, seed, stop_reason, state layout (blocks, names, units),
                        position/velocity slices, summary extras
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from proxops.core.layout import StateLayout
from proxops.solvers.stats import solve_time_stats
from proxops.status import Status


@dataclass
class SimResult:
    t: np.ndarray  # (n,) s
    x_true: np.ndarray  # (n, n_x) true relative state
    x_est: np.ndarray  # (n, n_x) navigation estimate
    u_cmd: np.ndarray  # (n, n_u) commanded control (m/s^2 or m/s)
    u_applied: np.ndarray  # (n, n_u) after the actuator model
    dv_cum: np.ndarray  # (n,) cumulative delta-v, m/s
    status: list[Status]  # (n,) controller/solver status (plain str values after load; they compare equal)
    solve_time_s: np.ndarray  # (n,)
    mode: list[str]  # (n,)
    info: dict[str, np.ndarray] = field(default_factory=dict)
    events: list[tuple[float, str, str]] = field(default_factory=list)
    meta: dict = field(default_factory=dict)
    plant_mode: list[str] = field(default_factory=list)  # (n,) the plant's discrete mode ("" = none)

    # --- state layout -------------------------------------------------------------
    @property
    def layout(self) -> StateLayout:
        """The plant's state layout stored with the result (results saved before layouts
        existed: position/velocity from the stored slices)."""
        d = self.meta.get("layout")
        if d is not None:
            return d if isinstance(d, StateLayout) else StateLayout.from_dict(d)
        return StateLayout.from_slices(self.x_true.shape[1], tuple(self.meta.get("position_slice", (0, 3))),
                                       tuple(self.meta.get("velocity_slice", (3, 6))))

    def block(self, name: str, estimate: bool = False) -> np.ndarray:
        """Columns of the named layout block (true state, or the estimate)."""
        b = self.layout.block(name)
        return (self.x_est if estimate else self.x_true)[:, b.start:b.stop]

    def _kind(self, kind: str) -> np.ndarray:
        span = self.layout.span(kind)
        if span is None:
            raise KeyError(f"the state layout has no {kind} block")
        return self.x_true[:, span[0]:span[1]]

    # --- derived quantities -------------------------------------------------------
    @property
    def position(self) -> np.ndarray:
        """(n, 2 or 3) first position block, m."""
        return self._kind("position")

    @property
    def velocity(self) -> np.ndarray:
        """(n, 2 or 3) first velocity block, m/s."""
        return self._kind("velocity")

    @property
    def attitude(self) -> np.ndarray:
        """(n, 4) first quaternion block (scalar-last), or (n, 1) planar angle (rad)."""
        span = self.layout.span("quaternion") or self.layout.span("angle")
        if span is None:
            raise KeyError("the state layout has no attitude (quaternion or angle) block")
        return self.x_true[:, span[0]:span[1]]

    @property
    def range_m(self) -> np.ndarray:
        return np.linalg.norm(self.position, axis=1)

    def events_of(self, kind: str) -> list[tuple[float, str, str]]:
        return [e for e in self.events if e[1] == kind]

    def summary(self) -> dict:
        """The standard run summary (``proxops run --json`` keys)."""
        solved = self.solve_time_s[self.solve_time_s > 0]
        rng_m = self.range_m
        counts: dict[str, int] = {}
        for _, kind, _ in self.events:
            counts[kind] = counts.get(kind, 0) + 1
        return {
            "status": self.meta.get("outcome", "completed"),
            "final_range_m": float(rng_m[-1]),
            "final_speed_mps": float(np.linalg.norm(self.velocity[-1])),
            "total_dv_mps": float(self.dv_cum[-1]),
            "min_range_m": float(rng_m.min()),
            "sim_time_s": float(self.t[-1] - self.t[0]),
            "wall_time_s": float(self.meta.get("wall_time_s", 0.0)),
            "steps": int(len(self.t) - 1),
            "solver_failures": int(sum(Status.parse(s).flagged for s in self.status)),
            "solve_time_ms": solve_time_stats(solved),
            "events": counts,
            **(self.navigation_summary() if self.meta.get("navigation_filter") else {}),
        }

    def navigation_summary(self) -> dict:
        """Estimation error of a filtered run: |r_est - r_true| (m) and |v_est - v_true| (m/s) over
        every recorded sample (median, p95, max), the measurements the filter rejected and its
        re-initialisations after a collapse."""
        (p0, p1), (v0, v1) = self.meta.get("position_slice", (0, 3)), self.meta.get("velocity_slice", (3, 6))
        err = self.x_est - self.x_true
        out = {}
        for key, e in (("nav_position_error_m", err[:, p0:p1]), ("nav_velocity_error_mps", err[:, v0:v1])):
            n = np.linalg.norm(e, axis=1)
            out[key] = {"median": float(np.median(n)), "p95": float(np.percentile(n, 95)), "max": float(n.max())}
        out["nav_rejected"] = len(self.events_of("nav-rejected"))
        out["nav_reinits"] = len(self.events_of("nav-reinit"))
        out.update(self.consistency_summary())
        return out

    def consistency_summary(self) -> dict:
        """NEES and NIS of a filtered run (:mod:`proxops.navigation.consistency`): ``nav_nees_mean``, its
        per-epoch band ``nav_nees_band`` (95 % of chi^2(d)), the band of the run's mean ``nav_nees_mean_band``,
        the fractions of epochs inside / above / below (``nav_nees_in_band``, ...), the epochs and the
        dimension; the same for ``nav_nis_*``; ``nav_consistent`` (NEES mean inside its band and <= 10 % of
        the epochs outside theirs); the innovation-whiteness statistic of the run and the number of
        windows flagged overconfident. Empty without a recorded NEES (``info["nav_nees"]``)."""
        from proxops.navigation.consistency import consistency_stats

        if "nav_nees" not in self.info:
            return {}
        out = {}
        for name, dim in (("nees", self.meta.get("nav_nees_dim", 6)), ("nis", self.meta.get("nav_nis_dim", 3))):
            for key, val in consistency_stats(self.info.get(f"nav_{name}", []), int(dim)).items():
                if key != "consistent":
                    out[f"nav_{name}_{key}"] = val
                elif name == "nees":
                    out["nav_consistent"] = val
        out["nav_whiteness_z"] = float(self.meta.get("nav_whiteness_z", float("nan")))
        out["nav_whiteness_bound"] = float(self.meta.get("nav_whiteness_bound", float("nan")))
        out["nav_overconfident_windows"] = int(self.meta.get("nav_overconfident_windows", 0))
        return out

    # --- persistence --------------------------------------------------------------
    def to_frame(self) -> "pd.DataFrame":
        import pandas as pd  # heavy (0.4 s + pyarrow on save): only when a result is stored

        cols: dict[str, np.ndarray | list] = {"t": self.t}
        for name, arr in (("x_true", self.x_true), ("x_est", self.x_est), ("u_cmd", self.u_cmd), ("u_applied", self.u_applied)):
            for i in range(arr.shape[1]):
                cols[f"{name}_{i}"] = arr[:, i]
        cols["dv_cum"] = self.dv_cum
        cols["status"] = [str(s) for s in self.status]
        cols["solve_time_s"] = self.solve_time_s
        cols["mode"] = list(self.mode)
        for key, arr in self.info.items():
            cols[f"info_{key}"] = arr
        if any(self.plant_mode):
            cols["plant_mode"] = list(self.plant_mode)
        return pd.DataFrame(cols)

    def save(self, directory: str | Path) -> Path:
        import pandas as pd

        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        self.to_frame().to_parquet(d / "steps.parquet", index=False)
        ev = pd.DataFrame(self.events, columns=["t", "kind", "message"]) if self.events else pd.DataFrame(
            {"t": pd.Series(dtype=float), "kind": pd.Series(dtype=str), "message": pd.Series(dtype=str)}
        )
        ev.to_parquet(d / "events.parquet", index=False)
        (d / "meta.json").write_text(json.dumps(self.meta, indent=2, default=_jsonable))
        return d

    @classmethod
    def load(cls, directory: str | Path) -> "SimResult":
        import pandas as pd

        d = Path(directory)
        df = pd.read_parquet(d / "steps.parquet")
        ev = pd.read_parquet(d / "events.parquet")
        meta = json.loads((d / "meta.json").read_text())

        def block(prefix: str) -> np.ndarray:
            names = sorted((c for c in df.columns if c.startswith(prefix + "_") and c[len(prefix) + 1 :].isdigit()),
                           key=lambda c: int(c.rsplit("_", 1)[1]))
            return df[names].to_numpy()

        info = {c[5:]: df[c].to_numpy() for c in df.columns if c.startswith("info_")}
        return cls(
            t=df["t"].to_numpy(),
            x_true=block("x_true"),
            x_est=block("x_est"),
            u_cmd=block("u_cmd"),
            u_applied=block("u_applied"),
            dv_cum=df["dv_cum"].to_numpy(),
            status=df["status"].tolist(),
            solve_time_s=df["solve_time_s"].to_numpy(),
            mode=df["mode"].tolist(),
            info=info,
            events=[(float(r.t), str(r.kind), str(r.message)) for r in ev.itertuples()],
            meta=meta,
            plant_mode=df["plant_mode"].tolist() if "plant_mode" in df.columns else [""] * len(df),
        )


def _jsonable(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, StateLayout):
        return obj.to_dict()
    return str(obj)
