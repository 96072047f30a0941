"""How the command line lays out its tables and lists for a person at a terminal (80 columns and up).

Rules: names a user types back (scene names, variants, metric keys) are never cut (``no_wrap``), free text
folds, long titles become a short title plus a caption, and a table too wide for the terminal is split
into several tables that share the row-name column. ``--json`` stays the interface for machines.
"""

from __future__ import annotations

import contextlib
import math
import os
from pathlib import Path
from typing import Mapping, Sequence

import typer
from rich import box
from rich.console import Console
from rich.measure import Measurement
from rich.progress import (BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn,
                           TimeRemainingColumn)
from rich.table import Table


def hide_flag_types() -> None:
    """Show no type beside flags in ``--help``.

    typer 0.29 prints ``<bool>`` beside every flag, which reads as if the flag took a value
    (``--overwrite <bool>``); a flag takes none, so its type column is left empty. Options with values
    keep their ``<path>``, ``<int>``... labels.
    """
    from typer.core import TyperOption

    original = TyperOption.display_type_rich
    if getattr(original, "_hides_flags", False):
        return

    def display_type_rich(self, ctx):
        return None if self.is_flag else original(self, ctx)

    display_type_rich._hides_flags = True
    TyperOption.display_type_rich = display_type_rich


def output_console() -> Console:
    """The console tables go to (stdout); its width follows ``$COLUMNS`` or the terminal like rich's."""
    return Console()


def fits(console: Console, table: Table) -> bool:
    """Whether ``table`` prints within the console's width without rich having to wrap or cut cells."""
    # Measured unbounded: rich clamps a measurement to the width it is given, which would always fit.
    return Measurement.get(console, console.options.update_width(10_000), table).maximum <= console.width


def format_value(value, digits: str = ".3g") -> str:
    """A metric value as text: ``nan`` for a missing or undefined value."""
    if value is None:
        return "nan"
    if isinstance(value, (int, float)):
        return f"{value:{digits}}"
    return str(value)


def metric_header(key: str, units: Mapping[str, str]) -> str:
    """Column header: the metric key (as ``--json`` names it), its unit below."""
    unit = units.get(key, "")
    return f"{key}\n{unit}" if unit else key


def split_metric_tables(console: Console, title: str, row_label: str, rows: Mapping[str, Mapping[str, object]],
                        keys: Sequence[str], units: Mapping[str, str], caption: str | None = None) -> list[Table]:
    """Tables of ``rows`` (row name -> metric -> value) with one column per metric of ``keys``.

    Metric columns are packed left to right into as few tables as fit the console's width, each table
    repeating the row-name column, so a wide terminal gets one table and 80 columns gets two or three.
    The first table carries ``title``; the last carries ``caption``.
    """
    def new_table(part: int) -> Table:
        table = Table(title=title if part == 0 else None, box=box.SIMPLE_HEAD, title_justify="left")
        table.add_column(row_label, no_wrap=True)
        return table

    def filled(table: Table, columns: Sequence[str]) -> Table:
        for key in columns:
            table.add_column(metric_header(key, units), justify="right", no_wrap=True)
        for name, values in rows.items():
            table.add_row(name, *(format_value(values.get(k)) for k in columns))
        return table

    groups: list[list[str]] = [[]]
    for key in keys:
        candidate = groups[-1] + [key]
        if groups[-1] and not fits(console, filled(new_table(len(groups) - 1), candidate)):
            groups.append([key])
        else:
            groups[-1] = candidate
    tables = [filled(new_table(i), group) for i, group in enumerate(groups)]
    if caption:
        tables[-1].caption = caption
        tables[-1].caption_justify = "left"
    return tables


def metric_list_table(title: str, values: Mapping[str, object], keys: Sequence[str], units: Mapping[str, str],
                      caption: str | None = None, digits: str = ".3f") -> Table:
    """One metric per row: ``metric``, ``value``, ``unit`` (the demo's and ``run --truth``'s table)."""
    table = Table(title=title, caption=caption, caption_justify="left")
    table.add_column("metric", no_wrap=True)
    table.add_column("value", justify="right", no_wrap=True)
    table.add_column("unit", overflow="fold")
    for key in keys:
        table.add_row(key, format_value(values.get(key), digits), units.get(key, ""))
    return table


def yes_no(value) -> str:
    """``True``/``False`` or one per shot (a per-shot setting) as ``yes``/``no`` text."""
    if isinstance(value, (list, tuple)):
        return ",".join("yes" if v else "no" for v in value)
    return "yes" if value else "no"


def file_lines(files: Mapping[str, str], out_dir: Path, indent: str = "  ") -> list[str]:
    """One line per output, its path relative to ``out_dir`` with its subfolder kept (``smpl/person_00.npz``),
    sorted so a folder's files stand together; paths outside ``out_dir`` stay as given."""
    def relative(path: str) -> str:
        try:
            text = Path(os.path.relpath(Path(path).resolve(), out_dir.resolve())).as_posix()
        except ValueError:  # another drive (Windows)
            return str(path)
        return str(path) if text.startswith("..") else text

    return [f"{indent}{rel}" for rel in sorted({relative(p) for p in files.values()})]

# Shared by the commands of cli.py and the areas' commands.py.
console = Console(stderr=True)
"""Progress, status and notes go to stderr, so --json on stdout stays clean."""

SMPL_OPTION = typer.Option(None, "--smpl-model", help="SMPL model file (.npz or .pkl); default: "
                           "$MULTITHUMBS_SMPL_MODEL, else the procedural SMPL-format body.")


def progress() -> Progress:
    """A transient progress bar on :data:`console`."""
    return Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                    TimeElapsedColumn(), TimeRemainingColumn(), console=console, transient=True)


@contextlib.contextmanager
def stage_bars(description: str):
    """One live display for a run: a spinner line for the whole, and a bar per label the stages report
    (:mod:`multithumbs.progress`; e.g. ``blazepose shot 2/4``), each removed when done."""
    from multithumbs.progress import add_listener, remove_listener

    if not console.is_terminal:  # logs and pipes get the result, not a display redrawn in place
        yield None
        return
    bars = Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), console=console, transient=True)
    tasks: dict[str, int] = {}
    bars.add_task(description, total=None)

    def listen(label: str, done: int, total: int) -> None:
        if label not in tasks:
            tasks[label] = bars.add_task(label, total=total or None)
        bars.update(tasks[label], completed=done)
        if total and done >= total:
            bars.remove_task(tasks[label])

    add_listener(listen)
    try:
        with bars:
            yield bars
    finally:
        remove_listener(listen)


def jsonable(value):
    """Nested results made JSON-safe: numpy values to lists and numbers, non-finite floats to null."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if hasattr(value, "tolist"):
        return jsonable(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
