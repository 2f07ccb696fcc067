"""Times of the gate, three-rotor and spherical four-bar critical-value maps (issue 23),
optionally against another checkout of the repository (before/after), each run in a fresh
process with one BLAS thread (as the service's workers run).

    .venv/bin/python bench/bench_slice_maps.py [--repeats 3] [--against /path/to/other/checkout]
        [--only spherical] [--json bench/results/slice_maps.json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: name -> code run in the child (prints seconds, curves, regions, complete)
MAPS = {
    "gate map: gated-kl-chain n=4 gate=2, (L2, D) in [1, 3] x [1, 3.5], resolution 48": """
lk = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
args = (lk, [("L2", 1.0, 3.0), ("D", 1.0, 3.5)])
kw = dict(resolution=48, options=SpaceOptions(angles=12, random_starts=2, max_components=4))
""",
    "three-rotor map: (L1, L2) in [0.6, 1.4]^2, resolution 48": """
lk = build_preset("three-rotor")
args = (lk, [("L1", 0.6, 1.4), ("L2", 0.6, 1.4)])
kw = dict(resolution=48)
""",
    "three-rotor map, the preset matrix's: (r1, r2) in [0.8, 1.2]^2, resolution 48": """
lk = build_preset("three-rotor")
args = (lk, [("r1", 0.8, 1.2), ("r2", 0.8, 1.2)])
kw = dict(resolution=48)
""",
    "spherical four-bar map: (L1, L2) in [0.3, 0.9] x [0.65, 1.95], resolution 48": """
lk = build_preset("spherical-four-bar")
args = (lk, [("L1", 0.3, 0.9), ("L2", 0.65, 1.95)])
kw = dict(resolution=48)
""",
    "spherical four-bar map, the preset matrix's: (OA, OB) in [0.8, 1.2]^2, resolution 48": """
lk = build_preset("spherical-four-bar")
args = (lk, [("OA", 0.8, 1.2), ("OB", 0.8, 1.2)])
kw = dict(resolution=48)
""",
    "spherical four-bar map: (OB, L2) in [0.5, 1.5] x [0.6, 1.9], resolution 48": """
lk = build_preset("spherical-four-bar")
args = (lk, [("OB", 0.5, 1.5), ("L2", 0.6, 1.9)])
kw = dict(resolution=48)
""",
}

CHILD = """
import sys, time
sys.path.insert(0, {root!r})
from engine.catalogue.presets import build_preset
from engine.design.critical_values import critical_value_slice
from engine.space.configuration_space import SpaceOptions
{setup}
t = time.perf_counter()
s = critical_value_slice(*args, **kw)
print(time.perf_counter() - t, len(s.curves), len(s.regions), s.search["complete"])
"""


def run(root: Path, setup: str) -> tuple[float, int, int, bool]:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "MKL_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", CHILD.format(root=str(root), setup=setup)],
                         capture_output=True, text=True, env=env, check=True, cwd=root)
    seconds, curves, regions, complete = out.stdout.split()[-4:]
    return float(seconds), int(curves), int(regions), complete == "True"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--against", type=Path, default=None)
    parser.add_argument("--json", type=Path, default=ROOT / "bench/results/slice_maps.json")
    parser.add_argument("--only", default=None, help="the maps whose name holds this")
    args = parser.parse_args()
    trees = {"this": ROOT} | ({"against": args.against} if args.against else {})
    rows = []
    for name, setup in MAPS.items():
        if args.only is not None and args.only not in name:
            continue
        runs: dict[str, list[tuple[float, int, int, bool]]] = {tree: [] for tree in trees}
        for _ in range(args.repeats):  # the trees in turn: a busy machine's load falls on both
            for tree, root in trees.items():
                runs[tree].append(run(root, setup))
        for tree, root in trees.items():
            secs = [r[0] for r in runs[tree]]
            last = runs[tree][-1]
            row = {"benchmark": name, "tree": tree, "root": str(root),
                   "seconds_min": min(secs), "seconds_median": statistics.median(secs),
                   "curves": last[1], "regions": last[2], "complete": last[3]}
            rows.append(row)
            print(f"{name:<80} {tree:<8} min {min(secs):7.2f} s  median "
                  f"{statistics.median(secs):7.2f} s  {row['curves']} curves, "
                  f"{row['regions']} regions")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(rows, indent=2) + "\n")


if __name__ == "__main__":
    main()
