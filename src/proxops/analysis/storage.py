"""Campaign storage on disk: the manifest (``campaign.json``), run rows as Parquet parts
(``runs/part-*.parquet``, atomic rename, compaction of own parts), per-run series folders.
See :mod:`proxops.analysis.campaign` for the layout."""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
import uuid
from pathlib import Path
from typing import Sequence

import pandas as pd

from proxops.analysis.statistics import DISP_PREFIX, METRIC_PREFIX
from proxops.errors import ProxopsInputError
from proxops.exec.backends import _sigint_blocked

FORMAT = "proxops-campaign/1"
MANIFEST = "campaign.json"


def scenario_hash(data: dict) -> str:
    """Content hash of a scenario's data after overrides (dispersions included)."""
    text = json.dumps(data, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def series_dir(out: Path, run_id: int) -> Path:
    return Path(out) / "series" / f"run_{run_id:06d}"


_MANIFEST_KEYS = ("format", "scenario", "scenario_hash", "seed", "n_runs", "scenario_data")


def read_manifest(out: Path) -> dict | None:
    """The folder's ``campaign.json`` (None if absent); a damaged one is a one-line error."""
    path = Path(out) / MANIFEST
    if not path.is_file():
        return None
    try:
        manifest = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ProxopsInputError(f"{path}: damaged campaign manifest ({exc}); restore it, or start the campaign "
                                "again in another folder") from None
    missing = [k for k in _MANIFEST_KEYS if not isinstance(manifest, dict) or k not in manifest]
    if missing:
        raise ProxopsInputError(f"{path}: damaged campaign manifest (missing {', '.join(missing)}); restore it, "
                                "or start the campaign again in another folder")
    return manifest


def read_rows(out: Path, strict: bool = False) -> pd.DataFrame:
    """Consolidate ``runs/part-*.parquet`` (last write of a run_id wins), sorted by run_id.
    A damaged part is an error with ``strict`` (reports must not silently drop runs); otherwise
    a warning, and its runs count as missing (resume runs them again; the file is kept)."""
    parts = sorted((Path(out) / "runs").glob("part-*.parquet"))
    frames = []
    for p in parts:
        try:
            frames.append(pd.read_parquet(p))
        except Exception as exc:  # a part cut by a crash or damaged on disk
            if strict:
                raise ProxopsInputError(
                    f"{p}: unreadable results file ({type(exc).__name__}); `proxops mc ... --resume` runs its "
                    "runs again, then move the file away") from None
            print(f"warning: {p.name} is unreadable, its runs count as missing and run again", file=sys.stderr)
    if not frames:
        return _empty_table()
    return _tidy(pd.concat(frames, ignore_index=True, sort=False))


def _empty_table() -> pd.DataFrame:
    return pd.DataFrame(columns=["run_id", "seed", "grid_index", "outcome", "success", "status", "error"])


def _tidy(table: pd.DataFrame) -> pd.DataFrame:
    table = table.drop_duplicates("run_id", keep="last").sort_values("run_id", kind="stable").reset_index(drop=True)
    completed = table["outcome"] != "error"
    for col in table.columns:
        if col.startswith(METRIC_PREFIX + "events."):
            filled = table[col].where(~completed | table[col].notna(), 0)
            table[col] = filled.astype("int64") if filled.notna().all() else filled
    front = ["run_id", "seed", "grid_index", "outcome", "success", "status", "error"]
    disp = sorted(c for c in table.columns if c.startswith(DISP_PREFIX))
    disp = [c for c in disp]  # declaration order is kept in the manifest; sorted here for stability
    metrics = [c for c in table.columns if c.startswith(METRIC_PREFIX)]
    rest = [c for c in table.columns if c not in front and c not in disp and c not in metrics]
    return table[[c for c in front if c in table.columns] + disp + sorted(metrics) + rest]


class _RowWriter:
    """Collects finished runs and appends them as Parquet parts (atomic rename), at most one
    part every ``flush_s`` seconds; time series are written as soon as a run arrives."""

    def __init__(self, out: Path | None, flush_s: float = 2.0):
        self.out = out
        self.flush_s = flush_s
        self.rows: list[dict] = []  # kept only without a folder (in-memory campaigns)
        self.written: list[Path] = []  # parts this writer wrote (compaction deletes only these)
        self.pending: list[dict] = []
        self.last_flush = time.perf_counter()
        if out is not None:
            (out / "runs").mkdir(parents=True, exist_ok=True)

    def add(self, rows: list[dict], series: list) -> None:
        if self.out is None:
            self.rows.extend(rows)
            return
        for row, res in zip(rows, series):
            if res is not None:
                res.save(series_dir(self.out, row["run_id"]))
        self.pending.extend(rows)
        self.tick()

    def tick(self) -> None:
        """Write the pending rows if the last write is ``flush_s`` old (also while runs are slow)."""
        if self.pending and time.perf_counter() - self.last_flush >= self.flush_s:
            with _sigint_blocked():
                self.flush()

    def flush(self) -> None:
        if self.out is None or not self.pending:
            return
        ids = [r["run_id"] for r in self.pending]
        self.written.append(write_part(self.out, pd.DataFrame(self.pending),
                                       f"{min(ids):08d}-{max(ids):08d}-{uuid.uuid4().hex[:8]}"))
        self.pending = []
        self.last_flush = time.perf_counter()


def write_part(out: Path, frame: pd.DataFrame, tag: str) -> Path:
    """Write ``runs/part-<tag>.parquet`` atomically (temporary file, then rename)."""
    final = Path(out) / "runs" / f"part-{tag}.parquet"
    tmp = final.with_name(final.name + ".tmp")
    frame.to_parquet(tmp, index=False)
    os.replace(tmp, final)
    return final


def compact(out: Path, parts: Sequence[Path]) -> None:
    """Merge ``parts`` (files this process wrote) into one; never touches another file, so a
    resume cannot delete results it did not write. A crash in between leaves duplicates,
    which are harmless: reading deduplicates on run_id."""
    parts = [Path(p) for p in parts if Path(p).is_file()]
    if len(parts) <= 1:
        return
    table = _tidy(pd.concat([pd.read_parquet(p) for p in parts], ignore_index=True, sort=False))
    merged = write_part(out, table, f"{int(table['run_id'].min()):08d}-{int(table['run_id'].max()):08d}-"
                                    f"all{uuid.uuid4().hex[:6]}")
    for p in parts:
        if p != merged:
            p.unlink(missing_ok=True)


def _check_out(out: Path, manifest: dict, resume: bool) -> dict | None:
    """Existing manifest for resume (or None for a new campaign); clear errors on mismatch."""
    if out.exists() and not out.is_dir():
        raise ProxopsInputError(f"--out {out}: exists and is a file; give a folder (it is created if missing)")
    old = read_manifest(out) if out.is_dir() else None
    if old is None:
        leftovers = [p.name for p in (out / "runs", out / "series") if p.exists()]
        if leftovers:  # rows of an unknown campaign: never mix them with new ones
            raise ProxopsInputError(
                f"--out {out}: holds {' and '.join(leftovers)}/ but no {MANIFEST}, so those results belong to no "
                "known campaign; choose an empty or new folder")
        if resume:
            raise ProxopsInputError(
                f"--resume {out}: no {MANIFEST} there, so nothing to resume; leave out --resume to start a campaign"
            )
        return None
    if not resume:
        raise ProxopsInputError(
            f"--out {out} already holds a campaign of scenario {old.get('scenario')!r} "
            f"({old.get('n_runs')} runs); pass --resume to complete it or choose another --out"
        )
    if old.get("format") != FORMAT:
        raise ProxopsInputError(f"--resume {out}: manifest format {old.get('format')!r}, this proxops writes {FORMAT!r}")
    if old.get("scenario_hash") != manifest["scenario_hash"]:
        raise ProxopsInputError(
            f"--resume {out}: that folder holds a campaign of scenario {old.get('scenario')!r} "
            f"(content hash {old.get('scenario_hash')}), not of {manifest['scenario']!r} with these overrides "
            f"(hash {manifest['scenario_hash']}); use the same scenario file and --set options, or another --out"
        )
    if old.get("proxops_version") != manifest["proxops_version"]:
        raise ProxopsInputError(
            f"--resume {out}: that campaign was run by proxops {old.get('proxops_version')}, this is "
            f"{manifest['proxops_version']}; rows of two versions would be mixed: finish it with that version or "
            "start again in another folder")
    if old.get("seed") != manifest["seed"]:
        raise ProxopsInputError(
            f"--resume {out}: campaign seed {manifest['seed']} differs from the folder's seed {old.get('seed')}; "
            f"pass --seed {old.get('seed')} or use another --out"
        )
    return old
