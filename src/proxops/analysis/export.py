"""Export of a run: CCSDS OEM ephemerides (:mod:`proxops.orbitdata.ccsds`) and MATLAB ``.mat``.

Absolute states. A run records the chaser's true Hill state relative to the target; the target
is never controlled, so its inertial trajectory is the scenario's truth propagated freely over
the run's sample times (:func:`run_ephemeris`), and the chaser's is the truth plant's own exact
inverse of the recorded Hill state about it (``with_relative_state``, the map the run used).
The re-propagation agrees with the run's truth to the integrator tolerance (the adaptive
DOP853 step control sees a different chaser offset; rtol 1e-10). Truth ``cw`` has no
inertial model: the target flies its Keplerian orbit and the chaser is the exact Hill map of
the linear CW state about it (stated in the OEM's comments).

Files of ``--oem PATH`` (an OEM holds one object, ODM 2.0 sec. 5.1): ``PATH`` the chaser,
``<stem>-target<suffix>`` the target (both EME2000 = the truth's inertial axes, UTC) and
``<stem>-hill<suffix>`` the chaser relative to the target in the target's RTN (Hill) axes,
CENTER_NAME = the target. Samples at the same time (an impulse) start a new segment.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from proxops.core.layout import HILL_LAYOUT
from proxops.errors import ProxopsInputError
from proxops.orbitdata.ccsds import TRUTH_FRAME, OemSegment, utc_epochs, write_oem
from proxops.propagation.truth import RelativeTruth
from proxops.systems.common import translational_plant
from proxops.systems.schema._build_free import target_elements
from proxops.analysis.storage import read_manifest, read_rows, series_dir
from proxops.scenarios.loader import validate_scenario
from proxops.sim.result import SimResult
from proxops.analysis.campaign import rerun
from proxops.analysis.campaign_worker import DISP_PREFIX
from proxops.scenarios.dispersions import apply_values


@dataclass
class RunEphemeris:
    """Inertial and relative states of one run at its sample times ``t`` (s from ``epoch_utc``)."""

    epoch_utc: str
    t: np.ndarray
    target: np.ndarray  # (n, 6) truth inertial frame, m, m/s
    chaser: np.ndarray  # (n, 6)
    hill: np.ndarray  # (n, 6) chaser relative to target, Hill/RTN, m, m/s
    truth: str
    object_name: str


def check_exportable(sc) -> None:
    """One-line error unless the scenario has a target orbit and a translational truth (before a run)."""
    if getattr(sc, "orbit", None) is None or getattr(sc, "truth", None) is None:
        raise ProxopsInputError(f"--oem: the {sc.system} scenario '{sc.name}' has no [orbit] and [truth]: "
                                "ephemerides need a target orbit (srf, station-keeping, cortex)")


def _require_orbit_run(sc, result) -> None:
    check_exportable(sc)
    if result.layout.to_dict() != HILL_LAYOUT.to_dict():
        raise ProxopsInputError(f"export: the {sc.system} run's state is not the Hill relative state "
                                "[x, y, z, vx, vy, vz]: ephemerides need a translational run (srf, station-keeping, cortex)")


def _target_plant(sc, x0_hill: np.ndarray):
    if sc.truth.model == "cw":
        return RelativeTruth(target_elements(sc.orbit), x0_hill, j2=False, integrator="fast")
    return translational_plant(sc.orbit, sc.truth, x0_hill)


def run_ephemeris(sc, result) -> RunEphemeris:
    """:class:`RunEphemeris` of a translational run (see module doc)."""
    _require_orbit_run(sc, result)
    t = np.asarray(result.t, dtype=float)
    hill = np.asarray(result.x_true, dtype=float)
    plant = _target_plant(sc, hill[0])
    y = plant.initial_state()
    if t[0] > 0.0:
        y = plant.propagate(0.0, y, None, float(t[0]))
    target = np.empty((t.size, 6))
    chaser = np.empty((t.size, 6))
    for k in range(t.size):
        if k > 0 and t[k] > t[k - 1]:
            y = plant.propagate(float(t[k - 1]), y, None, float(t[k] - t[k - 1]))
        target[k] = plant.target_state(y)
        chaser[k] = plant.chaser_state(plant.with_relative_state(y, hill[k]))
    return RunEphemeris(sc.orbit.epoch_utc, t, target, chaser, hill, sc.truth.model, sc.name)


def oem_paths(path: str | Path) -> dict[str, Path]:
    """``{"chaser": path, "target": <stem>-target<suffix>, "hill": <stem>-hill<suffix>}``."""
    p = Path(path)
    suffix = p.suffix or ".oem"
    return {"chaser": p, "target": p.with_name(f"{p.stem}-target{suffix}"),
            "hill": p.with_name(f"{p.stem}-hill{suffix}")}


def _segments(t: np.ndarray) -> list[slice]:
    """Index ranges with strictly increasing times (a repeated time starts a new segment)."""
    cuts = [0] + [k for k in range(1, t.size) if t[k] <= t[k - 1]] + [t.size]
    return [slice(a, b) for a, b in zip(cuts[:-1], cuts[1:]) if b > a]


def write_run_oem(sc, result, path: str | Path, label: str = "run") -> dict[str, Path]:
    """Write the three OEM files of a run (module doc); returns their paths by role."""
    eph = run_ephemeris(sc, result)
    epochs = utc_epochs(eph.epoch_utc, eph.t)
    base = _object_id(sc.name)
    truth_note = {"cw": "truth cw: linear CW relative state mapped exactly about the target's Keplerian orbit",
                  "two-body": "truth two-body (Encke)", "j2": "truth two-body + J2 (Encke)",
                  "full": "truth full composed force models"}[eph.truth]
    common = [f"proxops scenario {sc.name} ({sc.system}), {label}, epoch {eph.epoch_utc}; {truth_note}",
              "EME2000: the truth's inertial axes (J2000 mean equator and equinox, IAU-76/80 truncated; "
              "proxops.environment.earth)",
              "samples of the closed-loop run; an impulse changes the velocity at its sample: interpolate "
              "within coasts"]
    paths = oem_paths(path)
    for role, states, frame, center in (("chaser", eph.chaser, TRUTH_FRAME, "EARTH"),
                                        ("target", eph.target, TRUTH_FRAME, "EARTH"),
                                        ("hill", eph.hill, "RTN", f"{base}-TARGET")):
        obj = f"{base}-{'TARGET' if role == 'target' else 'CHASER'}"
        notes = ["RTN = the target's Hill axes: x radial, y along-track, z orbit normal; rotating with the target"] \
            if role == "hill" else []
        segs = [OemSegment(obj, obj, epochs[s], states[s], center_name=center, ref_frame=frame, comments=notes)
                for s in _segments(eph.t)]
        write_oem(paths[role], segs, comments=common)
    return paths


def _object_id(name: str) -> str:
    return re.sub(r"[^A-Z0-9]+", "-", name.upper()).strip("-") or "PROXOPS"


# ---------------------------------------------------------------------------- MATLAB
def _mat_name(key: str) -> str:
    """A MATLAB field name (letter first, [A-Za-z0-9_], at most 63 characters)."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", str(key))
    if not name or not name[0].isalpha():
        name = "x_" + name
    return name[:63]


