"""Command-line arguments made from the settings table (engine/core/settings.py), for both command
lines: ``python -m engine`` (engine/cli/main.py) and ``python -m mcrt_addon`` (mcrt_addon/cli.py).

Each row with a flag becomes one argument: an INT a bounded integer, a FLOAT a bounded number, a
CHOICE a choice, CHOICES a comma-separated list, a BOOL a switch that flips the row's default
(``--nested-dielectrics``, ``--no-adaptive``).  Two ways to read them back (`setting_values`):
every setting (the tracer's command line, whose defaults are the table's), or only those given
(the add-on's, where a flag not given keeps the .blend file's value).  `--preset` (fair or
cycles, engine/core/settings.py PRESETS) gives the Light Paths rows' values that the flags not given take.
"""
from __future__ import annotations

import argparse

from ..core.errors import SceneError
from ..core.settings import BOOL, CHOICE, CHOICES, FAIR, FLOAT, INT, PRESETS


def _bounded(convert, noun: str, low, high, limits: str, shown):
    """An argparse type: a value that `convert` reads, from low to high (one-line error otherwise);
    `limits` is the range as the message shows it, shown(text, value) the value given."""
    def parse(text):
        try:
            value = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not {noun}: {text!r}") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"must be from {limits}, got {shown(text, value)}")
        return value
    return parse


def bounded_int(low: int, high: int):
    """An argparse type: an integer from low to high."""
    return _bounded(int, "an integer", low, high, f"{low} to {high:,}", lambda text, value: value)


def bounded_float(low: float, high: float):
    """An argparse type: a number from low to high."""
    return _bounded(float, "a number", low, high, f"{low:g} to {high:g}", lambda text, value: text)


def choice_list(setting):
    """An argparse type: a comma-separated list of the setting's choices (one-line error otherwise)."""
    def parse(text):
        try:
            return setting.parse_choices(text)
        except SceneError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    return parse


def add_preset_argument(parser, extra=(), default: str = FAIR, note: str = "") -> None:
    """--preset: the values of the Light Paths rows (clamps, Filter Glossy, caustics, bounce limits)
    that a flag not given takes; `extra` choices besides PRESETS (the add-on's "file")."""
    parser.add_argument("--preset", choices=PRESETS + tuple(extra), default=default, type=str.lower,
                        help="fair: the reference settings (no clamp, no filter, caustics on, only the total "
                        "limits bounces); cycles: Cycles' defaults (Max Bounces 12, Diffuse 4, Glossy 4, "
                        f"Clamp Indirect 10, Filter Glossy 1, Blackman-Harris 1.5 px, ...){note}; default {default}")


def add_setting_arguments(parser, settings, table_defaults: bool = True, any_case: bool = False,
                          note=lambda setting: "") -> None:
    """One argument per row of `settings` that has a flag.  table_defaults: an absent flag means
    the table's default (else None: 'not given'); rows with a Cycles default are always None
    when absent, so that --preset can fill them (setting_values).  any_case: choices in any letter
    case (the add-on's command line).  note(setting): text appended to the help."""
    for s in settings:
        if s.flag is None:
            continue
        help_text = s.help + note(s)
        if s.kind == BOOL:
            parser.add_argument(s.flag, action="store_true", help=help_text)
            continue
        default = s.default if (table_defaults and s.blender_default is None) or s.kind == CHOICES else None
        options = dict(default=default, help=help_text)
        if s.metavar:
            options["metavar"] = s.metavar
        if s.kind == INT:
            options["type"] = bounded_int(*s.limits)
        elif s.kind == FLOAT:
            options["type"] = bounded_float(*s.limits)
        elif s.kind == CHOICE:
            options["choices"] = s.values
            if any_case:
                options["type"] = str.lower
        elif s.kind == CHOICES:
            options["type"] = choice_list(s)
        parser.add_argument(s.flag, **options)


def setting_values(args, settings, given_only: bool = False, preset=None) -> dict:
    """{setting name: value} from parsed arguments: every setting of `settings` that has a flag, or
    with given_only only those whose flag was on the command line (add_setting_arguments with
    table_defaults=False).  A row whose flag this parser lacks counts as not given.  preset: {name:
    value} (engine/core/settings.py preset_values) that a flag not given takes before the table's default."""
    values = {}
    preset = preset or {}
    for s in settings:
        if s.flag is None:
            continue
        value = getattr(args, s.dest, None)
        if s.kind == BOOL:
            if value:
                values[s.name] = not s.default
            elif not given_only:
                values[s.name] = preset.get(s.name, s.default)
        elif value is not None and not (given_only and s.kind == CHOICES and not value):
            values[s.name] = value
        elif not given_only:
            values[s.name] = preset.get(s.name, s.default)
    return values
