"""One version everywhere: the package, the engine, the client, the OpenAPI file and the
CHANGELOG's latest release agree, and the CHANGELOG keeps the Keep a Changelog shape (an
``[Unreleased]`` section first, then releases with dates, newest first)."""

from __future__ import annotations

import ast
import datetime as dt
import json
import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RELEASE = re.compile(r"^## \[(\d+\.\d+\.\d+)\] - (\d{4}-\d{2}-\d{2})$")
KINDS = {"Added", "Changed", "Deprecated", "Removed", "Fixed", "Security", "Known issues"}


def _assigned_version(path: Path) -> str:
    """``__version__`` as assigned in a module, read without importing it."""
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "__version__" for t in node.targets):
            assert isinstance(node.value, ast.Constant)
            return str(node.value.value)
    raise AssertionError(f"no __version__ in {path}")


def _project_version(path: Path) -> str:
    return str(tomllib.loads(path.read_text())["project"]["version"])


def _headings() -> list[str]:
    return [line for line in (ROOT / "CHANGELOG.md").read_text().splitlines()
            if line.startswith("## ") or line.startswith("### ")]


def test_every_version_string_agrees() -> None:
    version = _project_version(ROOT / "pyproject.toml")
    assert re.fullmatch(r"\d+\.\d+\.\d+", version)
    found = {
        "engine/__init__.py": _assigned_version(ROOT / "engine" / "__init__.py"),
        "client/pyproject.toml": _project_version(ROOT / "client" / "pyproject.toml"),
        "client/linkage_client/__init__.py":
            _assigned_version(ROOT / "client" / "linkage_client" / "__init__.py"),
        "openapi/openapi.json":
            json.loads((ROOT / "openapi" / "openapi.json").read_text())["info"]["version"],
    }
    assert found == dict.fromkeys(found, version)


def test_changelog_latest_release_is_the_version() -> None:
    releases = [RELEASE.match(h) for h in _headings() if h.startswith("## ")]
    h2 = [h for h in _headings() if h.startswith("## ")]
    assert h2[0] == "## [Unreleased]"
    assert all(releases[1:]), f"a release heading is not '## [x.y.z] - YYYY-MM-DD': {h2}"
    versions = [m.group(1) for m in releases[1:] if m]
    dates = [dt.date.fromisoformat(m.group(2)) for m in releases[1:] if m]
    assert versions, "the CHANGELOG has no release"
    assert versions[0] == _project_version(ROOT / "pyproject.toml")
    assert dates == sorted(dates, reverse=True)
    as_tuples = [tuple(int(p) for p in v.split(".")) for v in versions]
    assert as_tuples == sorted(as_tuples, reverse=True) and len(set(versions)) == len(versions)


def test_changelog_sections_are_the_kinds_of_change() -> None:
    kinds = {h[4:] for h in _headings() if h.startswith("### ")}
    assert kinds <= KINDS, kinds - KINDS
