"""The settings table (engine/core/settings.py) reaches every front end it declares, with the same
default, limits and choices: RenderSettings and validate(), `python -m engine`'s arguments,
`python -m mcrt_addon`'s arguments, the Blender PropertyGroup scene.tncg15 (bpy 5.0 in-process)
and its panels, and the render stats.

Each front end is checked by a function that compares it with a list of rows and returns the
problems it finds.  The front ends are built from the real table, so handing the checks an edited
copy of a row is what drift looks like: the negative controls do that and must see problems.
"""
import argparse
import contextlib
import dataclasses
import io
import os
import subprocess
import sys

import pytest

import bpy
import mcrt_addon
from engine.core import settings as table
from engine.core.errors import SceneError
from engine.core.settings import (ADDON_CLI, BLENDER, BOOL, CHOICE, CHOICES, ENGINE_CLI, EVERY_FRONT, FLOAT, INT,
                                  SETTINGS, STATS_AS_SET, RenderSettings)
from mcrt_addon.headless import ensure_registered

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BLENDER_ONLY = {"rna_type", "name", "viewport_samples", "estimate_text",      # scene.tncg15, not settings
                "use_preview_denoising", "viewport_denoise_start", "viewport_start_resolution"}
KINDS = {INT: "INT", FLOAT: "FLOAT", BOOL: "BOOLEAN", CHOICE: "ENUM"}      # bpy property types


@pytest.fixture(scope="module")
def addon():
    ensure_registered(mcrt_addon)                # as tests/addon/conftest.py does
    return mcrt_addon


@contextlib.contextmanager
def fresh_scene():
    """A new scene: its scene.tncg15 holds the PropertyGroup's defaults."""
    scene = bpy.data.scenes.new("settings-table")
    try:
        yield scene
    finally:
        bpy.data.scenes.remove(scene)


def other_value(s):
    """A value of the row other than its default, inside its limits."""
    if s.kind == BOOL:
        return not s.default
    if s.kind == INT:
        return s.default + 1 if s.default < s.limits[1] else s.default - 1
    if s.kind == FLOAT:
        return (s.limits[0] + s.limits[1]) / 2
    if s.kind == CHOICE:
        return next(v for v in s.values if v != s.default)
    return s.values


def flag_argv(s, value):
    if s.kind == BOOL:
        return [s.flag]
    return [s.flag, ",".join(value) if s.kind == CHOICES else repr(value) if s.kind == FLOAT else str(value)]


def parse(parser, argv):
    """The parsed arguments, or None when the parser refuses them (SystemExit)."""
    with contextlib.redirect_stderr(io.StringIO()):
        try:
            return parser.parse_args(argv)
        except SystemExit:
            return None


def refusal(parser, argv) -> str:
    """What the parser writes when it refuses `argv` ('' when it accepts them)."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            parser.parse_args(argv)
        except SystemExit:
            return err.getvalue()
    return ""


def same(a, b):
    return a == pytest.approx(b, rel=1e-6) if isinstance(b, float) else a == b


def limit_problems(name, s, parser, base):
    """The parser accepts exactly the row's limits (INT, FLOAT) or choices (CHOICE, CHOICES)."""
    out = []
    if s.kind in (INT, FLOAT):
        low, high = s.limits
        step = 1 if s.kind == INT else abs(high) * 1e-6 + 1e-9
        for value, ok in ((low, True), (high, True), (low - step, False), (high + step, False)):
            text = str(value) if s.kind == INT else repr(float(value))
            if (parse(parser, base + [s.flag, text]) is not None) != ok:
                out.append(f"{name}: {s.flag} {text} is {'refused' if ok else 'accepted'} (limits {s.limits})")
    elif s.kind in (CHOICE, CHOICES):
        for value in s.values:
            if parse(parser, base + [s.flag, value]) is None:
                out.append(f"{name}: {s.flag} {value} is refused")
        error = refusal(parser, base + [s.flag, "no-such-choice"]).replace("'", "")   # quoted before 3.12
        listed = f"({'choose from' if s.kind == CHOICE else 'known:'} {', '.join(s.values)})"
        if listed not in error:
            out.append(f"{name}: {s.flag} does not offer exactly {s.values}: {error.strip()!r}")
    return out


