"""The engine is pure numpy/scipy: nothing under engine/ imports the web stack (nor Dask or the
command line's progress bar: jobs and sweeps reach the engine through plain functions)."""

import ast
from pathlib import Path

FORBIDDEN = {"fastapi", "pydantic", "starlette", "uvicorn", "httpx", "service", "dask",
             "distributed", "rich"}


def test_engine_imports_no_web_stack():
    offenders = []
    for path in Path(__file__).resolve().parents[1].joinpath("engine").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            offenders += [f"{path.name}: {n}" for n in names if n.split(".")[0] in FORBIDDEN]
    assert not offenders, offenders