def _mat_value(v):
    if isinstance(v, dict):
        return {_mat_name(k): _mat_value(x) for k, x in v.items()}
    if v is None:
        return np.nan
    if isinstance(v, (list, tuple)):
        if all(isinstance(x, (int, float, bool, np.number)) for x in v):
            return np.asarray(v, dtype=float)
        return np.array([str(x) for x in v], dtype=object)
    return v


def result_struct(result, ephemeris: RunEphemeris | None = None) -> dict:
    """The named time series of a run as a MATLAB struct (dict of arrays; SI units)."""
    out = {"t_s": result.t, "x_true": result.x_true, "x_est": result.x_est, "u_cmd": result.u_cmd,
           "u_applied": result.u_applied, "dv_cum_mps": result.dv_cum, "solve_time_s": result.solve_time_s,
           "status": np.array([str(s) for s in result.status], dtype=object),
           "mode": np.array([str(m) for m in result.mode], dtype=object),
           "state_names": np.array([f"{b.name}.{n}" for b in result.layout.blocks for n in (b.names or
                                    [str(i) for i in range(b.stop - b.start)])], dtype=object),
           "events": {"t_s": np.array([e[0] for e in result.events], dtype=float),
                      "kind": np.array([e[1] for e in result.events], dtype=object),
                      "message": np.array([e[2] for e in result.events], dtype=object)}}
    out["info"] = {_mat_name(k): np.asarray(v) for k, v in result.info.items()}
    if ephemeris is not None:
        out.update(epoch_utc=ephemeris.epoch_utc, target_eci=ephemeris.target, chaser_eci=ephemeris.chaser,
                   eci_frame="EME2000 (truth inertial axes), m and m/s")
    return out


