"""Stage reports say which code made them: ``git describe`` of lampfab's checkout."""

import shutil
import subprocess

import pytest

from lampfab import artifacts

from tests.helpers import ROOT

GIT = shutil.which("git")


def _git(folder, *args) -> str:
    run = subprocess.run(["git", "-C", str(folder), "-c", "user.name=t", "-c", "user.email=t@t", *args],
                         capture_output=True, text=True, check=True)
    return run.stdout.strip()


def test_a_stage_report_records_the_checkout_next_to_the_versions():
    data = artifacts.StageReport("plan", {}, {}).data
    keys = list(data)
    assert keys.index("git_describe") == keys.index("versions") + 1
    if GIT and (ROOT / ".git").exists():
        assert data["git_describe"] == _git(ROOT, "describe", "--always", "--dirty")
    else:
        assert data["git_describe"] is None


@pytest.mark.skipif(GIT is None, reason="needs git to make a checkout")
def test_only_a_checkout_that_tracks_lampfab_is_described(tmp_path):
    describe = artifacts.git_describe.__wrapped__
    package = tmp_path / "lampfab"
    package.mkdir()
    (package / "__init__.py").write_text("")
    assert describe(package) is None                      # not in any checkout
    _git(tmp_path, "init", "-q")
    (tmp_path / "README").write_text("x")
    _git(tmp_path, "add", "README")
    _git(tmp_path, "commit", "-q", "-m", "first")
    assert describe(package) is None                      # a copy the checkout does not track
    _git(tmp_path, "add", "lampfab")
    _git(tmp_path, "commit", "-q", "-m", "lampfab")
    assert describe(package) == _git(tmp_path, "rev-parse", "--short", "HEAD")
    (package / "__init__.py").write_text("changed = True\n")
    assert describe(package).endswith("-dirty")


def test_no_git_is_no_description(monkeypatch):
    monkeypatch.setattr(artifacts.shutil, "which", lambda name: None)
    assert artifacts.git_describe.__wrapped__(ROOT / "lampfab") is None
