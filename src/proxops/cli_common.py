"""Helpers every ``proxops`` command shares: one top-level error policy and JSON output.

The error policy lives in one place, :class:`ProxopsGroup` (the click group behind the
``proxops`` typer app), so no command needs its own try/except:

- bad input (:class:`~proxops.errors.ProxopsInputError`, a wrong option type or value, an
  unknown option, a path that cannot be written): one line ``error: ...`` on stderr, exit 2;
- Ctrl-C (or SIGTERM) at any moment: one line ``interrupted...`` on stderr, exit 130;
- a failure that is not the user's (any other exception): one line ``error: internal ...``
  naming ``--debug``, exit 1. ``--debug`` shows the traceback instead.

Exit codes: 0 ok, 1 internal error or a campaign that could not go on, 2 bad input,
3 a campaign that finished but every run failed, 4 a single run (``proxops run``) that finished but
failed, 130 interrupted.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from typer import _click as click  # typer vendors its own click: its exceptions are these
from typer._click.utils import make_default_short_help
import typer
from typer.core import TyperGroup

from proxops.jsonable import json_default  # noqa: F401 (one home; re-exported for the CLI modules)
from proxops.errors import ProxopsInputError


def _plain_values_without_pydantic() -> None:
    """typer (0.29) coerces each parameter's value through a pydantic ``TypeAdapter`` built on first
    use, so any command imported pydantic (0.1 s idle, most of ``proxops scenarios``; measured with
    ``python -X importtime``) even when click had already parsed every value: a ``str`` of a ``str``
    parameter, a ``bool`` of a flag, None for one not given. Those values come back unchanged from
    the adapter (typer's ``_parse_cli_str``/``_parse_cli_bool``), so they are returned as they are;
    anything else (numbers, paths, choices, a parser, a value of another type) still goes through
    the adapter typer builds. Without these typer internals (another typer) nothing changes."""
    try:
        from typer import core as typer_core
        from typer._coercion import RuntimeParam
    except ImportError:  # pragma: no cover - another typer: its own coercion, unchanged
        return
    build = getattr(typer_core, "build_runtime_param", None)
    if build is None or getattr(build, "_proxops", False):
        return

    class PlainValue(RuntimeParam):
        def _coerce_value(self, value, param, ctx):
            if type(value) is self.annotation:
                return value
            return build(param.type_descriptor)._coerce_value(value, param=param, ctx=ctx)

    def build_runtime_param(descriptor):
        info = descriptor.parameter_info
        if (descriptor.annotation in (str, bool) and descriptor.file_annotation is None
                and getattr(info, "parser", None) is None and getattr(info, "click_type", None) is None):
            return PlainValue(parameter_info=info, annotation=descriptor.annotation)
        return build(descriptor)

    build_runtime_param._proxops = True
    typer_core.build_runtime_param = build_runtime_param


_plain_values_without_pydantic()

STATE = {"debug": False, "quiet": False}  # set by the top-level --debug and --quiet options

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT, EXIT_ALL_FAILED, EXIT_RUN_FAILED, EXIT_INTERRUPTED = 0, 1, 2, 3, 4, 130
EXIT_CODES_HELP = ("Exit codes: 0 ok; 1 internal error (please report it) or a campaign that could not go on; "
                   "2 bad input; 3 a campaign that finished but every run failed; 4 a run that finished but "
                   "failed; 130 interrupted.")


class Interrupted(KeyboardInterrupt):
    """Ctrl-C with a message for the user (e.g. how many campaign runs were saved)."""


class _CarriedInterrupt(Exception):
    """Carries a KeyboardInterrupt past typer's handler (which would exit 130 in silence)."""

    def __init__(self, interrupt: KeyboardInterrupt):
        super().__init__(str(interrupt))
        self.interrupt = interrupt


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


class ProxopsGroup(TyperGroup):
    """Typer's group with the proxops error policy (see the module docstring)."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        name_metavars(self)

        def call():
            rv = super(ProxopsGroup, self).main(args, prog_name, complete_var, standalone_mode=False, **extra)
            if isinstance(rv, int) and not isinstance(rv, bool) and rv == EXIT_INTERRUPTED:
                # typer turns a Ctrl-C outside ``invoke`` (parsing the command line, closing the context)
                # into a silent exit code 130: 5 of 10 Ctrl-Cs 3-5 s into `proxops mc` printed nothing
                raise KeyboardInterrupt
            return rv

        code = guarded(call)
        if standalone_mode:
            sys.exit(code)
        return code

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt as exc:
            raise _CarriedInterrupt(exc) from None


def make_app(name: str, help: str, cls=ProxopsGroup, **extra) -> typer.Typer:
    """A typer app (or command group) with the proxops settings: the error policy of :class:`ProxopsGroup`,
    plain-text help ([dispersions] is a word, not a style tag), no completion, no pretty tracebacks."""
    return typer.Typer(name=name, cls=cls, help=help, no_args_is_help=True, add_completion=False,
                       pretty_exceptions_enable=False, rich_markup_mode=None, **extra)


class LazyCommand:
    """A command whose module is imported only when the command is run or shows its own ``--help``:
    ``attribute`` of ``module`` is a command function (``kind="command"``) or a typer app
    (``kind="group"``); ``short_help`` is what ``proxops --help`` lists without importing it (a test
    checks it against the command's own help)."""

    def __init__(self, module: str, attribute: str, kind: str, short_help: str):
        self.module, self.attribute, self.kind, self.short_help = module, attribute, kind, short_help

    def load(self, name: str):
        """The click command, or None when the module is not installed (an optional command)."""
        import importlib

        try:
            obj = getattr(importlib.import_module(self.module), self.attribute)
        except ModuleNotFoundError as exc:
            if exc.name == self.module:
                return None
            raise
        if self.kind == "group":
            cmd = typer.main.get_command(obj)
        else:
            single = typer.Typer(add_completion=False, pretty_exceptions_enable=False, rich_markup_mode=None)
            single.command(name=name)(obj)
            cmd = typer.main.get_command(single)
        cmd.name = name
        name_metavars(cmd)
        return cmd


class LazyCommandGroup(ProxopsGroup):
    """The root group: the commands in ``lazy`` (name -> :class:`LazyCommand`) are listed by
    ``--help`` from their short help and imported only when used, so ``proxops --help`` imports no
    command module and ``proxops keys`` only ``cli_keys``."""

    lazy: dict[str, LazyCommand] = {}

    def list_commands(self, ctx) -> list[str]:
        return [*super().list_commands(ctx), *(n for n in self.lazy if n not in self.commands)]

    def get_command(self, ctx, cmd_name: str):
        cmd = super().get_command(ctx, cmd_name)
        if cmd is None and cmd_name in self.lazy:
            cmd = self.lazy[cmd_name].load(cmd_name)
            if cmd is not None:
                self.add_command(cmd, cmd_name)
        return cmd

    def format_commands(self, ctx, formatter) -> None:
        """As click's, with a command not yet imported listed from its table entry (the same shortening)."""
        names = [n for n in self.list_commands(ctx) if not getattr(self.commands.get(n), "hidden", False)]
        if not names:
            return
        limit = formatter.width - 6 - max(len(n) for n in names)
        rows = [(n, self.commands[n].get_short_help_str(limit) if n in self.commands
                 else make_default_short_help(self.lazy[n].short_help, limit)) for n in names]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


# option value placeholders in --help, by meaning (typer would print the Python type: <float>)
_METAVAR_BY_NAME = {"out": "DIR", "report_dir": "DIR", "set_": "KEY=VALUE", "overrides": "KEY=VALUE",
                    "seed": "SEED", "runs": "N", "n": "N", "workers": "N", "scheduler": "ADDRESS",
                    "scenario": "SCENARIO", "system": "SYSTEM", "folder": "DIR", "axis": "X Y Z",
                    "omega_deg": "DEG/S", "amax": "M/S^2"}
_METAVAR_BY_SUFFIX = (("_deg_s", "DEG/S"), ("_mps2", "M/S^2"), ("_mps", "M/S"), ("_deg", "DEG"), ("_km", "KM"),
                      ("_m", "M"), ("_s", "S"), ("_n", "N"), ("_kg", "KG"))


def _metavar(param) -> str | None:
    """A placeholder that says what to give: DIR, KEY=VALUE, N, or the unit of a ``*_m`` option."""
    if getattr(param, "is_flag", False) or getattr(param, "count", False):
        return ""
    name = (param.name or "").lower()
    if name in _METAVAR_BY_NAME:
        return _METAVAR_BY_NAME[name]
    for suffix, text in _METAVAR_BY_SUFFIX:
        if name.endswith(suffix):
            return text
    bare = getattr(param, "bare_type", None)  # typer's parameters: the annotation's type name
    kind = bare() if callable(bare) else getattr(getattr(param, "type", None), "name", "")
    return {"int": "N", "integer": "N", "float": "NUMBER", "Path": "PATH", "path": "PATH", "bool": "",
            "boolean": ""}.get(kind, name.upper() or "VALUE")


def name_metavars(command) -> None:
    """Give every option and argument of ``command`` and its subcommands a metavar by meaning
    (:func:`_metavar`) where none was set; idempotent."""
    for param in getattr(command, "params", []):
        if getattr(param, "param_type_name", "") == "argument":  # typer adds "<str>" after an argument's name
            param.display_type_rich = lambda ctx=None: ""
        elif param.metavar is None and (param.name or "") not in ("help", "version"):
            param.metavar = _metavar(param)
    for sub in getattr(command, "commands", {}).values():
        name_metavars(sub)


def configure_logging(verbose: bool = False, quiet: bool = False) -> None:
    """Stage lines on stderr through :mod:`logging` (logger ``proxops``): by default one line per
    finished stage when stderr is not a terminal (a log file sees progress), none on a terminal
    (which has the progress bars); ``--verbose`` adds the detail (also the start of each stage),
    ``--quiet`` leaves only errors and turns the progress bars off. A failing command prints only
    its one error line: no stage line is logged before the inputs are checked."""
    import logging

    STATE["quiet"] = quiet
    level = logging.DEBUG if verbose else logging.ERROR if quiet else \
        logging.INFO if not sys.stderr.isatty() else logging.WARNING
    logger = logging.getLogger("proxops")
    logger.setLevel(level)
    handler = next((h for h in logger.handlers if getattr(h, "_proxops", False)), None)
    if handler is None:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("proxops: %(message)s"))
        handler._proxops = True
        logger.addHandler(handler)
        logger.propagate = False
    handler.stream = sys.stderr  # this invocation's stderr (a test runner swaps it; setStream would flush the old one)


def guarded(call) -> int:
    """Run ``call()`` under the error policy; returns the exit code."""
    try:
        rv = call()
        return rv if isinstance(rv, int) and not isinstance(rv, bool) else EXIT_OK
    except typer.Exit as exc:
        return exc.exit_code
    except _CarriedInterrupt as exc:
        message = str(exc.interrupt) if isinstance(exc.interrupt, Interrupted) else ""
        typer.echo(_one_line(message) or "interrupted", err=True)
        return EXIT_INTERRUPTED
    except Interrupted as exc:
        typer.echo(_one_line(str(exc)) or "interrupted", err=True)
        return EXIT_INTERRUPTED
    except (KeyboardInterrupt, typer.Abort):
        typer.echo("interrupted", err=True)
        return EXIT_INTERRUPTED
    except click.exceptions.NoArgsIsHelpError as exc:
        exc.show()
        return EXIT_INPUT
    except click.exceptions.UsageError as exc:
        if STATE["debug"]:
            raise
        where = f" (see `{exc.ctx.command_path} --help`)" if exc.ctx is not None else ""
        typer.echo(f"error: {_one_line(exc.format_message())}{where}", err=True)
        return EXIT_INPUT
    except ProxopsInputError as exc:
        if STATE["debug"]:
            raise
        typer.echo(f"error: {_one_line(str(exc))}", err=True)
        return EXIT_INPUT
    except OSError as exc:  # a path the user gave that cannot be read or written
        if STATE["debug"]:
            raise
        if getattr(exc, "filename", None) is None:
            return _internal(exc)
        typer.echo(f"error: {exc.filename}: {exc.strerror or type(exc).__name__}", err=True)
        return EXIT_INPUT
    except Exception as exc:  # not the user's fault: say so in one line
        if STATE["debug"]:
            raise
        return _internal(exc)


def _internal(exc: BaseException) -> int:
    typer.echo(f"error: internal error {type(exc).__name__}: {_one_line(str(exc))[:300]} "
               "(run again with `proxops --debug ...` for the traceback, and please report it)", err=True)
    return EXIT_INTERNAL


def friendly_errors(func):
    """Kept for commands written against the earlier API: the policy is in :class:`ProxopsGroup`."""
    return func


CAMPAIGN_MARKERS = ("campaign.json", "runs")  # a folder holding either is a campaign's (analysis.storage)


def check_out_dir(path, option: str = "--out", campaign: bool = False) -> Path:
    """Check an output folder the user named, before any work: the one check of every command that
    writes (one ``error:`` line naming ``option``, exit code 2).

    - a file, a folder that cannot be created (under a file, a read-only file system) or written
      (a real write: permissions and quotas show here) is refused;
    - ``campaign=False`` (one result: ``run``, ``demo``, ``cortex reference``, ``reach table``, ...):
      the folder is created, and a campaign's folder is refused (the result's summary.json and
      figures would overwrite the campaign's);
    - ``campaign=True`` (``mc``, ``cortex references``, ``reach mc``): nothing is left behind (a
      folder created for the check is removed); the campaign checks its manifest itself.
    """
    import tempfile

    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ProxopsInputError(f"{option} {path}: exists and is a file; give a folder (it is created if missing)")
    if not campaign and path.is_dir():
        held = [name for name in CAMPAIGN_MARKERS if (path / name).exists()]
        if held:
            raise ProxopsInputError(
                f"{option} {path}: is a campaign folder (holds {' and '.join(held)}); writing one result there "
                f"would overwrite the campaign's files: give another folder (`proxops report {path}` redraws a "
                "campaign's report)")
    created = []  # folders this check creates, outermost first
    probe = path
    while not probe.exists() and probe != probe.parent:
        created.insert(0, probe)
        probe = probe.parent
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ProxopsInputError(f"{option} {path}: cannot create the folder ({exc.strerror or exc})") from None
    try:  # a real write: permissions, read-only file systems and quotas all show here
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as exc:
        raise ProxopsInputError(f"{option} {path}: cannot write there ({exc.strerror or exc}); "
                                "choose another folder") from None
    finally:
        if campaign:
            for folder in reversed(created):
                try:
                    folder.rmdir()
                except OSError:
                    pass
    return path


def check_out_file(path: Path | None, option: str) -> None:
    """An output file: not a folder, its parent not a file (one-line error)."""
    if path is None:
        return
    if path.is_dir():
        raise ProxopsInputError(f"{option} {path}: is a folder; give a file name")
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise ProxopsInputError(f"{option} {path}: {parent} is a file, not a folder")
            break


def emit(obj: dict, as_json: bool, text: str) -> None:
    """Print ``obj`` as exactly one JSON object on stdout, or ``text`` for people."""
    if as_json:
        sys.stdout.write(json.dumps(obj, default=json_default) + "\n")
    else:
        typer.echo(text)