def undeclared_flag_problems(name, rows, front, parser, base):
    """A row that does not declare this front end has no flag there."""
    return [f"{name}: {s.flag} exists though {s.name} does not declare {front}" for s in rows
            if s.flag and front not in s.fronts and parse(parser, base + flag_argv(s, other_value(s))) is not None]


# -- the front ends, each checked against a list of rows ---------------------------------------------
def dataclass_problems(rows):
    out = []
    fields = dataclasses.fields(RenderSettings)
    if [f.name for f in fields] != [s.name for s in rows]:
        out.append(f"RenderSettings fields {[f.name for f in fields]} are not the rows {[s.name for s in rows]}")
    defaults = RenderSettings()
    for s in rows:
        if getattr(defaults, s.name, None) != s.default:
            out.append(f"RenderSettings.{s.name} = {getattr(defaults, s.name, None)!r}, the row says {s.default!r}")
            continue
        if s.kind in (INT, FLOAT):
            low, high = s.limits
            step = 1 if s.kind == INT else abs(high) * 1e-6 + 1e-9
            for value, ok in ((low, True), (high, True), (low - step, False), (high + step, False)):
                try:
                    dataclasses.replace(defaults, **{s.name: value}).validate()
                    accepted = True
                except SceneError:
                    accepted = False
                if accepted != ok:
                    out.append(f"validate(): {s.name}={value!r} is {'refused' if ok else 'accepted'}")
        if s.kind == CHOICE:
            for value in s.values:
                dataclasses.replace(defaults, **{s.name: value}).validate()
    return out


def cli_problems(name, front, rows, parser, base, settings_after):
    """Every row of `front` has a flag; no flags give the row's default; the flag makes another
    value; the limits and choices offered are the row's; no flag without a row."""
    out = []
    defaults = settings_after(parse(parser, base))
    for s in rows:
        if front not in s.fronts:
            continue
        if s.flag is None:
            out.append(f"{name}: {s.name} declares it but has no flag")
            continue
        # the add-on's command line keeps the file's value: a new file's (Cycles' default where it
        # differs), but for what its default preset (fair) sets (mcrt_addon/properties.py apply_preset)
        fair = s.name in table.preset_values(table.FAIR) or s.name == "max_depth"
        expected = s.new_file_default if front == ADDON_CLI and BLENDER in s.fronts and not fair else s.default
        if not same(getattr(defaults, s.name), expected):
            out.append(f"{name}: {s.name} without its flag is {getattr(defaults, s.name)!r}, the row says {expected!r}")
        value = other_value(s)
        args = parse(parser, base + flag_argv(s, value))
        if args is None or not same(getattr(settings_after(args), s.name), value):
            out.append(f"{name}: {' '.join(flag_argv(s, value))} does not make {s.name}={value!r}")
        out += limit_problems(name, s, parser, base)
    return out + undeclared_flag_problems(name, rows, front, parser, base)


def engine_cli_problems(rows):
    from engine.cli.main import build_parser, settings_from_args
    return cli_problems("python -m engine", ENGINE_CLI, rows, build_parser(), ["render", "-o", "x.exr"],
                        settings_from_args)


def addon_cli_problems(rows):
    """Through apply_tncg15_settings onto a fresh scene and its to_settings (passes: the view layer)."""
    from mcrt_addon.cli import apply_tncg15_settings, build_parser
    from mcrt_addon.passes import apply_pass_options, enabled_passes

    def settings_after(args):
        with fresh_scene() as scene:
            apply_tncg15_settings(scene.tncg15, args)
            result = scene.tncg15.to_settings(RenderSettings)
            if args.passes:
                apply_pass_options(scene, args.passes, args.denoise)
                result.passes = tuple(p for p in enabled_passes(scene, scene.view_layers[0]) if p != "noisy")
            return result
    return cli_problems("python -m mcrt_addon", ADDON_CLI, rows, build_parser(), ["render", "f.blend", "-o", "o.exr"],
                        settings_after)


