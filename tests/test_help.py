"""--help of every command reads as plain text: bracketed words survive (no markup eats them),
option placeholders say what to give (DIR, KEY=VALUE, N, a unit), never a Python type."""

import re

import pytest
import typer
from typer.testing import CliRunner

from proxops.cli import app


def _paths(cmd, path=()):
    yield path
    for name, sub in getattr(cmd, "commands", {}).items():
        yield from _paths(sub, path + (name,))


PATHS = list(_paths(typer.main.get_command(app)))


@pytest.mark.parametrize("path", PATHS, ids=[" ".join(p) or "proxops" for p in PATHS])
def test_help_is_plain_and_placeholders_have_meaning(path):
    done = CliRunner().invoke(app, [*path, "--help"])
    assert done.exit_code == 0, done.output
    text = done.output
    assert not re.search(r"<(bool|str|int|float|list\[\w+\]|Path|tuple[^>]*)>", text), text
    assert "╭" not in text  # no rich panels: plain text in every terminal and log


def test_bracketed_words_survive_in_help():
    text = CliRunner().invoke(app, ["keys", "--help"]).output
    assert "[dispersions]" in text


def test_units_in_flag_names_and_the_old_names_still_work():
    text = CliRunner().invoke(app, ["reach", "map", "--help"]).output
    assert "--omega-deg-s" in text and "--a-max-mps2" in text and "DEG/S" in text and "M/S^2" in text
