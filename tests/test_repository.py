"""The repository keeps its promises: README commands, CI script, Dockerfile."""

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
