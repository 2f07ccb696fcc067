"""The repository keeps its promises: README commands, CI script, Dockerfile, the map of the
tests (tests/README.md)."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def readme_commands() -> list[str]:
    block = re.search(r"```bash\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
    assert block, "the README opens with a bash block of two commands"
    return [line for line in block.group(1).splitlines() if line.strip()]


def test_readme_opens_with_exactly_two_commands():
    cmds = readme_commands()
    assert len(cmds) == 2
    assert "uvicorn service.main:app --host 127.0.0.1 --port 8000" in cmds[0]
    assert "pytest" in cmds[1]


def test_ci_runs_the_readme_test_command_verbatim():
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert readme_commands()[1] in ci


def test_dockerfile_requirements():
    text = (ROOT / "Dockerfile").read_text()
    assert re.search(r"^FROM python:3\.\d+-slim", text, re.M)
    user = re.findall(r"^USER (\S+)", text, re.M)
    assert user and user[-1] not in ("root", "0")
    assert re.search(r"^HEALTHCHECK .*\n?.*/health", text, re.M)
    assert '"--host", "0.0.0.0", "--port", "8000"' in text
    assert "service.main:app" in text


def test_readme_and_docs_point_only_inside_the_repository():
    """Relative links of the README and docs/ resolve to files of the repository, and nothing
    sends readers to ../shared/ (the contract and the references live in docs/)."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    assert {"API.md", "notation.md", "methods.md", "references.md"} <= {p.name for p in pages}
    broken = []
    for page in pages:
        text = page.read_text()
        assert "../shared" not in text, f"{page.name} points at ../shared/"
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
            if "://" not in target and not (page.parent / target).exists():
                broken.append(f"{page.name}: {target}")
    assert not broken, broken


def test_readme_gives_the_quick_command_and_its_markers_are_registered():
    import tomllib

    readme = (ROOT / "README.md").read_text()
    assert '.venv/bin/python -m pytest -q -m "not slow"' in readme
    pytest_ini = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]
    registered = {m.split(":", 1)[0] for m in pytest_ini["ini_options"]["markers"]}
    assert {"slow", "process", "browser", "dask", "fuzz", "lint"} <= registered
    assert "--strict-markers" in pytest_ini["ini_options"]["addopts"]


# The map of the tests (tests/README.md): paths are written from the repository's root.
TEST_MAP = ROOT / "tests" / "README.md"


def mirror(module: Path) -> Path:
    """Where the tests of a module are by default: ``engine/a/b.py`` -> ``tests/engine/a/
    test_b.py``; a router ``service/routers/x.py`` -> ``tests/service/test_x.py``."""
    top, *inner, name = module.parts
    if top == "service" and inner == ["routers"]:
        inner = []
    return ROOT.joinpath("tests", top, *inner, f"test_{name}")


def modules() -> list[Path]:
    return sorted(p.relative_to(ROOT) for top in ("engine", "service")
                  for p in (ROOT / top).rglob("*.py") if p.name != "__init__.py")


def mapped_paths() -> set[str]:
    return set(re.findall(r"`((?:engine|service|tests)/[\w/]+\.py)`", TEST_MAP.read_text()))


def test_every_module_has_a_mirrored_test_file_or_a_row_in_the_test_map():
    named = mapped_paths()
    missing = [m.as_posix() for m in modules()
               if not mirror(m).exists() and m.as_posix() not in named]
    assert not missing, f"no tests/.../test_<module>.py and no row in tests/README.md: {missing}"


def test_the_test_map_is_true():
    """Every test file is a module's mirror or named in tests/README.md, and every path the
    map names exists (a renamed module or test file must be renamed there too)."""
    named = mapped_paths()
    mirrors = {mirror(m) for m in modules()}
    tests = sorted((ROOT / "tests").rglob("test_*.py"))
    unmapped = [p.relative_to(ROOT).as_posix() for p in tests
                if p not in mirrors and p.relative_to(ROOT).as_posix() not in named]
    assert not unmapped, f"test files that mirror no module, not in tests/README.md: {unmapped}"
    stale = sorted(p for p in named if not (ROOT / p).exists())
    assert not stale, f"tests/README.md names paths that do not exist: {stale}"