def blender_problems(rows):
    from mcrt_addon import properties
    rna = properties.TNCG15RenderSettings.bl_rna.properties
    name, out = "scene.tncg15", []
    wanted = set(BLENDER_ONLY)
    for s in rows:
        if BLENDER not in s.fronts:
            if s.blender_prop in rna:
                out.append(f"{name}.{s.blender_prop} exists though {s.name} does not declare {BLENDER}")
            continue
        wanted.add(s.blender_prop)
        p = rna.get(s.blender_prop)
        if p is None or p.type != KINDS[s.kind]:
            out.append(f"{name}: no {KINDS[s.kind]} property {s.blender_prop} for {s.name}")
            continue
        if p.name != s.label:
            out.append(f"{name}.{s.blender_prop}: label {p.name!r}, the row says {s.label!r}")
        toggle = s.off_toggle
        if toggle is not None:
            wanted.add(toggle.prop)
            t = rna.get(toggle.prop)
            if t is None or t.type != "BOOLEAN" or t.default is not False:
                out.append(f"{name}.{toggle.prop}: not an off checkbox for {s.name}")
            if s.default != s.limits[0]:
                out.append(f"{name}.{toggle.prop}: off is {s.limits[0]}, the row's default is {s.default!r}")
        if s.kind in (INT, FLOAT):
            low = toggle.on_min if toggle else s.limits[0]
            if not (same(p.hard_min, float(low)) and same(p.hard_max, float(s.limits[1]))):
                out.append(f"{name}.{s.blender_prop}: limits ({p.hard_min}, {p.hard_max}), the row says "
                           f"({low}, {s.limits[1]})")
            if not toggle and not same(p.default, s.new_file_default):
                out.append(f"{name}.{s.blender_prop}: default {p.default!r}, the row says {s.new_file_default!r}")
        elif s.kind == CHOICE:
            items = [(i.identifier, i.name, i.description) for i in p.enum_items]
            if items != [(c.identifier, c.label, c.description) for c in s.choices]:
                out.append(f"{name}.{s.blender_prop}: items {items}, the row says {s.choices}")
            if p.default != s.identifier(s.new_file_default):
                out.append(f"{name}.{s.blender_prop}: default {p.default}, the row says {s.new_file_default!r}")
        elif p.default != s.new_file_default:
            out.append(f"{name}.{s.blender_prop}: default {p.default!r}, the row says {s.new_file_default!r}")
    extra = sorted(set(rna.keys()) - wanted)
    if extra:
        out.append(f"{name} has properties that are no row of the table: {extra}")

    with fresh_scene() as scene:                      # to_settings: the defaults, then each value
        props = scene.tncg15
        defaults = props.to_settings(RenderSettings)
        for s in rows:
            if BLENDER in s.fronts and not same(getattr(defaults, s.name), s.new_file_default):
                out.append(f"to_settings(): {s.name} = {getattr(defaults, s.name)!r}, the row says "
                           f"{s.new_file_default!r}")
        for s in rows:
            if BLENDER not in s.fronts or s.blender_prop not in rna:
                continue
            value = other_value(s)
            if s.off_toggle is not None:
                setattr(props, s.off_toggle.prop, True)
            setattr(props, s.blender_prop, s.identifier(value) if s.kind == CHOICE else value)
            got = getattr(props.to_settings(RenderSettings), s.name)
            if not same(got, value):
                out.append(f"to_settings(): {name}.{s.blender_prop} = {value!r} gives {s.name}={got!r}")
            props.property_unset(s.blender_prop)
            if s.off_toggle is not None:
                props.property_unset(s.off_toggle.prop)
    return out


