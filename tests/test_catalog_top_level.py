"""``proxops scenarios`` reads only the head of each built-in (what precedes its first table,
:func:`proxops.scenarios.catalog.read_top_level`): the result must be the top-level keys of the whole
file as tomllib parses it, for every built-in and for the files where a line starting with ``[`` is
not a table header (inside a multi-line string or a multi-line array)."""

from __future__ import annotations

import tomllib

import pytest

from proxops.errors import ProxopsInputError
from proxops.scenarios.catalog import BUILTIN_DIR, builtin_heads, list_builtin, read_top_level


def _top_level(data: dict) -> dict:
    """The keys the catalogue reads (a [table] or [[array]] defines the others)."""
    return {k: data.get(k) for k in ("name", "description", "system", "grid")}


def test_every_builtin_head_is_the_whole_files_top_level():
    paths = sorted(BUILTIN_DIR.glob("*.toml"))
    assert len(paths) >= 30
    for path in paths:
        whole = tomllib.loads(path.read_text(encoding="utf-8"))
        assert _top_level(read_top_level(path)) == _top_level(whole), path.name
    assert [i["name"] for i in builtin_heads()] == [p.stem for p in paths]
    assert all(i["system"] and i["description"] for i in builtin_heads())


def test_the_index_proxops_scenarios_lists_is_every_builtin_files_head():
    """``list_builtin`` reads builtin_index.json: it must be what the files say now, each one parsed whole
    (a built-in added, removed or re-described without regenerating the index fails here)."""
    whole = [{"name": p.stem, **{k: tomllib.loads(p.read_text(encoding="utf-8")).get(k, "") for k in ("description", "system")}}
             for p in sorted(BUILTIN_DIR.glob("*.toml"))]
    assert list_builtin() == whole, (
        "regenerate: python -m proxops.scenarios.catalog > src/proxops/scenarios/builtin_index.json")


@pytest.mark.parametrize("text", [
    'name = "a"\ndescription = """two lines,\n[the second looks like a table]"""\nsystem = "srf"\n[sim]\nduration_s = 1.0\n',
    "name = 'a'\ndescription = '''x\n  [[y]]\n'''\nsystem = 'los'\n[[z]]\nq = 1\n",
    'name = "a"\ngrid = [\n  [1, 2],\n  [3, 4],\n]\nsystem = "cortex"\n[sim]\nduration_s = 1.0\n',
    'name = "a"\nsystem = "srf"\n',  # no table at all
    '[sim]\nduration_s = 1.0\n',  # no top-level key
    '  [sim]\nname = "in the table"\n',  # an indented header
])
def test_a_line_starting_with_a_bracket_that_is_no_header(tmp_path, text):
    path = tmp_path / "s.toml"
    path.write_text(text, encoding="utf-8")
    assert _top_level(read_top_level(path)) == _top_level(tomllib.loads(text))


def test_a_broken_file_is_one_input_error(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('name = "a\n[sim]\n', encoding="utf-8")  # unterminated string in the head itself
    with pytest.raises(ProxopsInputError, match="not valid TOML"):
        read_top_level(path)
