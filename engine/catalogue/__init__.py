"""The catalogue floor: named linkages (the paper's presets and the 3D frameworks), built from
the model alone (:mod:`.presets`, :mod:`.catalogue`).
"""

from engine.catalogue.presets import PRESETS, Preset, build_preset, resolve_parameters

__all__ = [
    "PRESETS",
    "Preset",
    "build_preset",
    "resolve_parameters",
]
