"""CCSDS exchange (proxops.orbitdata.ccsds, proxops.analysis.export): OEM files of a run parsed by
the independent ``oem`` package with the same states, OEM round trip, absolute states against an
independent integration, OPM targets and their one-line errors, MATLAB export, saved runs and
campaign runs through ``proxops export``."""

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from proxops.cli import app
from proxops.orbitdata.ccsds import OemSegment, format_oem, read_oem, seconds_between, utc_epochs
from conftest import one_line_error

L1 = "1 25544U 98067A   08264.51782528 -.00002182  00000-0 -11606-4 0  2927"
L2 = "2 25544  51.6416 247.4627 0006703 130.5360 325.0288 15.72125391563537"
TLE_SET = f'orbit.tle=["{L1}", "{L2}"]'
DURATION_S = 300.0


def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def run_files(tmp_path_factory):
    """``proxops run station-keeping`` from the ISS TLE (J2 truth, 300 s) with --out, --oem and --mat."""
    d = tmp_path_factory.mktemp("oem")
    res = invoke("run", "station-keeping", "--set", TLE_SET, "--set", f"sim.duration_s={DURATION_S}", "--out",
                 d / "run", "--no-figures", "--oem", d / "sk.oem", "--mat", d / "sk.mat", "--json")
    assert res.exit_code == 0, (res.stderr, res.exception)
    from proxops.sim.result import SimResult

    return d, json.loads(res.stdout), SimResult.load(d / "run" / "run")


def _oem_package_states(path):
    """(seconds from the first epoch, states m and m/s, metadata) read by the ``oem`` package."""
    from oem import OrbitEphemerisMessage

    o = OrbitEphemerisMessage.open(str(path))
    states = list(o.states)
    t0 = states[0].epoch
    t = np.array([(s.epoch - t0).sec for s in states])
    x = np.array([np.concatenate([s.position, s.velocity]) for s in states]) * 1e3
    return t, x, o._segments[0].metadata


def test_oem_parsed_by_the_oem_package_with_the_same_states(run_files):
    from proxops.analysis.export import oem_paths, run_ephemeris
    from proxops.scenarios.loader import load_scenario

    d, summary, result = run_files
    assert set(summary["export"]) == {"oem_chaser", "oem_target", "oem_hill", "mat"}
    sc = load_scenario("station-keeping", [TLE_SET, f"sim.duration_s={DURATION_S}"]).scenario
    eph = run_ephemeris(sc, result)
    paths = oem_paths(d / "sk.oem")
    for role, expected, frame in (("chaser", eph.chaser, "EME2000"), ("target", eph.target, "EME2000"),
                                  ("hill", result.x_true, "RTN")):
        t, x, meta = _oem_package_states(paths[role])
        assert meta["REF_FRAME"] == frame and meta["TIME_SYSTEM"] == "UTC" and meta["INTERPOLATION"] == "HERMITE"
        assert np.allclose(t, result.t - result.t[0], rtol=0, atol=1e-6)  # the oem package keeps microseconds
        assert np.max(np.abs(x[:, :3] - expected[:, :3])) < 1e-5  # m: printed to 1 um
        assert np.max(np.abs(x[:, 3:] - expected[:, 3:])) < 1e-8  # m/s: printed to 1 nm/s
    t, x, meta = _oem_package_states(paths["hill"])
    assert meta["CENTER_NAME"] == "STATION-KEEPING-TARGET"


