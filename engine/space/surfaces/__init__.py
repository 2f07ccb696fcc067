"""The configuration space of a two-degree-of-freedom linkage (``M - E = 2``): every compact
component as a triangulated surface with its topology (issue 25).

Modules: :mod:`.geometry` (oriented tangent frames, projection), :mod:`.mesh` (the marching
triangulation), :mod:`.homology` (Euler characteristic, orientability, Betti numbers over Z/2
and Q), :mod:`.morse` (critical points of a generic height: seeds on every compact component
and the Morse check), :mod:`.cones` (every critical point by homotopy, the fans the mesh grows
from around each cone's apex, the apexes' Morse terms and their resolution in the complex),
:mod:`.five_bar` (seeds and critical points of five-bar chains, planar or spherical, derived
from their crank angles where the height's homotopy is too big), :mod:`.explore` (the entry
point :func:`explore_surfaces`).
"""

from engine.space.surfaces.explore import (
    SurfaceComponent,
    SurfaceOptions,
    SurfaceResult,
    explore_surfaces,
)
from engine.space.surfaces.geometry import require_two_dof
from engine.space.surfaces.homology import Homology, manifold_defects, surface_homology

__all__ = [
    "Homology",
    "SurfaceComponent",
    "SurfaceOptions",
    "SurfaceResult",
    "explore_surfaces",
    "manifold_defects",
    "require_two_dof",
    "surface_homology",
]
