"""The examples (examples/*.py) reproduce the paper through the client against a real uvicorn on
loopback (the client tests' ``served`` fixture): each exits 0, every number it prints beside the
paper's agrees (``ok``), the numbers named below are among them, and every figure it names is
an SVG file it wrote."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.client import test_package

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
served = test_package.served  # the README's service, one engine worker

#: The paper's numbers each example must print (its rows' names): a row dropped is a failure.
ROWS = {
    "four_bar.py": ["branch points at L1 = L2 = L3 = a", "self-stresses and zero modes at each",
                    "components at L2 = 1.01", "components at L2 = 0.99",
                    "dL2 = +-0.01 joins opposite ray pairs"],
    "four_bar_map.py": ["L1 = 0.6: regions in the box", "L1 = 1.5: regions in the box",
                        "volumes met (sign patterns of tau)"],
    "three_rotor.py": ["branch points at r1 = r2 = r3 = L1 = L2 = a",
                       "pairs coinciding in a projection",
                       "L1 = 0.9 a switches how branch points split", "topology from red to blue",
                       "design: the pair split apart with (r1, L1, L2)"],
    "gated_chain.py": ["regions of the (L2, D) slice", "gated where Grashof stops the gate's crank",
                       "critical points of a unit cell at L2 = 2a, D = 5a/2",
                       "threshold in D (6 rotors, gate on rotor 3)"],
}
#: Seconds an example may take on a loaded 2-core machine (the gated chain's slice is ~10 s of
#: them at a load of 10; the others a few seconds).
TIMEOUT_S = 300


def test_every_example_is_run_here() -> None:
    scripts = {p.name for p in EXAMPLES.glob("*.py") if not p.name.startswith("_")}
    assert scripts == set(ROWS)


@pytest.mark.process
@pytest.mark.parametrize("name", sorted(ROWS))
def test_example_reproduces_the_paper(name: str, served: str, tmp_path: Path) -> None:
    out = tmp_path / "figures"
    env = {**os.environ, "NO_PROXY": "*", "no_proxy": "*",
           "PYTHONPATH": os.pathsep.join([str(ROOT / "client"), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, str(EXAMPLES / name), "--url", served, "--out",
                           str(out)], capture_output=True, text=True, timeout=TIMEOUT_S,
                          cwd=tmp_path, env=env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = [line for line in proc.stdout.splitlines() if line[:3] in ("ok ", "NO ")]
    assert rows and all(line.startswith("ok ") for line in rows), proc.stdout
    for what in ROWS[name]:
        assert any(line[3:].startswith(what) for line in rows), (what, proc.stdout)
    figures = [Path(line.split(": ", 1)[1]) for line in proc.stdout.splitlines()
               if line.startswith("figure: ")]
    assert figures and {p.parent for p in figures} == {out}
    for path in figures:
        assert "<svg" in path.read_text()[:2000], path


def test_an_example_exits_non_zero_when_a_number_disagrees(tmp_path: Path) -> None:
    """The exit status is the table's: one row that disagrees makes it 1 (no service needed)."""
    sys.path.insert(0, str(EXAMPLES))
    try:
        from _paper import Report
    finally:
        sys.path.remove(str(EXAMPLES))
    good = Report("t", tmp_path)
    good.check("three", 3, 3, True)
    bad = Report("t", tmp_path)
    bad.check("three", 3, 3, True)
    bad.check("twelve", 12, 11, False)
    assert good.finish() == 0 and bad.finish() == 1
    assert Report("t", tmp_path).finish() == 1  # nothing checked is no reproduction
