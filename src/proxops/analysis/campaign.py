"""Monte Carlo campaigns: dispersed closed-loop runs on a local process pool or Dask.

A campaign is a scenario (its ``[dispersions]`` table, see :mod:`proxops.scenarios.dispersions`),
a campaign seed and a number of runs. Run ``i`` gets its own seeds from the numpy
SeedSequence spawn tree of the campaign seed: child ``(i, 0)`` seeds the simulation (navigation
noise, thrust errors, missed thrusts), child ``(i, 1)`` draws the dispersed values. Its row
holds ``run_id, seed, grid_index``, the dispersed values (``disp.<key>``), the outcome and
the run summary flattened (``metric.<key>``), so :func:`rerun` repeats it alone, bit for bit.

On disk (``out``)::

    campaign.json            manifest: scenario name, content hash (file + overrides),
                             campaign seed, n_runs, the scenario data itself (for rerun)
    runs/part-*.parquet      rows, one file per finished batch (atomic rename), read back
                             consolidated (deduplicated on run_id, sorted)
    series/run_XXXXXX/       optional per-run time series (SimResult.save)

Execution: ``workers=1`` runs in this process; ``workers>1`` uses a spawn-safe
ProcessPoolExecutor; ``scheduler="tcp://HOST:PORT"``, a scheduler-file path or a
``distributed.Client`` uses Dask. Runs are sent in batches sized on the fly (about
``target_batch_s`` of work each) to keep per-run overhead low. Before anything is written the
scenario gets every check a run makes, once: on a local pool each worker runs it as its warm-up
(imports, numba kernels, per-process caches), so this process never builds the system; ``proxops
mc`` spawns the pool before importing this module, so the workers' start-up overlaps its imports. A run that raises is a row with
``outcome = "error"``; a killed pool worker is replaced and its runs retried.

Ctrl-C (or SIGTERM) at any moment: the first one only raises a flag (:class:`_GracefulStop`);
the driver stops submitting, lets the batches in flight finish, saves them and raises
:class:`CampaignInterrupted`. A second Ctrl-C stops waiting (runs still in flight are not
saved; finished ones are). Pool workers are born with SIGINT blocked and ignore it from their
first instruction, so a Ctrl-C during their imports cannot kill them.

Columns whose values depend on the machine (``metric.wall_time_s``, ``metric.solve_time_ms.*``,
``run_wall_s``, ``run_cpu_s``) are excluded by :meth:`CampaignResult.deterministic_table`.
"""

from __future__ import annotations

import copy
import json
import math
import os
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import pandas as pd

from proxops.scenarios.dispersions import DispersionPlan, apply_values, parse_dispersions
from proxops.scenarios.catalog import read_toml, resolve
from proxops.scenarios.loader import LoadedScenario, validate_scenario
from proxops.sim.result import SimResult
from proxops.scenarios.loader import check_scenario
from proxops.analysis.metric_order import ordered_metrics
from proxops.analysis.statistics import (
    METRIC_PREFIX,
    DISP_PREFIX,
    metric_statistics,
    navigation_consistency,
    outcome_counts,
    statistics_dict,
)
from proxops.errors import ProxopsInputError
from proxops.scenarios.registry import system_module


MAX_RUNS = 10_000_000  # rows of one campaign; items are made lazily, the table of results is what grows


from proxops.exec.backends import (  # noqa: E402,F401 (public names re-exported from here)
    CampaignError,
    CampaignInterrupted,
    RunError,
    _bar,
    _drive,
    _GracefulStop,
    _make_backend,
    _Progress,
    _sigint_blocked,
    default_workers,
    map_runs,
    shutdown_pools,
)


# =========================================================================== campaign
# What a worker runs lives in proxops.analysis.campaign_worker (no pandas: a spawned worker
# unpickles campaign_run from there and starts 0.4 s sooner); re-exported here.
from proxops.analysis.campaign_worker import (  # noqa: E402,F401
    _PREPARED,
    _SKIP_SUMMARY,
    CampaignSpec,
    RunItem,
    _prepared,
    campaign_run,
    check_nominal,
    classify,
    flatten_summary,
)
from proxops.exec.backends import _PoolBackend
from proxops import __version__


