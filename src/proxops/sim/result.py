"""SimResult: the time series and events of one closed-loop run, saved as Parquet.

On-disk layout of ``result.save(dir)``::

    dir/steps.parquet   one row per sample, columns named from the plant's layouts with frame and
                        unit (:meth:`SimResult.column_info`): t_s; the true state (x_hill_m, ...,
                        vz_hill_mps); the estimate (est_x_hill_m, ...); the commanded and applied
                        control (cmd_ux_hill_mps, applied_ux_hill_mps, ...); dv_cum_mps, status,
                        solve_time_s, mode, info_<key>, plant_mode (when any is set). Each column's
                        unit, frame and meaning are also in the Parquet schema's field metadata.
    dir/events.parquet  t, kind, message
    dir/meta.json       scenario name, seed, stop_reason, state layout (blocks, names, units),
                        position/velocity slices, summary extras
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from proxops.core.layout import StateLayout, make_control_layout
from proxops.jsonable import json_default
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
        # Kept local: the navigation package's __init__ imports numba (core.quaternion); a campaign's
        # parent and report load results without it
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
    @property
    def control_layout(self) -> StateLayout:
        """Names, units and frame of ``u_cmd`` / ``u_applied`` (see :func:`control_layout_of`)."""
        return control_layout_of(self.meta, self.u_cmd.shape[1])

    def column_info(self) -> dict[str, dict[str, str]]:
        """``{column: {"unit", "frame", "meaning"}}`` of the time-series table (``to_frame``)."""
        return column_info(self.layout, self.control_layout)

    def to_frame(self) -> "pd.DataFrame":
        """The time series as a pandas DataFrame with self-explaining columns (:meth:`column_info`)."""
        import pandas as pd  # heavy (0.4 s + pyarrow on save): only when a result is stored

        cols: dict[str, np.ndarray | list] = {"t_s": self.t}
        names = iter(self.column_info())
        next(names)  # t_s
        for arr in (self.x_true, self.x_est, self.u_cmd, self.u_applied):
            for i in range(arr.shape[1]):
                cols[next(names)] = arr[:, i]
        cols["dv_cum_mps"] = self.dv_cum
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

        import pyarrow as pa
        import pyarrow.parquet as pq

        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        table = pa.Table.from_pandas(self.to_frame(), preserve_index=False)
        info = self.column_info()
        fields = [f.with_metadata({k: v for k, v in info[f.name].items() if v}) if f.name in info else f
                  for f in table.schema]
        pq.write_table(table.cast(pa.schema(fields, metadata=table.schema.metadata)), d / "steps.parquet")
        ev = pd.DataFrame(self.events, columns=["t", "kind", "message"]) if self.events else pd.DataFrame(
            {"t": pd.Series(dtype=float), "kind": pd.Series(dtype=str), "message": pd.Series(dtype=str)}
        )
        ev.to_parquet(d / "events.parquet", index=False)
        meta = dict(self.meta)  # the layouts the column names came from, also for results built by hand
        meta.setdefault("layout", self.layout.to_dict())
        meta.setdefault("control_layout", self.control_layout.to_dict())
        (d / "meta.json").write_text(json.dumps(meta, indent=2, default=_jsonable))
        return d

    @classmethod
    def load(cls, directory: str | Path) -> "SimResult":
        import pandas as pd

        d = Path(directory)
        df = pd.read_parquet(d / "steps.parquet")
        ev = pd.read_parquet(d / "events.parquet")
        meta = json.loads((d / "meta.json").read_text())

        if "t_s" in df.columns:  # named columns, in the order column_info gives them
            layout = StateLayout.from_dict(meta["layout"])
            control = control_layout_of(meta, len(meta["control_layout"]["blocks"]))
            cols = list(column_info(layout, control))
            n_x, n_u = layout.n_x, control.n_x
            parts = np.split(np.array(cols[1:1 + 2 * n_x + 2 * n_u]), np.cumsum([n_x, n_x, n_u]))
            x_true, x_est, u_cmd, u_applied = (df[list(p)].to_numpy() for p in parts)
            t, dv_cum = df["t_s"].to_numpy(), df["dv_cum_mps"].to_numpy()
        else:  # results saved before the columns had names: x_true_<i>, ...
            def block(prefix: str) -> np.ndarray:
                names = sorted((c for c in df.columns if c.startswith(prefix + "_") and c[len(prefix) + 1:].isdigit()),
                               key=lambda c: int(c.rsplit("_", 1)[1]))
                return df[names].to_numpy()

            x_true, x_est, u_cmd, u_applied = (block(p) for p in ("x_true", "x_est", "u_cmd", "u_applied"))
            t, dv_cum = df["t"].to_numpy(), df["dv_cum"].to_numpy()
        info = {c[5:]: df[c].to_numpy() for c in df.columns if c.startswith("info_")}
        return cls(
            t=t,
            x_true=x_true,
            x_est=x_est,
            u_cmd=u_cmd,
            u_applied=u_applied,
            dv_cum=dv_cum,
            status=df["status"].tolist(),
            solve_time_s=df["solve_time_s"].to_numpy(),
            mode=df["mode"].tolist(),
            info=info,
            events=[(float(r.t), str(r.kind), str(r.message)) for r in ev.itertuples()],
            meta=meta,
            plant_mode=df["plant_mode"].tolist() if "plant_mode" in df.columns else [""] * len(df),
        )


def control_layout_of(meta: dict, n_u: int) -> StateLayout:
    """The control layout stored with a run (``meta["control_layout"]``), its ``"kind"`` units
    resolved from the run's command kind (m/s for impulses, m/s^2 for accelerations); ``u0, u1,
    ...`` without units for runs recorded before control layouts existed."""
    d = meta.get("control_layout")
    if d is None:
        return make_control_layout(tuple(f"u{i}" for i in range(n_u)), ("-",) * n_u)
    layout = d if isinstance(d, StateLayout) else StateLayout.from_dict(d)
    unit = {"impulse": "m/s", "acceleration": "m/s^2"}.get(meta.get("control_kind", "acceleration"), "-")
    return StateLayout(layout.n_x, tuple(replace(b, unit=unit if b.unit == "kind" else b.unit) for b in layout.blocks))


def column_info(layout: StateLayout, control: StateLayout) -> dict[str, dict[str, str]]:
    """``{column: {"unit", "frame", "meaning"}}`` of a run's time-series table, in column order."""
    out = {"t_s": {"unit": "s", "frame": "", "meaning": "time since the scenario start"}}
    for prefix, lay, what in (("", layout, "true state"), ("est_", layout, "navigation estimate"),
                              ("cmd_", control, "commanded control"),
                              ("applied_", control, "control after the actuator model")):
        for col, name, unit, frame in zip(_unique(lay.column_names(prefix)), lay.names, lay.units, lay.frames):
            out[col] = {"unit": unit, "frame": frame, "meaning": f"{what}: {name}"}
    out["dv_cum_mps"] = {"unit": "m/s", "frame": "", "meaning": "cumulative delta-v"}
    out["status"] = {"unit": "", "frame": "", "meaning": "controller/solver status of the sample"}
    out["solve_time_s"] = {"unit": "s", "frame": "", "meaning": "solver time of the sample's decision"}
    out["mode"] = {"unit": "", "frame": "", "meaning": "controller mode / guidance regime"}
    return out


def _unique(names: list[str]) -> list[str]:
    """Names made unique by appending the component index where two would collide."""
    seen = {n: names.count(n) for n in names}
    return [n if seen[n] == 1 else f"{n}_{i}" for i, n in enumerate(names)]


def _jsonable(obj):
    """meta.json: a state layout as its dict, the rest as everywhere (:func:`proxops.jsonable.json_default`)."""
    return obj.to_dict() if isinstance(obj, StateLayout) else json_default(obj)
