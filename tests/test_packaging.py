"""proxops as a library: the wheel that `uv build` makes installs into a clean virtual
environment and works there, away from the source tree (built-in scenarios and the EGM96
coefficients are package data, not files of the checkout).

Slow (a wheel build, a venv and the first compilation of the kernels in a fresh numba
cache): `make test-slow`, which CI runs. The dependencies are installed at the versions of
uv.lock (exported as constraints), from uv's cache where `make test` already put them.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BUILTINS = sorted(p.stem for p in (ROOT / "src/proxops/scenarios/builtin").glob("*.toml"))


def _uv() -> str:
    found = shutil.which("uv") or str(ROOT / ".tools/bin/uv")
    if not Path(found).exists():
        pytest.fail("uv not found: run the tests through `make test-slow` (it installs uv into .tools/)")
    return found


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    subprocess.run([_uv(), "build", "--wheel", "--out-dir", str(out), str(ROOT)], check=True,
                   capture_output=True, text=True)
    (whl,) = out.glob("proxops-*.whl")
    return whl


@pytest.mark.slow
def test_wheel_carries_the_package_data_and_the_license(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    for stem in BUILTINS:
        assert f"proxops/scenarios/builtin/{stem}.toml" in names
    assert "proxops/environment/data/egm96_120.npz" in names
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    assert not any(n.startswith(("tests/", "benchmarks/")) for n in names)


@pytest.mark.slow
def test_wheel_installs_into_a_clean_venv_and_runs(wheel, tmp_path):
    uv = _uv()
    venv = tmp_path / "venv"
    subprocess.run([uv, "venv", "--python", sys.executable, str(venv)], check=True, capture_output=True)
    pins = subprocess.run([uv, "export", "--frozen", "--no-hashes", "--no-emit-project", "--format",
                           "requirements-txt", "--project", str(ROOT)],
                          check=True, capture_output=True, text=True).stdout
    constraints = tmp_path / "constraints.txt"
    constraints.write_text(pins)
    subprocess.run([uv, "pip", "install", "--python", str(venv / "bin/python"), "-c", str(constraints), str(wheel)],
                   check=True, capture_output=True, text=True)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PROXOPS_NUMBA_CACHE"] = str(tmp_path / "numba")
    proxops = str(venv / "bin/proxops")

    def run(*args) -> dict:
        done = subprocess.run([proxops, *args, "--json"], cwd=tmp_path, env=env, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        return json.loads(done.stdout)

    where = subprocess.run([str(venv / "bin/python"), "-c", "import proxops; print(proxops.__file__)"],
                           cwd=tmp_path, env=env, capture_output=True, text=True, check=True).stdout
    assert str(venv) in where and str(ROOT) not in where  # the installed copy, not the checkout

    assert sorted(s["name"] for s in run("scenarios")) == BUILTINS
    # the full truth reads the shipped EGM96 coefficients (degree 20 here)
    drift = run("propagate", "--scenario", "station-keeping", "--duration-s", "600", "--model", "full",
                "--set", "truth.gravity_degree=20", "--set", "truth.gravity_order=20")
    assert drift["label"].startswith("20x20")  # the harmonics were read from the installed package data
    assert drift["final_hill"] != drift["cw_final_hill"]