def run_seeds(campaign_seed: int, run_id: int) -> tuple[int, np.random.Generator]:
    """Simulation seed (child ``(run_id, 0)``) and dispersion generator (child ``(run_id, 1)``)
    of run ``run_id``: the SeedSequence spawn tree of ``campaign_seed``."""
    sim_ss = np.random.SeedSequence(campaign_seed, spawn_key=(run_id, 0))
    seed = int(sim_ss.generate_state(1, np.uint64)[0] >> np.uint64(1))  # 63 bits: fits Parquet int64
    disp_rng = np.random.default_rng(np.random.SeedSequence(campaign_seed, spawn_key=(run_id, 1)))
    return seed, disp_rng


_TIMING_MARKS = ("wall_time", "solve_time", "solve_ms", "compute_time", "compute_ms", "cpu_time", "elapsed")


def is_timing_column(col: str) -> bool:
    """Columns that depend on the machine and load, not on the run's inputs (wall and CPU
    times, solver and compute times in any unit, e.g. ``metric.mpc_solve_ms.median``)."""
    return col in ("run_wall_s", "run_cpu_s") or col.startswith(METRIC_PREFIX) and any(m in col for m in _TIMING_MARKS)


# --------------------------------------------------------------------------- loading scenarios
@dataclass
class _Prepared:
    data: dict  # full data after overrides (with dispersions)
    loaded: Any
    plan: DispersionPlan
    source: str
    overrides: list[str]


def _prepare(scenario, overrides: Sequence[str]) -> _Prepared:
    overrides = list(overrides)
    if isinstance(scenario, LoadedScenario):
        if overrides:
            raise ProxopsInputError("overrides: apply them when loading, or pass the scenario name/file/dict instead")
        data = scenario.scenario.model_dump(mode="json", exclude_none=True)
        source = scenario.source
    elif isinstance(scenario, dict):
        data = copy.deepcopy(scenario)
        source = "<dict>"
    else:
        path = resolve(str(scenario))
        data = read_toml(path)
        source = str(path)
    loaded = validate_scenario(data, overrides, source=source)  # applies overrides to data in place
    plan = parse_dispersions(loaded.scenario, loaded.scenario.dispersions)
    return _Prepared(data=data, loaded=loaded, plan=plan, source=source, overrides=overrides)


# --------------------------------------------------------------------------- results
@dataclass
class CampaignResult:
    """Rows of a campaign (one per finished run) and its manifest."""

    table: pd.DataFrame
    manifest: dict
    out: Path | None = None
    wall_time_s: float = math.nan
    new_runs: int = 0

    @property
    def n_runs(self) -> int:
        return int(self.manifest.get("n_runs", len(self.table)))

    @property
    def complete(self) -> bool:
        return len(self.table) >= self.n_runs

    def missing(self) -> list[int]:
        have = set(self.table["run_id"].tolist()) if len(self.table) else set()
        return [i for i in range(self.n_runs) if i not in have]

    def statistics(self, subset: str = "completed", by=None) -> pd.DataFrame:
        return metric_statistics(self.table, subset=subset, by=by)

    def counts(self) -> dict:
        return outcome_counts(self.table)

    def headline_statistics(self, subset: str = "completed") -> pd.DataFrame:
        """:meth:`statistics` of the metrics that inform, in reading order
        (:func:`proxops.analysis.metric_order.ordered_metrics`: Δv, terminal accuracy, safety,
        navigation, the system's own, timings; constants, bookkeeping and repeats left out)."""
        cols = ordered_metrics(self.table) if len(self.table) else []
        return metric_statistics(self.table, metrics=cols, subset=subset)

    def deterministic_table(self) -> pd.DataFrame:
        """The table without machine-dependent timing columns (equal across backends/resumes)."""
        return self.table[[c for c in self.table.columns if not is_timing_column(c)]]

    def summary(self) -> dict:
        """The ``proxops mc --json`` object."""
        counts = self.counts()
        return {
            "scenario": self.manifest.get("scenario"),
            "runs": counts["runs"],
            "n_runs": self.n_runs,
            "succeeded": counts["succeeded"],
            "failed": counts["failed"],
            "errors": counts["errors"],
            "with_violations": counts["with_violations"],
            "violations_by_constraint": counts["violations_by_constraint"],
            "wall_time_s": None if not math.isfinite(self.wall_time_s) else round(self.wall_time_s, 3),
            "new_runs": self.new_runs,
            "complete": self.complete,
            "seed": self.manifest.get("seed"),
            "out": str(self.out) if self.out else None,
            "statistics": statistics_dict(self.statistics()),
            **({"navigation_consistency": nc} if (nc := navigation_consistency(self.table)) else {}),
        }

    def row(self, run_id: int) -> dict:
        hit = self.table[self.table["run_id"] == run_id]
        if hit.empty:
            raise ProxopsInputError(f"run_id = {run_id}: not in this campaign's finished runs (0..{self.n_runs - 1})")
        return hit.iloc[0].to_dict()

    def rerun(self, row_or_id, keep_series: bool = True):
        """Repeat one run alone from its row (or run_id); returns ``(row, SimResult or None)``."""
        row = self.row(row_or_id) if isinstance(row_or_id, (int, np.integer)) else dict(row_or_id)
        return rerun(row, self, keep_series=keep_series)

    def series(self, run_id: int):
        """The saved time series of a run (``keep_series=True`` campaigns)."""
        if self.out is None:
            raise ProxopsInputError("this campaign was not written to disk; rerun(run_id) gives its time series")
        path = series_dir(self.out, run_id)
        if not path.is_dir():
            raise ProxopsInputError(f"no time series for run {run_id} in {self.out} (run the campaign with keep_series)")
        return SimResult.load(path)


