"""The static site of docs/ (mkdocs.yml) builds: every page of docs/ is in its navigation and
written, and the only warnings are links out of docs/ to files of the repository (the README,
the OpenAPI file, the tests' map), which the site cannot hold but the repository has."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


def nav_pages(nav: list) -> set[str]:
    pages: set[str] = set()
    for item in nav:
        for value in item.values() if isinstance(item, dict) else [item]:
            pages |= nav_pages(value) if isinstance(value, list) else {value}
    return pages


def test_every_page_is_in_the_navigation() -> None:
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    assert nav_pages(config["nav"]) == {p.name for p in (ROOT / "docs").glob("*.md")}


def test_the_site_builds(tmp_path: Path) -> None:
    site = tmp_path / "site"
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--site-dir", str(site)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    for page in (ROOT / "docs").glob("*.md"):
        assert (site / f"{page.stem}.html").is_file(), page.name
    assert (site / "figures" / "configuration-space.svg").is_file()
    warnings = [ln for ln in proc.stderr.splitlines() if ln.startswith("WARNING")]
    outside = re.compile(r"Doc file '[\w.-]+' contains a link '\.\./([\w./-]+)', but the target "
                         r"is not found among documentation files\.")
    for line in warnings:
        m = outside.search(line)
        assert m and (ROOT / m.group(1)).is_file(), line
