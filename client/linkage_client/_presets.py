"""One method per preset route (``getPresetFourBar`` is ``get_preset_four_bar``), for both
clients: each calls the client's ``get_preset``, so it returns a ``Linkage`` from ``Client``
and an awaitable of one from ``AsyncClient``."""

from __future__ import annotations

from typing import Generic, TypeVar

R = TypeVar("R")


class PresetRoutes(Generic[R]):
    """The preset routes; the parameters are the preset's (all optional, see ``list_presets``)."""

    def get_preset(self, name: str, /, **parameters: float) -> R:
        raise NotImplementedError

    def get_preset_four_bar(self, **parameters: float) -> R:
        """``a, L1, L2, L3, theta, side``: the planar four-bar of the paper."""
        return self.get_preset("four-bar", **parameters)

    def get_preset_three_rotor(self, **parameters: float) -> R:
        """``a, r1, r2, r3, L1, L2, phi, theta, side1, side3``: the paper's three-rotor."""
        return self.get_preset("three-rotor", **parameters)

    def get_preset_kl_chain(self, **parameters: float) -> R:
        """``n, a, r, l, theta, side``: a Kane-Lubensky rotor chain."""
        return self.get_preset("kl-chain", **parameters)

    def get_preset_gated_kl_chain(self, **parameters: float) -> R:
        """``n, a, r, l, gate, D, L1, L2, theta, side``: the paper's gated chain."""
        return self.get_preset("gated-kl-chain", **parameters)

    def get_preset_tetrahedron(self, **parameters: float) -> R:
        """``a``: a regular tetrahedron (3D)."""
        return self.get_preset("tetrahedron", **parameters)

    def get_preset_octahedron(self, **parameters: float) -> R:
        """``a``: a regular octahedron (3D)."""
        return self.get_preset("octahedron", **parameters)

    def get_preset_bricard_line(self, **parameters: float) -> R:
        """``x0, x2, y2, z2, x4, y4, z4``: Bricard's line-symmetric octahedron (3D)."""
        return self.get_preset("bricard-line", **parameters)

    def get_preset_bricard_plane(self, **parameters: float) -> R:
        """``y0, z0, y1, z1, x2, x4, y4``: Bricard's plane-symmetric octahedron (3D)."""
        return self.get_preset("bricard-plane", **parameters)

    def get_preset_three_prism(self, **parameters: float) -> R:
        """``ratio, twist, dx, dy``: the three-prism."""
        return self.get_preset("three-prism", **parameters)

    def get_preset_three_prism_flexible(self, **parameters: float) -> R:
        """``ratio, twist, dx, dy``: the three-prism at its flexible ratio."""
        return self.get_preset("three-prism-flexible", **parameters)

    def get_preset_k33_conic(self, **parameters: float) -> R:
        """``rx, ry``: K_{3,3} on a conic."""
        return self.get_preset("k33-conic", **parameters)

    def get_preset_k33_dixon(self, **parameters: float) -> R:
        """``x0, x2, x4, y1, y3, y5``: Dixon's flexible K_{3,3}."""
        return self.get_preset("k33-dixon", **parameters)

    def get_preset_cn_symmetric_four_regular(self, **parameters: float) -> R:
        """``n`` (even): a C_n-symmetric four-regular framework."""
        return self.get_preset("cn-symmetric-four-regular", **parameters)

    def get_preset_rotor_chain3d(self, **parameters: float) -> R:
        """``n, a, r, l, h, tilt, theta, side``: a rotor chain in 3D."""
        return self.get_preset("rotor-chain-3d", **parameters)

    def get_preset_pentagon(self, **parameters: float) -> R:
        """``L0, L1, L2, L3, L4, theta1, theta2, side``: a planar pentagon, L0 pinned (D = 2)."""
        return self.get_preset("pentagon", **parameters)

    def get_preset_five_bar(self, **parameters: float) -> R:
        """``a, L1, L2, L3, L4, theta1, theta2, side``: a planar five-bar (D = 2)."""
        return self.get_preset("five-bar", **parameters)

    def get_preset_spherical_four_bar(self, **parameters: float) -> R:
        """``R, g, L1, L2, L3, theta1, side``: a spherical four-bar of bars in 3D (D = 1)."""
        return self.get_preset("spherical-four-bar", **parameters)

    def get_preset_sphere_slider(self, **parameters: float) -> R:
        """``d, r, s, c, theta, side``: a sphere and a slider in 3D, a torus (D = 2)."""
        return self.get_preset("sphere-slider", **parameters)

    def get_preset_spherical_five_bar(self, **parameters: float) -> R:
        """``R, g, L1, L2, L3, L4, theta1, theta2, side``: a spherical five-bar of bars in 3D
        (D = 2)."""
        return self.get_preset("spherical-five-bar", **parameters)

    def get_preset_spatial_quadrilateral(self, **parameters: float) -> R:
        """``l1, l2, l3, l4, phi, theta``: a spatial quadrilateral, ``v2`` sliding in a plane
        (D = 2)."""
        return self.get_preset("spatial-quadrilateral", **parameters)