def load_campaign(out: str | Path) -> CampaignResult:
    """Read a campaign folder: manifest and all finished rows (consolidated)."""
    out = Path(out)
    if not out.is_dir():
        raise ProxopsInputError(f"{out}: not a folder; give a campaign folder written by `proxops mc ... --out DIR`")
    manifest = read_manifest(out)
    if manifest is None:
        raise ProxopsInputError(f"{out}: not a campaign folder (no {MANIFEST}); `proxops mc ... --out {out}` makes one")
    return CampaignResult(table=read_rows(out, strict=True), manifest=manifest, out=out)


from proxops.analysis.storage import (  # noqa: E402,F401 (public names re-exported from here)
    FORMAT,
    MANIFEST,
    _check_out,
    _empty_table,
    _RowWriter,
    _tidy,
    compact,
    read_manifest,
    read_rows,
    scenario_hash,
    series_dir,
    write_part,
)


def run_campaign(scenario, n_runs: int | None = None, workers: int | None = None, scheduler=None,
                 seed: int | None = None, out: str | Path | None = None, resume: bool = False,
                 overrides: Sequence[str] = (), progress: bool = True, keep_series: bool = False,
                 chunk_size: int | None = None, connect_timeout_s: float = 5.0,
                 target_batch_s: float = 0.5) -> CampaignResult:
    """Run (or with ``resume`` complete) a Monte Carlo campaign of a scenario.

    ``scenario``: built-in name, TOML file, raw dict or LoadedScenario. ``n_runs`` defaults to
    the number of grid points when the dispersions declare grids. ``seed`` (campaign seed,
    default ``sim.seed``) makes every run reproducible. ``out`` receives the manifest, the rows
    (Parquet, incrementally) and with ``keep_series`` each run's time series; ``out=None``
    keeps the rows in memory only. Ctrl-C saves the finished runs and re-raises KeyboardInterrupt.
    """
    if n_runs is not None and (isinstance(n_runs, bool) or not isinstance(n_runs, (int, np.integer))
                               or not 1 <= n_runs <= MAX_RUNS):
        raise ProxopsInputError(f"runs = {n_runs!r}: give a whole number of runs from 1 to {MAX_RUNS:,}")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))
                             or not 0 <= seed < 2**63):
        raise ProxopsInputError(f"seed = {seed!r}: give a whole number from 0 to 2^63 - 1")
    if not (isinstance(connect_timeout_s, (int, float)) and math.isfinite(connect_timeout_s) and connect_timeout_s > 0):
        raise ProxopsInputError(f"connect_timeout_s = {connect_timeout_s!r} s: give a positive, finite number of seconds")
    if resume and out is None:
        raise ProxopsInputError("resume: give the campaign folder (--out DIR) to resume")
    if chunk_size is not None and (not isinstance(chunk_size, int) or chunk_size < 1):
        raise ProxopsInputError(f"chunk_size = {chunk_size!r}: give a whole number >= 1 (or None: sized on the fly)")
    if not target_batch_s > 0:
        raise ProxopsInputError(f"target_batch_s = {target_batch_s!r} s: give a positive duration")
    prep = _prepare(scenario, overrides)
    sc = prep.loaded.scenario
    plan = prep.plan
    previous = read_manifest(Path(out)) if (resume and out is not None and Path(out).is_dir()) else None
    if seed is None:
        seed = previous["seed"] if previous and isinstance(previous.get("seed"), int) else int(sc.sim.seed)
    seed = int(seed)
    if n_runs is None:
        if previous and previous.get("n_runs"):
            n_runs = int(previous["n_runs"])
        elif plan.grid:
            n_runs = plan.n_grid
        else:
            raise ProxopsInputError("runs: give the number of runs (--runs N, a whole number >= 1)")
    n_runs = int(n_runs)
    if n_runs > MAX_RUNS:
        raise ProxopsInputError(f"runs = {n_runs:,} (the grid size): at most {MAX_RUNS:,} runs in one campaign")

    module = system_module(sc.system)  # found, not imported: this process never builds the system
    data_hash = scenario_hash(prep.data)
    manifest = {
        "format": FORMAT,
        "scenario": sc.name,
        "system": sc.system,
        "source": prep.source,
        "overrides": prep.overrides,
        "scenario_hash": data_hash,
        "seed": seed,
        "n_runs": n_runs,
        "n_grid": plan.n_grid,
        "dispersion_columns": [DISP_PREFIX + c for c in plan.columns()],
        "grid_axes": [[DISP_PREFIX + c for c in cols] for cols in plan.grid_columns()],
        "keep_series": bool(keep_series),
        "system_module": module,
        "scenario_data": prep.data,
        "proxops_version": _version(),
    }
    out_path = Path(out) if out is not None else None
    done_ids: set[int] = set()
    if out_path is not None:
        old = _check_out(out_path, manifest, resume)
        if old is not None:
            if n_runs < old.get("n_runs", 0):
                n_runs = int(old["n_runs"])  # resume never shrinks a campaign
                manifest["n_runs"] = n_runs
            manifest["keep_series"] = bool(old.get("keep_series", keep_series)) or bool(keep_series)
            manifest["created_utc"] = old.get("created_utc")
            existing = read_rows(out_path)
            done_ids = set(int(i) for i in existing["run_id"].tolist())

    spec_data = {k: v for k, v in prep.data.items() if k != "dispersions"}
    spec = CampaignSpec(data=spec_data, system=sc.system, system_module=module, source=prep.source,
                        scenario_hash=data_hash, keep_series=manifest["keep_series"])
    items = _LazyItems(plan, seed, n_runs, done_ids)
    # connect (Dask) / check workers before writing anything, so a bad --scheduler leaves no folder behind
    backend = _make_backend(workers, scheduler, spec, connect_timeout_s, len(items)) if items else None
    _check_campaign(backend, prep)  # every check a run makes, once, before anything is written
    if out_path is not None:
        out_path.mkdir(parents=True, exist_ok=True)
        manifest["created_utc"] = manifest.get("created_utc") or time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        tmp = out_path / (MANIFEST + ".tmp")
        tmp.write_text(json.dumps(manifest, indent=2, default=str))
        os.replace(tmp, out_path / MANIFEST)

    writer = _RowWriter(out_path)
    bar = _bar(n_runs, len(done_ids), f"mc {sc.name}", progress)
    state = _Progress()
    wall0 = time.perf_counter()

    def on_batch(idx, batch):
        rows = [r for r, _ in batch]
        writer.add(rows, [s for _, s in batch])
        state.done += len(rows)
        state.failed += sum(not r["success"] for r in rows)
        bar.update(len(rows))
        bar.set_postfix(failed=state.failed, refresh=False)

    def on_lost(i, message):
        item = items[i]
        row = {"run_id": item.run_id, "seed": item.seed, "grid_index": item.grid_index,
               **{DISP_PREFIX + k: v for k, v in item.values.items()},
               "outcome": "error", "success": False, "status": "error", "error": f"WorkerLost: {message}"}
        on_batch([i], [(row, None)])

    try:
        if backend is not None:
            _drive(backend, campaign_run, items, "return", on_batch, chunk_size, target_batch_s, on_lost=on_lost,
                   on_tick=writer.tick)
    except KeyboardInterrupt:
        with _sigint_blocked():  # the rows in hand are written whatever the user presses now
            writer.flush()
            bar.close()
        where = f"saved in {out_path}" if out_path is not None else "kept in memory only (no --out)"
        raise CampaignInterrupted(
            f"interrupted: {state.done} new runs {where}, {len(done_ids) + state.done} of {n_runs} finished; "
            "complete them with --resume", new_runs=state.done, out=out_path) from None
    finally:
        with _sigint_blocked():
            writer.flush()
        bar.close()
        wall = time.perf_counter() - wall0
    if out_path is not None:
        compact(out_path, writer.written)
        table = read_rows(out_path)
    else:
        table = _tidy(pd.DataFrame(writer.rows)) if writer.rows else _empty_table()
    return CampaignResult(table=table, manifest=manifest, out=out_path, wall_time_s=wall, new_runs=state.done)


