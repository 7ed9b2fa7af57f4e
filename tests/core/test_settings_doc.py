"""docs/settings.md is what scripts/settings_doc.py writes from the settings table."""
import dataclasses
import importlib.util
import os

from engine.core import settings as table

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def settings_doc():
    spec = importlib.util.spec_from_file_location("settings_doc", os.path.join(ROOT, "scripts", "settings_doc.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_committed_settings_reference_matches_the_table():
    with open(os.path.join(ROOT, "docs", "settings.md"), encoding="utf-8") as fh:
        committed = fh.read()
    assert committed == settings_doc().markdown(), "docs/settings.md is out of date: run python scripts/settings_doc.py"


def test_every_setting_is_in_the_reference_with_its_default_and_flags():
    text = settings_doc().markdown()
    for s in table.SETTINGS:
        row = next(line for line in text.splitlines() if line.startswith(f"| `{s.name}`"))
        assert f" {settings_doc().default_text(s)} |" in row
        if s.flag:
            assert row.count(f"`{s.flag}") == len(s.fronts & {table.ENGINE_CLI, table.ADDON_CLI}), row
        if table.BLENDER in s.fronts:
            assert s.label in row and s.panel in row


def test_a_changed_row_changes_the_reference(monkeypatch):
    """Negative control: the comparison sees an edit of the table."""
    doc = settings_doc()
    before = doc.markdown()
    rows = tuple(dataclasses.replace(s, default=32) if s.name == "tile_size" else s for s in table.SETTINGS)
    monkeypatch.setattr(doc.table, "SETTINGS", rows)
    assert doc.markdown() != before
