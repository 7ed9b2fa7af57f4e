"""engine/core/allocator.py: glibc's malloc thresholds are set once; elsewhere nothing is done."""
import platform
import sys
import types

import pytest

from engine.core import allocator


@pytest.fixture
def fresh(monkeypatch):
    monkeypatch.setattr(allocator, "_tuned", None)
    return allocator


@pytest.mark.skipif(not (sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc"),
                    reason="glibc only")
def test_glibc_accepts_the_thresholds_once(fresh, monkeypatch):
    assert fresh.tune_malloc() is True
    monkeypatch.setattr(fresh.ctypes, "CDLL", lambda *a: pytest.fail("mallopt called twice"))
    assert fresh.tune_malloc() is True                       # cached: one-way and process-wide


def test_other_systems_do_nothing(fresh, monkeypatch):
    monkeypatch.setattr(fresh.sys, "platform", "darwin")
    monkeypatch.setattr(fresh.ctypes, "CDLL", lambda *a: pytest.fail("libc opened on darwin"))
    assert fresh.tune_malloc() is False


def test_a_libc_without_mallopt_is_not_an_error(fresh, monkeypatch):
    monkeypatch.setattr(fresh.sys, "platform", "linux")
    monkeypatch.setattr(fresh.ctypes, "CDLL", lambda *a: object())
    assert fresh.tune_malloc() is False


def test_a_refused_setting_is_reported(fresh, monkeypatch):
    def mallopt(option, value):                              # glibc returns 0 for a refused value
        return 0 if option == fresh.M_MMAP_THRESHOLD else 1
    monkeypatch.setattr(fresh.sys, "platform", "linux")
    monkeypatch.setattr(fresh.ctypes, "CDLL", lambda *a: types.SimpleNamespace(mallopt=mallopt))
    assert fresh.tune_malloc() is False
