"""MkDocs hooks: pages generated from the code at build time, so they cannot go stale.

- ``cli.md``: the command-line reference, from the typer app (every command, option, default).
- ``changelog.md``: CHANGELOG.md of the repository.
"""

from __future__ import annotations

from pathlib import Path

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parents[1]


def _cli_reference() -> str:
    import typer

    from proxops.cli import app

    from proxops.cli_common import name_metavars

    root = typer.main.get_command(app)
    name_metavars(root)  # the placeholders --help shows (DIR, KEY=VALUE, ...)
    lines = ["# Command line", "",
             "Generated from the command-line app at build time (`proxops COMMAND --help` prints the same).",
             "Every command prints a readable summary; `--json` prints exactly one JSON object on stdout.", ""]

    def walk(cmd, path: list[str], parent) -> None:  # typer's (vendored) click commands
        ctx = cmd.context_class(cmd, info_name=path[-1], parent=parent)
        if len(path) > 1:
            lines.extend([f"{'#' * min(len(path), 4)} `{' '.join(path)}`", ""])
            text = (cmd.help or "").strip()
            if text:
                lines.extend([text, ""])
            usage = cmd.collect_usage_pieces(ctx)
            lines.extend(["```text", " ".join(path + usage), "```", ""])
            params = [p for p in cmd.get_params(ctx) if p.get_help_record(ctx)]
            if params:
                lines.extend(["| option | help |", "| --- | --- |"])
                for p in params:
                    name, help_text = p.get_help_record(ctx)
                    cell = help_text.replace("|", "\\|").replace("\n", " ")
                    lines.append(f"| `{name}` | {cell} |")
                lines.append("")
        if hasattr(cmd, "list_commands"):
            for sub in cmd.list_commands(ctx):
                walk(cmd.get_command(ctx, sub), path + [sub], ctx)

    walk(root, ["proxops"], None)
    return "\n".join(lines) + "\n"


def on_files(files, config):
    files.append(File.generated(config, "cli.md", content=_cli_reference()))
    changelog = ROOT / "CHANGELOG.md"
    files.append(File.generated(config, "changelog.md", content=changelog.read_text()))
    return files


# Equation -> module map of each system page: the modules that implement the paper, with the
# first line of their docstring and every equation, algorithm, table and section they cite.
SYSTEM_MODULES = {
    "srf": ["guidance/hop_times.py", "control/srf_mpc.py", "constraints/keep_out.py", "constraints/passive_safety.py",
            "frames/lvlh.py", "systems/schema/srf.py", "systems/srf.py", "cli_srf.py", "plotting/srf.py"],
    "los": ["dynamics/tumbling_target.py", "constraints/los_corridor.py", "control/los_mpc.py",
            "control/los_regimes.py", "analysis/reach.py", "analysis/feasibility_maps.py",
            "analysis/los_boundary.py", "analysis/los_sweep.py", "systems/schema/los.py", "systems/los.py",
            "cli_reach.py"],
    "cortex": ["guidance/cortex/config.py", "guidance/cortex/reference.py", "guidance/cortex/phases.py",
               "guidance/cortex/holds.py", "guidance/cortex/timeline.py", "guidance/cortex/replanner.py",
               "control/cortex_supervisor.py", "control/cortex_triggers.py", "control/cortex_cpg.py",
               "control/cortex_insertion.py", "control/cortex_tracking.py", "control/relaxation.py",
               "constraints/approach_cone.py", "constraints/plume.py", "actuators/thrusters.py",
               "environment/eclipse.py", "navigation/ekf.py", "systems/schema/cortex.py", "systems/cortex.py",
               "systems/cortex_setup.py", "systems/cortex_loop.py"],
    "hybrid": ["dynamics/two_rigid_bodies.py", "dynamics/hybrid_relative.py", "propagation/hybrid_plant.py",
               "control/hybrid_mpc.py", "control/hybrid_supervisor.py", "systems/schema/hybrid.py",
               "systems/hybrid.py", "analysis/hybrid_model_check.py"],
    "underactuated": ["dynamics/planar_cubesat.py", "control/nmpc_underactuated.py", "systems/schema/underactuated.py",
                      "systems/underactuated.py"],
}
_CITE = r"(?:[Ee]qs?\. ?\(?\d+[a-z]?\)?|Algorithm \d+|Problem \d+|Table \d+|Fig(?:s)?\. ?\d+|§\d+(?:\.\d+)*)"


def module_map(system: str) -> str:
    import ast
    import re

    rows = ["| module | what it is | cites |", "| --- | --- | --- |"]
    for rel in SYSTEM_MODULES[system]:
        path = ROOT / "src" / "proxops" / rel
        if not path.exists():
            continue
        text = path.read_text()
        doc = (ast.get_docstring(ast.parse(text)) or "").strip().split("\n\n")[0].replace("\n", " ")
        cites = sorted(set(re.sub(r"\s+", " ", c) for c in re.findall(_CITE, text)),
                       key=lambda c: (c[0], [int(n) for n in re.findall(r"\d+", c)] or [0]))
        mod = "proxops." + rel[:-3].replace("/", ".")
        rows.append(f"| `{mod}` | {doc.replace('|', '/')} | {', '.join(cites).replace('|', '/')} |")
    return "\n".join(rows)


def on_page_markdown(markdown, page, config, files):
    import re

    return re.sub(r"<!-- module-map: (\w+) -->", lambda m: module_map(m.group(1)), markdown)
