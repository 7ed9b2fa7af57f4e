"""Writes docs/settings.md, the user guide's settings reference, from the settings table
(engine/core/settings.py).  tests/core/test_settings_doc.py checks that the committed file is
what this writes.

  python scripts/settings_doc.py            # rewrite docs/settings.md
  python scripts/settings_doc.py --check    # exit 1 when docs/settings.md is out of date
"""
from __future__ import annotations

import argparse
import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOC = os.path.join(REPO, "docs", "settings.md")
sys.path.insert(0, REPO)

from engine.core import settings as table  # noqa: E402  (standard library only: no numpy needed)


METAVARS = {table.INT: "N", table.FLOAT: "X", table.CHOICE: "NAME", table.CHOICES: "LIST"}


def value_text(s, value) -> str:
    if s.kind == table.BOOL:
        return "on" if value else "off"
    if s.kind == table.CHOICES:
        return ", ".join(value) or "none"
    if s.kind == table.FLOAT:
        return f"{value:g}"
    return str(value)


def default_text(s) -> str:
    """The default; and a new Blender file's where it differs (Cycles' default)."""
    text = value_text(s, s.default)
    if s.blender_default is not None:
        text += f" (new Blender files: {value_text(s, s.blender_default)})"
    return text


def limits_text(s) -> str:
    if s.kind == table.INT:
        return f"{s.limits[0]:,} to {s.limits[1]:,}"
    if s.kind == table.FLOAT:
        return f"{s.limits[0]:g} to {s.limits[1]:g}"
    if s.kind == table.CHOICE:
        return " \\| ".join(f"`{v}`" for v in s.values)
    if s.kind == table.CHOICES:
        return "comma-separated: " + ", ".join(f"`{v}`" for v in s.values)
    return "on \\| off"


def flag_text(s, front) -> str:
    if front not in s.fronts:
        return "—"
    if s.kind == table.BOOL:
        return f"`{s.flag}`"
    return f"`{s.flag} {s.metavar or METAVARS[s.kind]}`"


def blender_text(s) -> str:
    if table.BLENDER not in s.fronts:
        return s.panel or "—"
    text = f"{s.label} ({s.panel})"
    if s.off_toggle is not None:
        text += f"; a checkbox turns it on, from {s.off_toggle.on_min:g} (starts at {s.off_toggle.on_default:g})"
    return text


def markdown() -> str:
    lines = [
        "# Settings",
        "",
        "<!-- Written by scripts/settings_doc.py from engine/core/settings.py: edit the table, not this file. -->",
        "",
        "Every setting of a render, with its default and limits, its flag in both command lines and where",
        "Blender shows it (Render Properties, with the TNCG15 MC render engine).  One table in the code",
        "(engine/core/settings.py) makes all of them, so they agree; tests/core/test_settings_table.py",
        "checks that they do.",
        "",
        "* `python -m engine render|estimate`: an absent flag means the default.  Choices are written as listed.",
        "* `python -m mcrt_addon render FILE.blend`: an absent flag keeps the file's value; choices in any",
        "  letter case.  `python -m mcrt_addon estimate` takes `--noise-target` and a few of these (`--help`).",
        "* A switch (`--nested-dielectrics`, `--no-adaptive`) flips the setting from its default.",
        "* Presets (`--preset`, both command lines): `fair` (the default) gives the Light Paths rows",
        f"  ({', '.join(f'`{n}`' for n in table.LIGHT_PATH_SPEEDUPS)}) their defaults here: the",
        "  reference settings; `cycles` gives every row Cycles' default, shown as \"(new Blender files: ...)\",",
        "  which is what a new .blend file starts with in Blender.  `python -m mcrt_addon` also takes",
        "  `--preset file`: the file's own values.  A flag given wins over the preset.",
        "* Stats: how `--stats-json` lists the setting: *as set*, *as resolved* (what the render made of",
        "  it, e.g. `threads` 0 as the number of cores), or not at all.",
        "",
        "| Setting | Default | Limits / choices | `python -m engine` | `python -m mcrt_addon` | Blender | Stats |",
        "|---|---|---|---|---|---|---|",
    ]
    for s in table.SETTINGS:
        internal = " (internal)" if not s.fronts else ""
        lines.append(f"| `{s.name}`{internal} | {default_text(s)} | {limits_text(s)} | "
                     f"{flag_text(s, table.ENGINE_CLI)} | {flag_text(s, table.ADDON_CLI)} | {blender_text(s)} | "
                     f"{s.stats or '—'} |")
    lines += ["", "## What each setting does", ""]
    for s in table.SETTINGS:
        meaning = (s.description or s.help).rstrip(".")
        where = " (set by the tracer itself or by Python callers only)" if not s.fronts else ""
        text = f"**`{s.name}`**{where}: {meaning[0].upper() + meaning[1:]}."
        if s.flag and s.help.rstrip(".").lower() != meaning.lower():
            text += f"  `{s.flag}`: {s.help}."
        lines += [text, ""]
        for c in s.choices:
            if c.description:
                lines.append(f"* `{c.value}` ({c.label}): {c.description.rstrip('.')}.")
        if any(c.description for c in s.choices):
            lines.append("")
    lines += [
        "## Blender only",
        "",
        "* Sampling > Viewport > Max Samples (`viewport_samples`): samples per pixel the 3D viewport's",
        "  Rendered mode accumulates (it is the viewport's `samples`).",
        "* View Layer > Passes: Z, Denoising Data, Sample Count, Variance are the `passes` (mcrt_addon/passes.py).",
        "* Object Properties > TNCG15 MC > Implicit Sphere: per mesh, not a render setting.",
        "",
    ]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 when docs/settings.md is out of date")
    args = parser.parse_args(argv)
    text = markdown()
    if args.check:
        with open(DOC, encoding="utf-8") as fh:
            current = fh.read()
        if current != text:
            print(f"{DOC} is out of date: run python scripts/settings_doc.py", file=sys.stderr)
            return 1
        return 0
    with open(DOC, "w", encoding="utf-8") as fh:
        fh.write(text)
    print(f"wrote {DOC}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
