"""``info`` and ``stats``: commands that read scenes and describe them, and write nothing."""

from __future__ import annotations

import click

from ..stats import describe_file, stats_findings
from ..text import info_text, stats_markdown, stats_text, to_json
from ._base import (Failure, color_option, library_errors, main, notes, options, progress, quiet_option,
                    zstd_option)


@main.command()
@click.argument("paths", metavar="FILE...", nargs=-1, required=True, type=click.Path(dir_okay=False))
@options(
    click.option("--json", "as_json", is_flag=True,
                 help="Print the facts as JSON (keys in specs/json.md): one object per file, in a list when "
                      "there are several."),
    color_option(),
)
@library_errors
def info(paths, as_json, color):
    """Describe scene files: format, variant, count, texture, cameras, time range,
    bounds, non-finite values and what is ignored.

    \b
    Example:
      splatconv info scene.splatv
      splatconv info --json segments/*.splatv
    """
    facts = [describe_file(path, color=color) for path in paths]
    if as_json:
        click.echo(to_json(facts[0] if len(facts) == 1 else facts))
    else:
        click.echo("\n\n".join(info_text(f) for f in facts))


@main.command()
@click.argument("source", type=click.Path(dir_okay=False))
@click.argument("converted", required=False, type=click.Path(dir_okay=False))
@options(
    click.option("--json", "as_json", is_flag=True, help="Print the report as JSON (keys in specs/json.md)."),
    click.option("--markdown", is_flag=True, help="Print the report as Markdown tables."),
    zstd_option("the transport sizes"),
    color_option(),
    quiet_option(),
)
@library_errors
def stats(source, converted, as_json, markdown, zstd_level, color, quiet):
    """Report sizes, zstd transport size and what a conversion loses.

    With CONVERTED, compares it against SOURCE attribute by attribute. With SOURCE
    alone, reports what converting it to .splatv would give; a file the viewer
    loads as it is (.splatv) is reported as stored, with nothing compared.

    \b
    Example:
      splatconv stats scene.ply scene.splatv
      splatconv stats scene.ply --markdown
    """
    if as_json and markdown:
        raise Failure("--json and --markdown cannot be used together", 2)
    data = stats_findings(source, converted, zstd_level=zstd_level, color=color, progress=progress(quiet))
    notes(data["notes"])
    click.echo(to_json(data) if as_json else stats_markdown(data) if markdown else stats_text(data))