class RecordingLayout:
    """Stands in for a UILayout: records the scene.tncg15 properties drawn."""

    def __init__(self, props, seen):
        object.__setattr__(self, "_props", props)
        object.__setattr__(self, "_seen", seen)

    def __getattr__(self, name):
        return None

    def __setattr__(self, name, value):            # use_property_split, active, ...: accepted
        pass

    def column(self, **kw):
        return self

    row = column

    def prop(self, data, name, **kw):
        if data == self._props:
            self._seen.append(name)

    def operator(self, *a, **kw):
        pass

    def label(self, **kw):
        pass


def panel_problems(rows):
    """Each Blender row's property is drawn once, in the Render Properties panel the row names."""
    import types
    from mcrt_addon import ui
    labels = {c.__name__: c.bl_label for c in ui.classes}
    drawn = {}
    with fresh_scene() as scene:
        context = types.SimpleNamespace(engine=ui.ENGINE_ID, scene=scene)
        for cls in ui.classes:
            if getattr(cls, "bl_context", "") != "render":
                continue
            path = " > ".join(filter(None, (labels.get(getattr(cls, "bl_parent_id", "")), cls.bl_label)))
            seen = []
            for method in ("draw_header", "draw"):
                if hasattr(cls, method):
                    getattr(cls, method)(types.SimpleNamespace(layout=RecordingLayout(scene.tncg15, seen)), context)
            for prop in seen:
                drawn.setdefault(prop, []).append(path)
    out = []
    for s in rows:
        if BLENDER in s.fronts and drawn.get(s.blender_prop) != [s.panel]:
            out.append(f"panels: {s.blender_prop} is drawn in {drawn.get(s.blender_prop, [])}, the row says {s.panel!r}")
    return out


FRONT_ENDS = {"RenderSettings": dataclass_problems, ENGINE_CLI: engine_cli_problems,
              ADDON_CLI: addon_cli_problems, BLENDER: blender_problems, "panels": panel_problems}


# -- the tests -----------------------------------------------------------------------------------------
def test_rows_are_well_formed():
    names = [s.name for s in SETTINGS]
    assert len(set(names)) == len(names)
    flags = [s.flag for s in SETTINGS if s.flag]
    assert len(set(flags)) == len(flags)
    for s in SETTINGS:
        assert s.kind in (INT, FLOAT, BOOL, CHOICE, CHOICES) and s.fronts <= EVERY_FRONT and s.help, s.name
        if s.kind in (INT, FLOAT):
            assert s.limits[0] <= s.default <= s.limits[1], s.name
        if s.kind in (CHOICE, CHOICES):
            assert s.choices and set(s.default if s.kind == CHOICES else (s.default,)) <= set(s.values), s.name
        if s.fronts & {ENGINE_CLI, ADDON_CLI}:
            assert s.flag and s.flag.startswith("--"), s.name
            if s.kind == BOOL:           # a switch flips the default
                assert s.flag.startswith("--no-") == s.default, s.name
        else:
            assert s.flag is None, s.name
        if BLENDER in s.fronts:
            assert s.label and s.description and s.panel and s.kind != CHOICES, s.name
    assert [s.name for s in table.settings_for(BLENDER)] == [s.name for s in SETTINGS if BLENDER in s.fronts]


@pytest.mark.parametrize("front", list(FRONT_ENDS))
def test_every_row_reaches_its_front_ends(addon, front):
    assert FRONT_ENDS[front](SETTINGS) == []


def edited(name, **change):
    return tuple(dataclasses.replace(s, **change) if s.name == name else s for s in SETTINGS)


