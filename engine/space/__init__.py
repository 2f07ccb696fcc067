"""The space floor: whole configuration spaces. The tracer and its compiled kernel
(:mod:`.trace`, :mod:`.trace_kernel`), seeds (:mod:`.assembly`), walks (:mod:`.kinematics`),
rotor-chain counts (:mod:`.chain_count`), planar dyad chains in closed form (:mod:`.dyads`), 3D
hinged rotor chains from their cells (:mod:`.hinge_chain`, :mod:`.hinge_sheets`) and the
search of every component and critical point (:mod:`.configuration_space`).
"""

from engine.space.chain_count import chain_components
from engine.space.configuration_space import (
    Component,
    SpaceOptions,
    SpaceResult,
    explore,
    find_critical_points,
)
from engine.space.trace import TraceOptions, correct, trace_curve

__all__ = [
    "Component",
    "SpaceOptions",
    "SpaceResult",
    "TraceOptions",
    "chain_components",
    "correct",
    "explore",
    "find_critical_points",
    "trace_curve",
]
