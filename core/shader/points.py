"""What a shader program sees of n shading points: the hits' geometry, as (3, n) bundles
and (n,) arrays in the render precision.

Attributes a program does not read are never computed: each is made on first use and kept
for the rest of the program's run (``functools.cached_property``).  The hits of one batch
share one ``ShadingPoints``; ``take`` makes the points of a subset (one material's hits).
"""

from __future__ import annotations


import numpy as np


class ShadingPoints:
    """n shading points.

    position: (3, n) world-space hit points; for the world (rays that left the scene), the
        unit direction each ray travels, as Cycles' P of the background: an Environment
        Texture's unlinked Vector reads it (``shader.images``).
    normal: (3, n) unit shading normals facing the incoming ray's side (smooth, bumped
        later by Bump and Normal Map nodes through the program's Normal sockets).
    true_normal: (3, n) unit geometric normals on the same side.
    incoming: (3, n) unit vectors from the points back along the ray (Cycles' ``wi``: the
        Geometry node's Incoming).
    backfacing: (n,) bool, the ray arrived at the back of the surface.
    coordinates: {name: (3, n)} texture coordinates the exporter or the hit provide
        (``generated``, ``object``, ``uv``: see ``coordinate``), computed lazily by
        ``sources`` where given.  ``object_normal`` is the shading normal (as ``normal``,
        facing the incoming ray) in object space, which a Box-projected Image Texture
        weighs its faces by.
    """

    def __init__(self, position, normal, true_normal, incoming, backfacing=None,
                 sources=None):
        self.position = position
        self.normal = normal
        self.true_normal = true_normal
        self.incoming = incoming
        n = position.shape[1]
        self.backfacing = np.zeros(n, bool) if backfacing is None else backfacing
        self._sources = dict(sources or {})
        self._made: dict[str, np.ndarray] = {}

    def __len__(self) -> int:
        return self.position.shape[1]

    @property
    def dtype(self) -> np.dtype:
        return self.position.dtype

    def coordinate(self, name: str) -> np.ndarray:
        """(3, n) the texture coordinate ``name``: 'position' and 'normal' and 'incoming'
        are the attributes above; others ('generated', 'object', 'uv', 'uv:<map name>',
        'camera', 'window', 'reflection') come from the sources the integrator gave,
        made on first use.  A name with no source is zero, as Cycles reads an attribute a
        mesh does not have."""
        if name in ("position", "normal", "incoming"):
            return getattr(self, name)
        made = self._made.get(name)
        if made is None:
            source = self._sources.get(name)
            made = (source() if source is not None
                    else np.zeros((3, len(self)), self.dtype))
            self._made[name] = made
        return made
