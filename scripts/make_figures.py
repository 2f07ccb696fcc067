"""Write the README's pictures, docs/figures/*.svg (``python scripts/make_figures.py``).

Each is what the figure endpoint answers for the request shown in the README, made by the
same job the endpoint runs in its worker (no server needed)."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET = ROOT / "docs" / "figures"


def main() -> None:
    sys.path.insert(0, str(ROOT))
    from engine.catalogue.presets import build_preset
    from service import figures, mappers
    from service.config import Settings
    from service.schemas.figures import (
        CriticalValuesFigureRequest,
        LinkageFigureRequest,
        SpaceFigureRequest,
        SplittingFigureRequest,
    )

    settings = Settings()

    def linkage(name: str, **params: float) -> dict[str, object]:
        return mappers.linkage_out(build_preset(name, params, settings.limits)).model_dump(
            exclude_none=True)

    four_bar = linkage("four-bar")  # equilateral: the paper's three branch points
    jobs = {
        "linkage.svg": (figures.linkage_figure, LinkageFigureRequest.model_validate(
            {"linkage": linkage("gated-kl-chain", n=5, gate=2), "show": ["zero_modes"]})),
        "configuration-space.svg": (figures.configuration_space_figure,
                                    SpaceFigureRequest.model_validate({"linkage": four_bar})),
        "critical-values.svg": (figures.critical_values_figure, CriticalValuesFigureRequest
                                .model_validate({"linkage": four_bar, "axes": [
                                    {"bar": "L2", "min": 0.4, "max": 2.5},
                                    {"bar": "L3", "min": 0.4, "max": 2.5}]})),
        "splitting.svg": (figures.splitting_figure, SplittingFigureRequest.model_validate(
            {"linkage": four_bar, "perturbation": {"L2": 0.01}})),
    }
    TARGET.mkdir(parents=True, exist_ok=True)
    for name, (job, body) in jobs.items():
        (TARGET / name).write_bytes(job(body, settings))  # type: ignore[operator]
        print(f"wrote {(TARGET / name).relative_to(ROOT)}")


if __name__ == "__main__":
    main()
