"""The argument of a critical-value slice (:func:`engine.design.critical_values.
critical_value_slice`): whether its curves are every critical curve in the box and its regions'
counts exact, and the sentence that says what is proved when they are not; the sweeps' report
keys."""

from __future__ import annotations

import numpy as np

from engine.design.slice_regions import THIN_REFINE, Region
from engine.design.slice_scan import Scan
from engine.design.slice_turning import TurningFound
from engine.model.budget import ARGUMENT_DERIVED, ARGUMENT_PROVED, Argument


def _scan_details(scan: Scan | None) -> dict[str, object]:
    """The sweeps in the search report (none for a closed form)."""
    if scan is None:
        return {}
    return {"sweeps": scan.planned,
            "sweeps_complete": sum(s.success for s in scan.lines),
            "sweep_paths": scan.paths,
            "sweep_step": scan.step}


def _slice_argument(lines: list[np.ndarray] | None, regions: list[Region],
                    scan: Scan | None = None, thin_unresolved: int = 0,
                    turning: TurningFound | None = None, open_curves: int = 0,
                    planes_of: str = "") -> tuple[Argument | None, str]:
    """A slice is complete when its curves are every critical curve in the box and every
    region's count is exact (its exploration complete, with an argument). The curves are
    every one: from a closed form (``planes_of`` says what each curve is: a one-dyad chain's
    or a rotor chain's critical hyperplanes met with the plane, a three-rotor's curves), or
    traced from every critical configuration on the box's edges (the sweeps) and from every
    turning point of a curve in the box (a closed curve inside the box holds one), each traced
    to its end. A traced slice without all of these says what is proved."""
    inexact = sum(r.argument is None for r in regions)
    if lines is None:
        labels = (f"{len(regions) - inexact} of {len(regions)} regions' component counts "
                  "exact, the others lower bounds")
        if scan is None or not scan.complete:
            what = scan.summary() if scan is not None else "no scanline"
            return None, (f"the curves were traced from seed lengths ({what}): no argument "
                          f"proves that every critical curve crossing the box was found; {labels}")
        sweeps = ("for each axis held, the critical configurations on the box's two edges "
                  f"across it (every isolated solution of a square system: a {scan.paths}-path "
                  "total-degree homotopy at a generic length, its finite solutions followed to "
                  "each edge, every path ended)")
        if turning is not None and turning.complete:
            gaps = [f"{n} {what}" for n, what in (
                (inexact, "regions' component counts are lower bounds"),
                (open_curves, "curves stopped before their end"),
                (thin_unresolved, "places where curves run closer than "
                                  f"1/{THIN_REFINE} of a raster cell")) if n]
            if not gaps:
                return ARGUMENT_PROVED, (
                    f"every critical curve crossing the box was traced: {sweeps}; "
                    f"{turning.summary()}; every one of the {len(regions)} regions' component "
                    "counts is exact (" + ", ".join(sorted({str(r.argument) for r in regions}))
                    + ")")
            return None, (f"every critical curve crossing the box was found ({sweeps}; "
                          f"{turning.summary()}), but " + ", ".join(gaps))
        what = turning.summary() if turning is not None else "no turning points"
        return None, (
            "every critical curve crossing the box was found, but for a closed curve born and "
            f"gone within one sweep step ({scan.step:.3g}) of both axes ({what}): {sweeps} "
            "and, followed from one edge to the other in steps of at most that, wherever a "
            f"curve turns or enters the box between two steps; {labels}")
    if inexact:
        return None, (f"the curves are the closed form's, but {inexact} of {len(regions)} "
                      "regions' component counts are lower bounds")
    if thin_unresolved:
        return None, (f"the curves are the closed form's, but at {thin_unresolved} places they "
                      f"run closer than 1/{THIN_REFINE} of a raster cell: a region between them "
                      "may be missing (a finer resolution resolves it)")
    return ARGUMENT_DERIVED, (
        f"every critical curve in the box is {planes_of}; every one of the {len(regions)} "
        "regions' component counts is exact ("
        + ", ".join(sorted({str(r.argument) for r in regions})) + ")")
