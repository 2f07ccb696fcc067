"""Benchmarks of critical-value maps, robustness and the gated chain (run on demand).

    .venv/bin/python bench/bench_maps.py [--json bench/results/maps.json]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from engine.catalogue.presets import build_preset
from engine.design.critical_values import critical_value_slice
from engine.design.robustness import robustness
from engine.space.configuration_space import SpaceOptions, explore, rotor_angles, winding


def timed(fn):  # noqa: ANN001, ANN201 - tiny helper
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def slice_http(resolution: int) -> tuple[float, dict]:
    """Time of POST /v1/analysis/critical-values (four-bar, (L2, L3) in [0.3, 2.2]^2) through
    the real service (uvicorn on a loopback port, worker processes as deployed), after a
    warm-up request on a small slice."""
    import httpx
    from harness import served

    with served() as url, httpx.Client(base_url=url, timeout=300.0) as client:
        linkage = client.get("/v1/presets/four-bar", params={"L2": 1.2}).json()
        axes = [{"bar": "L2", "min": 0.3, "max": 2.2}, {"bar": "L3", "min": 0.3, "max": 2.2}]

        def once(res: int) -> dict:
            r = client.post("/v1/analysis/critical-values",
                            json={"linkage": linkage, "axes": axes,
                                  "options": {"resolution": res}})
            r.raise_for_status()
            return dict(r.json())

        once(8)  # warm-up: worker processes started, imports done
        return timed(lambda: once(resolution))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--json", type=Path, default=Path("bench/results/maps.json"))
    args = parser.parse_args()
    rows = []

    def record(name: str, seconds: float, detail: str) -> None:
        rows.append({"benchmark": name, "seconds": seconds, "detail": detail})
        print(f"{name:<62} {seconds:9.3f} s   {detail}")

    four_bar = build_preset("four-bar", {"L2": 1.2})
    for res in (48, 200):
        t, s = timed(lambda r=res: critical_value_slice(
            four_bar, [("L2", 0.3, 2.2), ("L3", 0.3, 2.2)], resolution=r))
        record(f"four-bar slice (L2, L3), resolution {res}x{res} (engine)", t,
               f"{len(s.curves)} curves, {len(s.regions)} regions")
    t, body = slice_http(200)
    record("four-bar slice (L2, L3), resolution 200x200 (HTTP, POST critical-values)", t,
           f"{len(body['curves'])} curves, {len(body['regions'])} regions")
    gated = build_preset("gated-kl-chain", {"n": 4, "gate": 2})
    t, s = timed(lambda: critical_value_slice(
        gated, [("L2", 1.0, 3.0), ("D", 1.0, 3.5)], resolution=48,
        options=SpaceOptions(angles=12, random_starts=2, max_components=4)))
    record("gate slice (L2, D), 4-rotor chain, resolution 48", t,
           f"{len(s.curves)} curves, {len(s.regions)} regions")
    t, m = timed(lambda: robustness(four_bar))
    record("robustness margin, four-bar, all bars adjustable", t, f"margin {m.margin:.6f}")
    for n, d in ((20, 2.3), (20, 2.7)):
        lk = build_preset("gated-kl-chain", {"n": n, "gate": n // 2, "D": d})
        t, res = timed(lambda lk=lk: explore(lk, options=SpaceOptions(max_components=2)))
        comp = next(c for c in res.components if c.through_start)
        turns = {abs(winding(a, True)) for k, a in rotor_angles(lk, comp.points).items()
                 if k.startswith("r")}
        record(f"gated chain n={n}, D={d}: configuration space (budget 2)", t,
               f"{'ungated' if turns == {1} else 'gated'} (rotor turns {sorted(turns)})")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(rows, indent=2) + "\n")


if __name__ == "__main__":
    main()
