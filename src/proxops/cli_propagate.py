"""``proxops propagate``: the uncontrolled relative state under the scenario's truth, and what
each force model changes at the end. Mounted by :mod:`proxops.cli` as a command::

    proxops propagate --scenario station-keeping --duration-s 5668 --model full --json
    proxops propagate --scenario my.toml --duration-s 5668 --set truth.gravity_degree=100 --set truth.srp=true

JSON: ``{"scenario", "model", "label", "epoch_utc", "duration_s", "initial_hill", "final_hill",
"cw_final_hill", "contributions": [{"model", "delta_hill", "delta_position_m",
"delta_velocity_mps"}], "runtime_s"}``; Hill states are [x, y, z, vx, vy, vz] (m, m/s),
x radial, y along-track, z orbit normal.
"""

from __future__ import annotations

import math
import time
from typing import Annotated, Optional

import numpy as np
import typer

from proxops.cli_common import emit
from proxops.errors import input_error
from proxops.core.cw import cw_stm
from proxops.propagation.composed import ForceModels, final_hill, force_contributions
from proxops.scenarios.loader import load_scenario
from proxops.systems.schema._build_free import initial_hill_state, target_elements
from proxops.systems.full_truth import force_models
from proxops.propagation.truth import RelativeTruth

MODELS = ("cw", "two-body", "j2", "full")


def propagate(
    scenario: Annotated[str, typer.Option("--scenario", help="Built-in scenario name or TOML file with [orbit], [initial] and [truth].")],
    duration_s: Annotated[float, typer.Option("--duration-s", help="Propagation time, s (> 0).")],
    model: Annotated[Optional[str], typer.Option("--model", help="Override truth.model: cw, two-body, j2 or full.")] = None,
    overrides: Annotated[Optional[list[str]], typer.Option("--set", help="Override a scenario key, e.g. truth.gravity_degree=100 (repeatable).")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
):
    """Propagate the uncontrolled chaser relative to the target and show what each force model changes."""

    if not (math.isfinite(duration_s) and duration_s > 0):
        raise input_error("--duration-s", duration_s, "must be finite and > 0", "s")
    if model is not None and model not in MODELS:
        raise input_error("--model", model, "must be one of cw, two-body, j2, full")
    sets = list(overrides or [])
    if model is not None:
        sets.append(f'truth.model="{model}"')
    loaded = load_scenario(scenario, sets)
    sc = loaded.scenario
    for section in ("orbit", "initial", "truth"):
        if getattr(sc, section, None) is None:  # srf's [initial] is optional (it starts on its approach axis)
            raise input_error("--scenario", scenario, f"needs an [{section}] section (a translational scenario "
                              "with its initial relative state)")
    elements = target_elements(sc.orbit)
    x0 = initial_hill_state(sc.initial)
    truth = sc.truth
    n = math.sqrt(3.986004418e14 / elements.sma**3)
    cw_final = cw_stm(n, duration_s) @ x0
    started = time.perf_counter()
    if truth.model == "full":
        models = force_models(sc.orbit, truth)
    else:
        models = ForceModels(epoch=sc.orbit.epoch_utc, gravity={"j2": "j2"}.get(truth.model, "point"))
    if truth.model == "cw":
        final, rows, label = cw_final, [], "CW (linear)"
    else:
        final, rows = force_contributions(elements, x0, models, duration_s, truth.integrator)
        label = models.label()
        if truth.model != "full":  # RelativeTruth is the run-time path of these models

            plant = RelativeTruth(elements, x0, j2=truth.model == "j2", integrator=truth.integrator)
            final = plant.relative_state(plant.propagate(0.0, plant.initial_state(), None, duration_s))
    runtime = time.perf_counter() - started
    payload = {
        "scenario": sc.name,
        "model": truth.model,
        "label": label,
        "epoch_utc": sc.orbit.epoch_utc,
        "duration_s": duration_s,
        "initial_hill": x0,
        "final_hill": np.asarray(final),
        "cw_final_hill": cw_final,
        "contributions": rows,
        "runtime_s": runtime,
    }
    sep = float(np.linalg.norm(x0[:3]))
    lines = [
        f"{sc.name}: {label} truth, {duration_s:g} s from {sc.orbit.epoch_utc} (initial separation {sep:.1f} m)",
        "final Hill state  x, y, z (m)  vx, vy, vz (m/s):",
        "  " + "  ".join(f"{v:.6g}" for v in final[:3]) + "   " + "  ".join(f"{v:.6g}" for v in final[3:]),
        f"  CW (linear) differs by {np.linalg.norm(np.asarray(final[:3]) - cw_final[:3]):.4g} m",
    ]
    if rows:
        lines.append(f"what each model changes at the end (final - final without it):")
        lines.append(f"  {'model':<22} {'|dr| (m)':>12} {'|dv| (m/s)':>12}   dx, dy, dz (m)")
        for r in rows:
            d = r["delta_hill"]
            lines.append(
                f"  {r['model']:<22} {r['delta_position_m']:>12.4g} {r['delta_velocity_mps']:>12.4g}   "
                + ", ".join(f"{v:.3g}" for v in d[:3])
            )
    lines.append(f"runtime {runtime:.2f} s")
    emit(payload, as_json, "\n".join(lines))