def _check_campaign(backend, prep: _Prepared) -> None:
    """Every check a run makes (:func:`proxops.scenarios.loader.check_scenario`: the system's build and
    the dispersions), once, before anything is written. On a local pool the workers run the build
    (:func:`check_nominal`, one task per worker: it is their warm-up -- imports, numba kernels,
    per-process caches -- which the first run would do anyway), so this process never builds the
    system; its error is raised here as it would be by the check in this process."""
    if isinstance(backend, _PoolBackend):
        try:
            if backend.check(check_nominal, meanwhile=_parent_imports):
                return  # the dispersions were parsed by _prepare
        except BaseException:
            backend.close(cancel=True, force=True)
            raise
    check_scenario(prep.loaded)


def _parent_imports() -> None:
    """What this process imports once the runs go anyway -- the progress bar (tqdm) before the first
    batch is sent, the Parquet writer at the first part written -- imported while the pool's workers
    start instead (tqdm delayed the first batch, the writer's import took a core from the workers:
    25-60 ms, measured under load)."""
    import pyarrow.parquet  # noqa: F401
    import tqdm  # noqa: F401


class _LazyItems:
    """The runs still to do, as a sequence whose items are made when sent (a campaign of
    millions of runs starts at once)."""

    def __init__(self, plan: DispersionPlan, seed: int, n_runs: int, done_ids: set[int]):
        self.plan, self.seed = plan, seed
        self.todo = range(n_runs) if not done_ids else [i for i in range(n_runs) if i not in done_ids]

    def __len__(self) -> int:
        return len(self.todo)

    def __getitem__(self, k: int) -> RunItem:
        return make_item(self.plan, self.seed, self.todo[k])


