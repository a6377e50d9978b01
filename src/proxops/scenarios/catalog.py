"""The built-in scenario files and the reading of a scenario file, without validating it.

Imports nothing heavy (json, pathlib; tomllib when a file is read): ``proxops scenarios`` lists the
built-ins from their index without a TOML parser, the early pool start of ``proxops mc``
(:mod:`proxops.exec.prestart`) reads a scenario's system with it, and :mod:`proxops.scenarios.loader`
(pydantic) reads the files it validates through it.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from proxops.errors import ProxopsInputError

BUILTIN_DIR = Path(__file__).parent / "builtin"
INDEX = Path(__file__).with_name("builtin_index.json")  # builtin_heads() as JSON (python -m proxops.scenarios.catalog)
_TABLE_LINE = re.compile(r"^[ \t]*\[", re.MULTILINE)  # a line that may open a [table] or [[array]]


def builtin_names() -> list[str]:
    return sorted(p.stem for p in BUILTIN_DIR.glob("*.toml"))


def list_builtin() -> list[dict]:
    """``[{name, description, system}]`` of the built-in scenarios: :data:`INDEX`, the JSON of
    :func:`builtin_heads` (tests/test_catalog_top_level.py keeps them equal). ``proxops scenarios``
    then imports no TOML parser and parses no file: 8 % of its instructions (callgrind)."""
    return json.loads(INDEX.read_text(encoding="utf-8"))


def builtin_heads() -> list[dict]:
    """``[{name, description, system}]`` read from the built-in files (not validated here)."""
    out = []
    for path in sorted(BUILTIN_DIR.glob("*.toml")):
        data = read_top_level(path)
        out.append({"name": path.stem, "description": data.get("description", ""), "system": data.get("system", "")})
    return out


def resolve(name_or_path: str) -> Path:
    path = Path(name_or_path)
    if path.is_file():
        return path
    builtin = BUILTIN_DIR / f"{name_or_path}.toml"
    if builtin.is_file():
        return builtin
    raise ProxopsInputError(
        f"scenario {name_or_path!r}: no such file and no built-in scenario of that name "
        f"('proxops scenarios' lists the {len(builtin_names())} built-ins)"
    )


def read_top_level(path: Path) -> dict:
    """The top-level keys of a TOML file (name, description, system: what precedes its first table),
    parsing only that head: TOML puts every top-level key before the first table header. A cut that
    is not a real header (a line of a multi-line string or array starting with ``[``) leaves an
    unterminated value, a parse error, and then the whole file is parsed. ``proxops scenarios``: 4-5x
    less than parsing every built-in whole (measured under load: 15-19 ms against 62-81 ms)."""
    import tomllib  # local here and in _parse: `proxops scenarios` (the index) never parses TOML

    text = _read_text(path)
    head = _TABLE_LINE.search(text)
    if head is not None:
        try:
            return tomllib.loads(text[: head.start()])
        except tomllib.TOMLDecodeError:
            pass
    return _parse(path, text)


def read_toml(path: Path) -> dict:
    return _parse(path, _read_text(path))


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ProxopsInputError(f"{path}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset {exc.start}); "
                                "TOML files are UTF-8: save it as UTF-8") from None


def _parse(path: Path, text: str) -> dict:
    import tomllib

    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProxopsInputError(f"{path}: not valid TOML: {exc}") from None


if __name__ == "__main__":  # python -m proxops.scenarios.catalog > src/proxops/scenarios/builtin_index.json
    print(json.dumps(builtin_heads(), indent=1, ensure_ascii=False))
