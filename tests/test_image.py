"""The image definition (no Docker engine here, so the Dockerfile is read, not built): a base
pinned by digest, a dependency layer from the checked-in lock before the code is copied, a
non-root user, a health check, and the README's server options plus --proxy-headers."""

from __future__ import annotations

import json
import re
import shlex
import tomllib
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[1]


def instructions() -> list[tuple[str, str]]:
    """(INSTRUCTION, arguments) in order, continuation lines joined, comments dropped."""
    text = (ROOT / "Dockerfile").read_text()
    logical, current = [], ""
    for line in text.splitlines():
        if not current and (not line.strip() or line.lstrip().startswith("#")):
            continue
        current += line.rstrip("\\").strip() + " "
        if not line.rstrip().endswith("\\"):
            logical.append(current.strip())
            current = ""
    assert not current, "dangling line continuation"
    return [(ln.split(None, 1)[0].upper(), ln.split(None, 1)[1]) for ln in logical]


def index_of(steps: list[tuple[str, str]], kind: str, pattern: str) -> int:
    found = [i for i, (k, args) in enumerate(steps) if k == kind and re.search(pattern, args)]
    assert found, f"no {kind} matching {pattern!r}"
    return found[0]


def lock() -> dict[str, str]:
    pins: dict[str, str] = {}
    text = (ROOT / "requirements.lock").read_text()
    for block in re.split(r"\n(?=[A-Za-z0-9])", text):
        head = block.split("\n", 1)[0]
        if head.startswith("#") or not head.strip():
            continue
        name, _, rest = head.partition("==")
        assert rest, f"not pinned: {head}"
        assert "--hash=sha256:" in block, f"no hash for {name}"
        pins[canonicalize_name(name)] = rest.split()[0].rstrip("\\").strip()
    return pins


def test_base_image_is_pinned_by_digest() -> None:
    steps = instructions()
    froms = [args for kind, args in steps if kind == "FROM"]
    assert froms
    for image in froms:
        assert re.fullmatch(r"python:3\.11-slim@sha256:[0-9a-f]{64}( AS \w+)?", image), image


def test_dependency_layer_from_the_lock_comes_before_the_code() -> None:
    steps = instructions()
    copy_lock = index_of(steps, "COPY", r"^requirements\.lock ")
    install_lock = index_of(steps, "RUN", r"pip install .*--require-hashes.*-r requirements\.lock")
    first_code = min(index_of(steps, "COPY", r"^engine "), index_of(steps, "COPY", r"^service "),
                     index_of(steps, "COPY", r"pyproject\.toml"))
    install_code = index_of(steps, "RUN", r"pip install .*--no-deps.* \.$")
    assert copy_lock < install_lock < first_code < install_code
    # nothing but the lock is copied before the dependency layer
    assert [i for i, (k, _) in enumerate(steps) if k in ("COPY", "ADD")][0] == copy_lock


def test_lock_pins_every_dependency_within_pyproject() -> None:
    pins = lock()
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    for spec in project["dependencies"]:
        req = Requirement(spec)
        name = canonicalize_name(req.name)
        assert name in pins, f"{req.name} missing from requirements.lock (run scripts/lock.sh)"
        assert req.specifier.contains(pins[name], prereleases=True), (req, pins[name])
    assert (ROOT / "scripts" / "lock.sh").exists()


def test_runs_as_a_non_root_user_with_a_health_check() -> None:
    steps = instructions()
    users = [(i, args.strip()) for i, (k, args) in enumerate(steps) if k == "USER"]
    assert users and users[-1][1] not in ("root", "0", "0:0")
    assert all(i > users[-1][0] for i, (k, _) in enumerate(steps) if k == "CMD")
    assert all(i < users[-1][0] for i, (k, _) in enumerate(steps) if k == "RUN")
    health = [args for k, args in steps if k == "HEALTHCHECK"]
    assert len(health) == 1 and "/health" in health[0] and "--timeout=" in health[0]


def test_command_uses_the_guarded_protocol_and_proxy_headers() -> None:
    steps = instructions()
    cmd = json.loads([args for k, args in steps if k == "CMD"][-1])
    assert cmd[:2] == ["uvicorn", "service.main:app"]
    assert cmd[cmd.index("--http") + 1] == "service.protocol:GuardedH11Protocol"
    assert "--proxy-headers" in cmd
    assert "--workers" not in cmd  # one uvicorn process; engine workers from the CPU quota
    readme = (ROOT / "README.md").read_text()
    start = next(ln for ln in readme.splitlines() if ".venv/bin/uvicorn service.main:app" in ln)
    readme_args = shlex.split(start.split(".venv/bin/uvicorn ", 1)[1])
    assert readme_args[readme_args.index("--http") + 1] == cmd[cmd.index("--http") + 1]
    env = " ".join(args for k, args in steps if k == "ENV")
    assert "LINKAGE_WORKERS" not in env


def test_the_tracer_kernel_is_compiled_into_the_image_for_the_app_user() -> None:
    """numba's cache must be warm and writable by the user that runs the service: the kernel
    is compiled at build time into ``NUMBA_CACHE_DIR`` in the app user's home, handed to it."""
    text = (ROOT / "Dockerfile").read_text()
    cache = re.search(r"NUMBA_CACHE_DIR=(\S+)", text)
    assert cache and cache.group(1).startswith("/home/app/")
    warm = next(args for k, args in instructions() if k == "RUN" and "trace_kernel.load()" in args)
    assert "chown -R app" in warm and cache.start() < text.index("trace_kernel.load()")