def make_item(plan: DispersionPlan, campaign_seed: int, run_id: int) -> RunItem:
    """Seeds and dispersed values of run ``run_id`` (pure function of plan, seed and id)."""
    seed, rng = run_seeds(campaign_seed, run_id)
    grid_index, values = plan.values(run_id, rng)
    return RunItem(run_id=run_id, seed=seed, grid_index=grid_index, values=values)


def rerun(row: dict, campaign, keep_series: bool = True):
    """Repeat one run alone from its ``row`` (a dict or pandas Series of the campaign table).

    ``campaign``: a :class:`CampaignResult` or a campaign folder. Uses only the row's seed
    and ``disp.*`` values plus the scenario data stored in the manifest, so the returned row
    equals the stored one bit for bit (timing columns aside). Returns ``(row, SimResult)``."""
    if not isinstance(campaign, CampaignResult):
        campaign = load_campaign(campaign)
    m = campaign.manifest
    row = dict(row)
    data = m["scenario_data"]
    spec = CampaignSpec(data={k: v for k, v in data.items() if k != "dispersions"}, system=m["system"],
                        system_module=m.get("system_module", ""), source=m.get("source", "<manifest>"),
                        scenario_hash=m["scenario_hash"], keep_series=keep_series)
    values = {}
    for col, val in row.items():
        if isinstance(col, str) and col.startswith(DISP_PREFIX):
            if isinstance(val, float) and math.isnan(val):
                continue
            values[col[len(DISP_PREFIX):]] = val.item() if isinstance(val, np.generic) else val
    item = RunItem(run_id=int(row["run_id"]), seed=int(row["seed"]), grid_index=int(row.get("grid_index", 0)),
                   values=values)
    return campaign_run(spec, item)


def _campaign_system(manifest: dict):
    """The campaign's nominal scenario, validated, with its system (for the report hooks)."""
    data = {k: v for k, v in manifest["scenario_data"].items() if k != "dispersions"}
    return validate_scenario(data, source=str(manifest.get("scenario")))


def _version() -> str:
    return __version__


__all__ = [
    "run_campaign",
    "map_runs",
    "rerun",
    "load_campaign",
    "CampaignResult",
    "CampaignError",
    "CampaignInterrupted",
    "RunError",
    "campaign_run",
    "make_item",
    "run_seeds",
    "default_workers",
    "is_timing_column",
]