def write_run_mat(path: str | Path, summary: dict, results: dict, sc=None) -> Path:
    """``.mat`` (scipy.io.savemat, MATLAB 5 format) with ``summary`` (struct) and one struct per
    result label (``run``, ...) of :func:`result_struct`; absolute ephemerides when the run has an
    orbit (``target_eci``, ``chaser_eci``)."""
    from scipy.io import savemat

    data = {"summary": _mat_value(summary)}
    for label, result in results.items():
        eph = None
        if sc is not None:
            try:
                eph = run_ephemeris(sc, result)
            except ProxopsInputError:
                eph = None
        data[_mat_name(label)] = result_struct(result, eph)
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    savemat(p, data, long_field_names=True, do_compression=True, oned_as="column")
    return p


# ---------------------------------------------------------------------------- runs on disk
def export_run(loaded, summary: dict, results: dict, oem: Path | None = None, mat: Path | None = None,
               label: str | None = None) -> dict[str, str]:
    """Write the OEM files of result ``label`` (default: the first) and/or the ``.mat`` of all
    results; returns ``{role: path}`` of what was written."""
    written: dict[str, str] = {}
    if oem is not None:
        label = label or next(iter(results))
        if label not in results:
            raise ProxopsInputError(f"--label {label!r}: the run has results {', '.join(results)}")
        for role, p in write_run_oem(loaded.scenario, results[label], oem, label).items():
            written[f"oem_{role}"] = str(p)
    if mat is not None:
        written["mat"] = str(write_run_mat(mat, summary, results, loaded.scenario))
    return written


def load_saved_run(folder: str | Path, run_id: int | None = None):
    """``(loaded scenario, summary, {label: SimResult})`` of a folder written by ``proxops run --out``
    (needs its ``scenario.json``) or, with ``run_id``, of one run of a campaign folder (its stored
    series, or the run repeated bit for bit from the manifest when the series were not kept)."""
    import json

    d = Path(folder)
    if not d.is_dir():
        raise ProxopsInputError(f"{d}: no such folder (give a folder written by proxops run --out or proxops mc --out)")
    manifest = read_manifest(d)
    if manifest is not None:
        if run_id is None:
            raise ProxopsInputError(f"{d} is a campaign of {manifest['n_runs']} runs: choose one with --run N "
                                    f"(0 to {int(manifest['n_runs']) - 1})")

        rows = read_rows(d, strict=True)
        match = rows[rows["run_id"] == run_id]
        if match.empty:
            done = f"0 to {int(rows['run_id'].max())}" if len(rows) else "none yet"
            raise ProxopsInputError(f"--run {run_id}: no such run in {d} (runs stored: {done})")
        row = match.iloc[0].to_dict()
        values = {k[len(DISP_PREFIX):]: (v.item() if isinstance(v, np.generic) else v) for k, v in row.items()
                  if isinstance(k, str) and k.startswith(DISP_PREFIX) and not (isinstance(v, float) and np.isnan(v))}
        base = {k: v for k, v in manifest["scenario_data"].items() if k != "dispersions"}
        nominal = validate_scenario(json.loads(json.dumps(base)), source=str(manifest.get("scenario"))).scenario
        data = apply_values(json.loads(json.dumps(base)), values, nominal)
        loaded = validate_scenario(data, source=f"{manifest.get('scenario')} (run {run_id})")
        sdir = series_dir(d, run_id)
        result = SimResult.load(sdir) if (sdir / "steps.parquet").is_file() else rerun(row, d)[1]
        summary = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in row.items()}
        return loaded, summary, {"run": result}
    scen = d / "scenario.json"
    if not scen.is_file():
        raise ProxopsInputError(f"{d}: no scenario.json (folders of proxops run --out from this version on have "
                                "one; run the scenario again with --out)")
    try:
        data = json.loads(scen.read_text())
        summary = json.loads((d / "summary.json").read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ProxopsInputError(f"{d}: damaged run folder ({type(exc).__name__}: {exc})") from None
    loaded = validate_scenario(data, source=str(scen))
    labels = sorted(p.parent.name for p in d.glob("*/steps.parquet"))
    if not labels:
        raise ProxopsInputError(f"{d}: no run results (<label>/steps.parquet)")
    order = ["run"] + [x for x in labels if x != "run"]
    return loaded, summary, {x: SimResult.load(d / x) for x in order if x in labels}
