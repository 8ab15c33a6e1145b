"""What a shader program sees of n shading points: the hits' geometry, as (3, n) bundles
and (n,) arrays in the render precision.

Attributes a program does not read are never computed: each is made on first use and kept
for the rest of the program's run (``functools.cached_property``).  The hits of one batch
share one ``ShadingPoints``; ``take`` makes the points of a subset (one material's hits).

Named coordinates the input nodes read (``coordinate(name)``, each (3, n); a per-hit number
is given as a coordinate and read from its first row).  Where a node's default is not zero
it applies only when the integrator gives no source of that name (``point_data``):

* Texture Coordinate: 'generated' (the mesh's texture space: (local - (location - size)) /
  (2 size)), 'uv', 'object' (local position), 'camera' (Cycles' camera space: x right, y
  up, z along the view), 'window' (the frame, 0 to 1 across and up, z 0); with From
  Instancer 'instancer_generated' and 'instancer_uv'.
* Geometry: 'tangent', 'parametric' (Cycles' (1 - u - v, u, 0)), 'pointiness' (0.5
  without), 'random_per_island'.
* The hit's object: 'object_axis_x', 'object_axis_y', 'object_axis_z' (its world matrix's
  columns: Vector Transform and Texture Coordinate's Normal; world space without them),
  'object_location', 'object_color' (white without), 'object_alpha' (1 without),
  'object_index', 'material_index' (pass indices), 'object_random'.
* 'object_incoming': 'incoming' taken into the object's space as a normal (by the transpose
  of the world matrix's 3 x 3 part, normalised), what Cycles links to an IES Texture's
  unlinked Vector (Geometry Incoming through a world-to-object Vector Transform); made from
  'incoming' and the object axes, so world space without them.
* Attribute: '<prefix>:<name>' and '<prefix>_alpha:<name>' (alpha 1 without) with prefix
  'attribute', 'object_attribute', 'instancer_attribute' or 'view_layer_attribute' by the
  node's type.
* Light Path: 'ray_type' (the ray's ``input_nodes.RAY_*`` bits; a camera ray without),
  'ray_length' (from the ray's origin: a camera ray starts on the near clipping plane),
  'ray_depth', 'diffuse_depth', 'glossy_depth', 'transparent_depth', 'transmission_depth',
  'portal_depth'.
"""

from __future__ import annotations


import numpy as np

from .point_data import ObjectFrame

#: The derived coordinate an IES Texture's unlinked Vector reads (module docstring).
OBJECT_INCOMING = "object_incoming"


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
                 sources=None, jacobians=None, footprint=None):
        self.position = position
        self.normal = normal
        self.true_normal = true_normal
        self.incoming = incoming
        n = position.shape[1]
        self.backfacing = np.zeros(n, bool) if backfacing is None else backfacing
        self._sources = dict(sources or {})
        self._jacobians = dict(jacobians or {})
        self._made: dict[str, np.ndarray] = {}
        #: (n,) how wide a ray's footprint is at each point (its pixel's spread times the
        #: distance it travelled), what Cycles' ray differentials give a Bump node.
        self.footprint = np.zeros(n, position.dtype) if footprint is None else footprint

    def shifted(self, offset) -> "ShadingPoints":
        """These points moved by ``offset`` (3, n) along their surface (a Bump node's
        neighbouring points): each coordinate with a Jacobian (its derivatives by position)
        moves with it, to first order, as Cycles' bump evaluation moves texture
        coordinates by their differentials; the others stay."""
        def moved(name):
            def made():
                value = self.coordinate(name)
                jacobian = self._jacobians.get(name)
                if jacobian is None:
                    return value
                return value + np.einsum("ijk,jk->ik", jacobian(), offset)
            return made

        sources = {name: moved(name) for name in self._sources}
        shifted = ShadingPoints(self.position + offset, self.normal, self.true_normal,
                                self.incoming, self.backfacing, sources, self._jacobians,
                                self.footprint)
        return shifted

    def __len__(self) -> int:
        return self.position.shape[1]

    @property
    def dtype(self) -> np.dtype:
        return self.position.dtype

    def coordinate(self, name: str) -> np.ndarray:
        """(3, n) the texture coordinate ``name``: 'position' and 'normal' and 'incoming'
        are the attributes above, 'object_incoming' is made from them (module docstring);
        others ('generated', 'object', 'uv', 'uv:<map name>', 'camera', 'window',
        'reflection') come from the sources the integrator gave, made on first use.  A
        name with no source is zero, as Cycles reads an attribute a mesh does not have."""
        if name in ("normal", "incoming") or (name == "position"
                                               and "position" not in self._sources):
            return getattr(self, name)
        made = self._made.get(name)
        if made is None:
            source = self._sources.get(name)
            if source is not None:
                made = source()
            elif name == OBJECT_INCOMING:
                made = ObjectFrame(self).to_object(self.incoming, "NORMAL")
            else:
                made = np.zeros((3, len(self)), self.dtype)
            self._made[name] = made
        return made