def test_absolute_states_against_an_independent_integration(run_files):
    """Target: scipy DOP853 of two-body + J2 (written here) from the TLE state agrees with the OEM at
    the last epoch to 1 mm; chaser - target rotated into the target's RTN axes (proxops.frames) is
    the recorded Hill position to 1 um."""
    from scipy.integrate import solve_ivp

    from proxops.core.constants import J2_EARTH, MU_EARTH, R_EARTH
    from proxops.frames.hill import eci_to_hill
    from proxops.orbitdata.tle import tle_orbit

    d, _, result = run_files
    t, target, _ = _oem_package_states(d / "sk-target.oem")
    _, chaser, _ = _oem_package_states(d / "sk.oem")

    def rhs(_t, y):
        r = y[:3]
        rn = np.linalg.norm(r)
        z2 = (r[2] / rn) ** 2
        k = 1.5 * J2_EARTH * MU_EARTH * R_EARTH**2 / rn**5
        a = -MU_EARTH * r / rn**3 + k * np.array([r[0] * (5 * z2 - 1), r[1] * (5 * z2 - 1), r[2] * (5 * z2 - 3)])
        return np.concatenate([y[3:], a])

    sol = solve_ivp(rhs, (0.0, t[-1]), tle_orbit([L1, L2]).state_eci, method="DOP853", rtol=1e-12, atol=1e-9)
    assert np.linalg.norm(sol.y[:3, -1] - target[-1, :3]) < 1e-3
    for k in (0, len(t) // 2, len(t) - 1):
        rel = eci_to_hill(target[k], chaser[k])
        assert np.linalg.norm(rel[:3] - result.x_true[k, :3]) < 1e-5


def test_oem_round_trip(tmp_path):
    """write -> read: epochs to 1 ns, states to the printed 1 um / 1 nm/s; a repeated time (an impulse)
    starts a second segment that the oem package accepts (segments may touch)."""
    from oem import OrbitEphemerisMessage

    rng = np.random.default_rng(3)
    epoch = "2024-02-29T23:59:59.999999Z"  # day and leap-year boundary
    t = np.array([0.0, 0.1234567891, 60.0, 60.0, 3600.5])
    states = rng.normal(0, 7e6, (5, 6))
    from proxops.analysis.export import _segments

    segs = [OemSegment("X", "X", utc_epochs(epoch, t)[s], states[s]) for s in _segments(t)]
    assert len(segs) == 2
    path = tmp_path / "x.oem"
    path.write_text(format_oem(segs))
    back = read_oem(path)
    assert [len(s.epochs) for s in back] == [3, 2]
    got_t = np.array([seconds_between(epoch, e) for s in back for e in s.epochs])
    assert np.allclose(got_t, t, rtol=0, atol=1e-9)
    assert back[1].epochs[0] == "2024-03-01T00:00:59.999999000"
    got = np.concatenate([s.states for s in back])
    assert np.max(np.abs(got[:, :3] - states[:, :3])) <= 0.5e-6 + 1e-9
    assert np.max(np.abs(got[:, 3:] - states[:, 3:])) <= 0.5e-9 + 1e-12
    assert len(list(OrbitEphemerisMessage.open(str(path)).states)) == 5


def test_mat_holds_the_series_and_summary(run_files):
    from scipy.io import loadmat

    d, summary, result = run_files
    m = loadmat(d / "sk.mat", simplify_cells=True)
    assert np.array_equal(m["run"]["x_true"], result.x_true)
    assert np.array_equal(m["run"]["t_s"], result.t)
    assert m["summary"]["total_dv_mps"] == pytest.approx(summary["total_dv_mps"], rel=0, abs=0)
    assert m["run"]["target_eci"].shape == (len(result.t), 6)


def test_export_of_a_saved_run_equals_the_run_export(run_files, tmp_path):
    d, _, _ = run_files
    res = invoke("export", d / "run", "--oem", tmp_path / "e.oem", "--json")
    assert res.exit_code == 0, res.stderr
    strip = lambda p: [ln for ln in p.read_text().splitlines() if not ln.startswith("CREATION_DATE")]  # noqa: E731
    assert strip(tmp_path / "e-hill.oem") == strip(d / "sk-hill.oem")
    assert strip(tmp_path / "e-target.oem") == strip(d / "sk-target.oem")


def test_export_errors(run_files, tmp_path):
    d, _, _ = run_files
    one_line_error(invoke("export", d / "run"), "give --oem FILE and/or --mat FILE")
    one_line_error(invoke("export", tmp_path, "--oem", tmp_path / "x.oem"), "no scenario.json")
    one_line_error(invoke("export", d / "run", "--oem", tmp_path), "is a folder")
    one_line_error(invoke("run", "underactuated-case1", "--oem", tmp_path / "u.oem"), "has no [orbit] and [truth]")


def test_campaign_run_export(tmp_path):
    """One run of a campaign (series not kept) is repeated from the manifest and exported; its Hill
    OEM holds the repeated run's recorded states."""
    from proxops.analysis.campaign import run_campaign

    out = tmp_path / "mc"
    run_campaign("station-keeping", n_runs=2, workers=1, out=out, overrides=[TLE_SET, "sim.duration_s=60"],
                 progress=False)
    one_line_error(invoke("export", out, "--oem", tmp_path / "c.oem"), "choose one with --run N")
    one_line_error(invoke("export", out, "--run", "7", "--oem", tmp_path / "c.oem"), "--run 7: no such run")
    res = invoke("export", out, "--run", "1", "--oem", tmp_path / "c.oem", "--json")
    assert res.exit_code == 0, res.stderr
    hill = read_oem(tmp_path / "c-hill.oem")[0]
    from proxops.analysis.campaign import rerun

    from proxops.analysis.storage import read_rows

    _, result = rerun(read_rows(out).iloc[1].to_dict(), out)
    assert np.max(np.abs(hill.states[:, :3] - result.x_true[:, :3])) < 1e-5


# ---------------------------------------------------------------------------- OPM
OPM = """CCSDS_OPM_VERS = 2.0
COMMENT the ISS TLE state at its epoch, in TEME
CREATION_DATE = 2026-11-27T00:00:00
ORIGINATOR = TEST
META_START
OBJECT_NAME = ISS
OBJECT_ID = 1998-067A
CENTER_NAME = EARTH
REF_FRAME = {frame}
TIME_SYSTEM = {scale}
META_STOP
EPOCH = {epoch}
X = {x[0]:.9f} [km]
Y = {x[1]:.9f} [km]
Z = {x[2]:.9f}
X_DOT = {x[3]:.12f} [km/s]
Y_DOT = {x[4]:.12f}
Z_DOT = {x[5]:.12f}
"""


def _opm(tmp_path, frame="TEME", scale="UTC", epoch="2008-09-20T12:25:40.104192", drop=()):
    from proxops.orbitdata.tle import tle_orbit

    o = tle_orbit([L1, L2])
    text = OPM.format(frame=frame, scale=scale, epoch=epoch, x=(o.state_teme if frame == "TEME" else o.state_eci) / 1e3)
    text = "\n".join(ln for ln in text.splitlines() if ln.split(" =")[0] not in drop)
    p = tmp_path / f"t-{frame}-{scale}-{len(drop)}.opm"
    p.write_text(text)
    return p, o


@pytest.mark.parametrize("frame", ["TEME", "EME2000"])
def test_opm_target_equals_the_tle_target(tmp_path, frame):
    """The TLE's state written as an OPM (in TEME, or already in EME2000) gives the same scenario orbit."""
    from proxops.scenarios.loader import load_scenario

    p, o = _opm(tmp_path, frame)
    sc = load_scenario("station-keeping", [f"orbit.opm_file={p}"]).scenario
    ref = load_scenario("station-keeping", [TLE_SET]).scenario
    assert sc.orbit.epoch_utc == ref.orbit.epoch_utc
    from proxops.frames.elements import elements_to_eci
    from proxops.systems.common import target_elements

    x, x_ref = elements_to_eci(target_elements(sc.orbit)), elements_to_eci(target_elements(ref.orbit))
    assert np.max(np.abs(x[:3] - x_ref[:3])) < 1e-5 and np.max(np.abs(x[3:] - x_ref[3:])) < 1e-8  # printed: 1 um


def test_opm_time_systems(tmp_path):
    """TT = UTC + 33 s (TAI - UTC in 2008, IERS Bulletin C) + 32.184 s."""
    from proxops.scenarios.loader import load_scenario

    p, _ = _opm(tmp_path, "EME2000", "TT", epoch="2008-09-20T12:26:45.288192")
    assert load_scenario("station-keeping", [f"orbit.opm_file={p}"]).scenario.orbit.epoch_utc == \
        "2008-09-20T12:25:40.104192Z"


def test_opm_missing_keys_and_bad_values_are_one_line(tmp_path):
    p, _ = _opm(tmp_path, drop=("Y_DOT", "EPOCH"))
    one_line_error(invoke("validate", "station-keeping", "--set", f"orbit.opm_file={p}"), "orbit.opm_file",
                   "missing keys EPOCH, Y_DOT")
    p, _ = _opm(tmp_path, frame="ITRF2000")
    one_line_error(invoke("validate", "station-keeping", "--set", f"orbit.opm_file={p}"), "REF_FRAME = ITRF2000")
    p, _ = _opm(tmp_path, scale="UT1")
    one_line_error(invoke("validate", "station-keeping", "--set", f"orbit.opm_file={p}"), "TIME_SYSTEM = UT1")
    p, _ = _opm(tmp_path, epoch="1969-07-20T20:17:40")
    one_line_error(invoke("validate", "station-keeping", "--set", f"orbit.opm_file={p}"), "EPOCH",
                   "supported range")
    bad = tmp_path / "bad.opm"
    bad.write_text(_opm(tmp_path)[0].read_text().replace("[km/s]", "[m/s]"))
    one_line_error(invoke("validate", "station-keeping", "--set", f"orbit.opm_file={bad}"), "unit must be [km/s]")
    one_line_error(invoke("validate", "station-keeping", "--set", f"orbit.opm_file={tmp_path / 'none.opm'}"),
                   "no such OPM file")


@pytest.mark.slow
def test_acceptance_srf_vbar_from_the_iss_tle(tmp_path):
    """Issue 33's acceptance command: srf-vbar around the ISS TLE orbit, OEM read back by the oem package."""
    res = invoke("run", "srf-vbar", "--set", TLE_SET, "--oem", tmp_path / "vbar.oem", "--json")
    assert res.exit_code == 0, (res.stderr, res.exception)
    t, x, meta = _oem_package_states(tmp_path / "vbar.oem")
    own = read_oem(tmp_path / "vbar.oem")
    states = np.concatenate([s.states for s in own])
    assert np.max(np.abs(x - states)) < 1e-9 and meta["REF_FRAME"] == "EME2000"
    assert math.isclose(t[-1], json.loads(res.stdout)["sim_time_s"], abs_tol=1e-6)
