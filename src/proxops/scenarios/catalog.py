"""The built-in scenario files and the reading of a scenario file, without validating it.

Imports nothing heavy (tomllib, pathlib): ``proxops scenarios`` lists the built-ins with it, the
early pool start of ``proxops mc`` (:mod:`proxops.exec.prestart`) reads a scenario's system with it,
and :mod:`proxops.scenarios.loader` (pydantic) reads the files it validates through it.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from proxops.errors import ProxopsInputError

BUILTIN_DIR = Path(__file__).parent / "builtin"


def builtin_names() -> list[str]:
    return sorted(p.stem for p in BUILTIN_DIR.glob("*.toml"))


def list_builtin() -> list[dict]:
    """``[{name, description, system}]`` of the built-in scenarios (files are not validated here)."""
    out = []
    for path in sorted(BUILTIN_DIR.glob("*.toml")):
        data = read_toml(path)
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


def read_toml(path: Path) -> dict:
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise ProxopsInputError(f"{path}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset {exc.start}); "
                                "TOML files are UTF-8: save it as UTF-8") from None
    except tomllib.TOMLDecodeError as exc:
        raise ProxopsInputError(f"{path}: not valid TOML: {exc}") from None
