import matplotlib

matplotlib.use("Agg")


def one_line_error(res, *fragments):
    """A CLI result that is one bad-input line: exit 2, one ``error:`` line naming each fragment."""
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.exit_code == 2, (res.exit_code, res.stderr, res.exception)
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in res.stderr, res.stderr
    for f in fragments:
        assert f in lines[0], (f, lines[0])
