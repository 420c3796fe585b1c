"""Compiling the FMU runtime: cache, missing compiler, failing compiler."""

import os
import stat

import pytest

from twin.fmu.build import FMUBuildError, compiled_runtime, find_compiler


def test_runtime_is_compiled_once_and_cached(tmp_path, monkeypatch):
    monkeypatch.setenv("TWIN_CACHE_DIR", str(tmp_path))
    first = compiled_runtime()
    assert first.is_file() and first.stat().st_size > 1000
    mtime = first.stat().st_mtime_ns
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))  # not needed any more
    assert compiled_runtime() == first and first.stat().st_mtime_ns == mtime


def test_missing_compiler_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("TWIN_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CC", "no-such-compiler-xyz")
    with pytest.raises(FMUBuildError, match="no C compiler found .*no-such-compiler-xyz.*apt-get install gcc"):
        find_compiler()
    with pytest.raises(FMUBuildError, match="no C compiler found"):
        compiled_runtime()


def test_compiler_failure_shows_the_compiler_message(tmp_path, monkeypatch):
    fake = tmp_path / "badcc"
    fake.write_text("#!/bin/sh\necho 'twin_lti.c:1: error: something is wrong' >&2\nexit 1\n")
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    monkeypatch.setenv("TWIN_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("CC", str(fake))
    with pytest.raises(FMUBuildError, match="failed:\ntwin_lti.c:1: error: something is wrong"):
        compiled_runtime()
    leftovers = [p for p in (tmp_path / "cache").rglob("*") if p.is_file()]
    assert leftovers == [] and os.environ["CC"] == str(fake)
