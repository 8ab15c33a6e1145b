"""Point clouds -> ``core.SphereSet``: one analytic sphere per point.

Blender's PointCloud objects, and the points Geometry Nodes makes (Mesh to Points, Distribute
Points, Points, which the depsgraph yields as POINTCLOUD instances), render in Cycles as
spheres of the ``radius`` attribute (0.01 where a cloud has none: Blender's default) around
``position``.  Both attributes are read with one ``foreach_get`` each, and so is
``material_index`` where it exists (slots as for meshes: past the last slot, the last one).
The world matrix must be a rotation times a uniform scale, which scales the radii (Cycles
draws a non-uniformly scaled cloud's points as ellipsoids, which Glint cannot: such a cloud
is skipped with a warning; one whose matrix is not finite draws nothing, as in Cycles).
Points that draw nothing in Cycles (radius <= 0, a position or radius not finite) are left
out by the core, which says how many (``core.SphereSet``).
"""

from __future__ import annotations

import numpy as np

from ...core import SceneError, SphereSet
from .errors import ExportError
from .geometry import degenerate_transforms, read_array, uniform_scales

#: Cycles' radius for points that have no ``radius`` attribute.
DEFAULT_POINT_RADIUS = 0.01


def _attribute(cloud, name: str, width: int, dtype, default):
    attribute = cloud.attributes.get(name)
    if attribute is None:
        return None if default is None else np.full(len(cloud.points), default, dtype)
    field = "vector" if width == 3 else "value"
    return read_array(attribute.data, field, width, dtype)


def export_point_cloud(context, obj, matrix_world, name: str) -> None:
    """An evaluated POINTCLOUD object (placed by ``matrix_world``) -> a SphereSet in the
    context, or a skipped entry naming why it cannot be drawn."""
    cloud = obj.data
    count = len(cloud.points)
    if count == 0:
        return
    matrix = np.asarray(matrix_world, np.float64)
    if not np.isfinite(matrix).all():
        context.skip(name, "matrix not finite: draws nothing, as in Cycles")
        return
    if degenerate_transforms(matrix[None])[0]:
        context.skip(name, "zero scale: draws nothing")
        return
    scales, uniform = uniform_scales(matrix[None])
    if not uniform[0]:
        context.skip(name, "non-uniformly scaled point cloud: its points would be ellipsoids")
        return
    positions = _attribute(cloud, "position", 3, np.float32, None)
    radii = _attribute(cloud, "radius", 1, np.float32, DEFAULT_POINT_RADIUS)
    slots = _attribute(cloud, "material_index", 1, np.int32, 0)
    holdout = context.is_holdout(obj)
    materials = [context.material(slot.material, name, holdout)
                 for slot in obj.material_slots] or [context.material(None, name, holdout)]
    with np.errstate(invalid="ignore", over="ignore"):  # (the core leaves such points out)
        centers = positions.astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
    try:
        context.sphere_sets.append(SphereSet(
            centers=centers, radii=radii.astype(np.float64) * scales[0],
            material_indices=np.clip(slots, 0, len(materials) - 1), materials=tuple(materials),
            name=name))
    except SceneError as error:
        raise ExportError(f"point cloud '{name}': {error}") from None