# A copy of a row edited as if one front end had drifted from it, and the front ends that must see it.
DRIFTS = {
    "default": (edited("tile_size", default=32), set(FRONT_ENDS) - {"panels"}),
    "limit": (edited("shadow_rays", limits=(0, 64)), {"RenderSettings", ENGINE_CLI, ADDON_CLI, BLENDER}),
    "choice": (edited("estimator", choices=table.SETTING["estimator"].choices[:2]), {ENGINE_CLI, ADDON_CLI, BLENDER}),
    "front": (edited("rr_start_depth", fronts=frozenset((ENGINE_CLI, BLENDER))), {ADDON_CLI}),
    "label": (edited("max_depth", label="Max Depth"), {BLENDER}),
    "panel": (edited("seed", panel="Sampling > Render"), {"panels"}),
    "bool": (edited("adaptive", default=False), {"RenderSettings", ENGINE_CLI, ADDON_CLI, BLENDER}),
    "new file default": (edited("clamp_indirect", blender_default=5.0), {BLENDER}),
}


@pytest.mark.parametrize("drift", list(DRIFTS))
def test_a_drifted_row_is_caught_by_the_front_ends_it_reaches(addon, drift):
    """Negative control: with one row edited, exactly the front ends that read it report problems."""
    rows, caught_by = DRIFTS[drift]
    found = {front for front, check in FRONT_ENDS.items() if check(rows)}
    assert found == caught_by


def test_validate_keeps_its_messages():
    cases = [(dict(samples=0), "samples must be an integer from 1 to 2,147,483,647, got 0"),
             (dict(tile_size=True), "tile size must be an integer from 8 to 16,384, got True"),
             (dict(noise_target=2.0), "noise target must be a number from 0 (off) to 1, got 2.0"),
             (dict(time_limit=-1.0), "time limit must be a number from 0 (off) to 1e+09, got -1.0"),
             (dict(passes=("albedo", "z")), f"unknown pass 'z' (known: {', '.join(table.PASSES)})"),
             (dict(estimator="fast"), "unknown estimator 'fast' (expected one of mis, solid-angle, report)")]
    for change, message in cases:
        with pytest.raises(SceneError) as exc:
            RenderSettings(**change).validate()
        assert str(exc.value) == message


def test_render_stats_list_the_settings_the_table_says():
    from engine.api import render
    from engine.scene.builtin import BUILTIN_SCENES
    scene = BUILTIN_SCENES["cornell"]()
    scene.resolution = (8, 8)
    settings = RenderSettings(samples=1, threads=1, seed=3, passes=("depth",))
    stats = render(scene, settings, log=lambda *a: None).stats
    assert {s.name for s in SETTINGS if s.stats} <= set(stats)
    assert not {s.name for s in SETTINGS if not s.stats} & set(stats)
    for s in SETTINGS:
        if s.stats == STATS_AS_SET:
            assert stats[s.name] == (list(getattr(settings, s.name)) if s.kind == CHOICES else getattr(settings, s.name))


def test_the_table_imports_without_numpy():
    """The add-on reads the table at registration (mcrt_addon/bridge.py settings_table), also where
    numpy is missing; the tracer's heavy modules still need it (the block works)."""
    code = ("import sys; sys.modules['numpy'] = None\n"
            "import engine.core.settings as t; t.RenderSettings().validate()\n"
            "try:\n    import engine.scene.model\nexcept ImportError:\n    print('blocked')\n")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.strip() == "blocked", r.stderr


def test_the_engine_package_exports_lazily():
    import engine
    assert engine.RenderSettings is RenderSettings and callable(engine.render)
    with pytest.raises(AttributeError):
        engine.no_such_name  # noqa: B018


def test_argparse_types_refuse_with_one_line():
    from engine.cli.settings_args import bounded_float, bounded_int, choice_list
    with pytest.raises(argparse.ArgumentTypeError, match="must be from 8 to 16,384, got 4"):
        bounded_int(8, 16384)("4")
    with pytest.raises(argparse.ArgumentTypeError, match="must be from 0 to 1, got 5"):
        bounded_float(0.0, 1.0)("5")
    with pytest.raises(argparse.ArgumentTypeError, match="unknown pass 'z'"):
        choice_list(table.SETTING["passes"])("albedo,z")
    assert choice_list(table.SETTING["passes"])("Normal, albedo") == ("albedo", "normal")
