"""The row types and verdict rules of ``proxops reproduce`` (shared by every ``claims/<system>.py``).

A :class:`Claim` is one headline result of a paper beside ours with a verdict from :data:`VERDICTS`;
the rules each verdict must satisfy are :data:`VERDICT_RULES` (printed under the table and in the
README). A :class:`Goal` is one of the project's own targets (wall times, our Monte Carlo success
rates): it is not a paper claim and never carries a paper verdict. Campaigns run through
:func:`campaign`, which keeps them in ``<out>/cache/<scenario>-runs<N>-seed<S>-<overrides>-v<version>``
and reuses a finished one instead of running it again.
"""

from __future__ import annotations

from proxops.jsonable import json_default

import hashlib
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from proxops.runner import run_scenario
from proxops import __version__
from proxops.analysis.campaign import MANIFEST, run_campaign
from proxops.report.campaign import write_report

REPRODUCED = "reproduced"
EXPLAINED = "differs, explained"
UNEXPLAINED = "differs, unexplained"
CALIBRATED = "calibrated or fitted to the paper"
NOT_ATTEMPTED = "not attempted"
INCONSISTENT = "paper inconsistent"
VERDICTS = (REPRODUCED, EXPLAINED, UNEXPLAINED, CALIBRATED, NOT_ATTEMPTED, INCONSISTENT)

VERDICT_RULES = (
    f"`{REPRODUCED}`: ours agrees with the paper within the row's stated tolerance, and the row says where the "
    "tolerance comes from (the paper's printed precision, a paper-given bound, or a spread measured independently); "
    "a quantity our simulation makes true by construction is never 'reproduced' (a property the paper itself says "
    "holds by construction is, when the row measures the construction's precondition).",
    f"`{EXPLAINED}`: ours differs and the row carries a measurement that shows the cause (in its note and data); "
    "a bracket of two readings or a plausible story without a measurement is not an explanation.",
    f"`{UNEXPLAINED}`: ours differs and we have no measurement showing why.",
    f"`{CALIBRATED}`: ours matches because a parameter the paper does not give was chosen on the paper's own "
    "number: the match is not evidence.",
    f"`{NOT_ATTEMPTED}`: the result needs hardware, data or a model the paper does not give, or the row's number "
    "cannot differ from the paper's by construction; the row says which.",
    f"`{INCONSISTENT}`: the paper contradicts itself on this result; the row names both places.",
    "Labels: a row whose number inherits a calibrated or tuned choice carries it in its labels "
    "(CALIBRATED: ..., TUNED: ...), whatever its verdict; tuned choices are reported on seeds never used for tuning.",
    "Our own goals (wall times, our Monte Carlo success rates) are in a separate table with met / not met, "
    "never with a paper verdict.",
)


@dataclass
class Claim:
    system: str
    claim: str
    paper: str  # value and where (section / table / figure)
    ours: str
    verdict: str
    note: str = ""  # how it was measured, the window, why it differs
    reduced: str = ""  # what --quick reduced for this row ("" = as in the full run)
    data: dict = field(default_factory=dict)  # the numbers behind ``ours`` (JSON)
    tolerance: str = ""  # for "reproduced": the tolerance and its source
    labels: list = field(default_factory=list)  # "CALIBRATED: ...", "TUNED: ..." inherited choices

    def __post_init__(self):
        if self.verdict not in VERDICTS:
            raise ValueError(f"verdict {self.verdict!r} is not one of {VERDICTS}")
        if self.verdict == REPRODUCED and not self.tolerance:
            raise ValueError(f"{self.system}: {self.claim!r} is 'reproduced' without a stated tolerance")


@dataclass
class Goal:
    """One of our own targets (not a paper claim): met is True / False (None: not measured)."""

    system: str
    goal: str
    target: str
    ours: str
    met: bool | None
    note: str = ""
    data: dict = field(default_factory=dict)


@dataclass
class Context:
    quick: bool = False
    workers: int = 2
    out: Path | None = None  # full run: campaign cache and figures go here
    progress: bool = False
    goals: list = field(default_factory=list)  # Goal rows the claim functions add
    campaigns: list = field(default_factory=list)  # {key, runs, reused, wall_s}

    def sub(self, name: str) -> Path | None:
        if self.out is None:
            return None
        p = Path(self.out) / name
        p.mkdir(parents=True, exist_ok=True)
        return p


def f(x: float, digits: int = 2) -> str:
    return f"{x:.{digits}f}"


RUN_CACHE: dict = {"dir": None, "memo": {}}  # set by reproduce(): OUT/cache (None: in memory only)


def run(name: str, overrides=(), out: Path | None = None, cache: bool = True) -> dict:
    """One closed loop of a built-in (``proxops run``): its summary. With ``cache`` the summary is kept
    for this process and, when reproduce() has an OUT folder, in ``OUT/cache/run-<key>.json`` (a later
    reproduction reuses it; figures are written on the first run only). ``cache=False`` for rows that
    measure wall time."""

    key = cache_key(name, 1, None, overrides).replace("-runs1-seeddefault", "")
    memo, folder = RUN_CACHE["memo"], RUN_CACHE["dir"]
    path = Path(folder) / f"run-{key}.json" if folder is not None else None
    if cache and key in memo:
        return memo[key]
    if cache and path is not None and path.exists():
        memo[key] = json.loads(path.read_text())
        return memo[key]
    s = run_scenario(name, overrides=list(overrides), out=out, figures=out is not None)
    if cache:
        memo[key] = s
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(s, default=json_default))
    return s


def cache_key(name: str, runs: int, seed: int | None, overrides=()) -> str:
    """``<scenario>-runs<N>-seed<S>-<sha of the overrides>-v<proxops version>`` (folder name under out/cache)."""

    ov = hashlib.sha1(json.dumps(sorted(overrides)).encode()).hexdigest()[:8] if overrides else "default"
    return f"{name}-runs{runs}-seed{'default' if seed is None else seed}-{ov}-v{__version__}"


def campaign(name: str, ctx: Context, runs: int | None, overrides=(), seed: int | None = None, scenario=None):
    """A Monte Carlo campaign of a built-in, cached under ``out/cache/<cache_key>``: a finished campaign
    there is reused (its rows read back), an interrupted one completed (``seed=None``: the scenario's
    ``sim.seed``; ``scenario``: a scenario dict to run instead of the built-in ``name``, which then only
    names the cache; ``runs=None``: its grid size). Without ``out`` (--quick) the rows stay in memory."""

    key = cache_key(name, runs, seed, overrides)
    out = ctx.sub(f"cache/{key}")
    resume = out is not None and (out / MANIFEST).exists()
    t0 = time.perf_counter()
    res = run_campaign(name if scenario is None else scenario, n_runs=runs, workers=ctx.workers, out=out, overrides=list(overrides), seed=seed,
                       progress=ctx.progress, keep_series=out is not None, resume=resume)
    wall = time.perf_counter() - t0
    if out is not None and not (out / "report").exists():
        write_report(res)  # tables + the system's Monte Carlo figures under out/report
    ctx.campaigns.append({"key": key, "runs": runs, "reused": resume, "wall_s": wall})
    return res


def abort_items(table) -> list[list[dict]]:
    out = []
    for v in table["metric.abort"]:
        out.append(json.loads(v) if isinstance(v, str) else list(v))
    return out


def sig_round(x: float, digits: int = 1) -> float:
    """``x`` rounded to ``digits`` significant figures (how a paper's '~10x' is read)."""
    import math

    if x == 0 or not math.isfinite(x):
        return x
    return round(x, -int(math.floor(math.log10(abs(x)))) + digits - 1)
