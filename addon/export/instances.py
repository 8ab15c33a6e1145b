"""Geometry Nodes instances, read in bulk from the instancer's evaluated geometry.

``depsgraph.object_instances`` yields every instance as its own Python object; reading each
one's matrix costs about 2 microseconds (measured with pip bpy 5.0.1: 0.18 s for 10^5
instances), so a million instanced spheres would spend seconds in Python.  Blender 4.3+
exposes an object's evaluated geometry (``Object.evaluated_geometry()``): its instances are a
point cloud whose ``instance_transform`` (4x4, column-major) and ``.reference_index``
attributes ``foreach_get`` reads in one call each, and ``instance_references()`` lists what
each index draws.

An instancer is read in bulk when all of its instances come from that instance point cloud,
which holds for a MESH or POINTCLOUD object with a Geometry Nodes modifier, no particle
systems and no vertex/face instancing, whose references are all plain meshes (no nested
instances, collections or objects).  Its instances are then handed to the mesh exporter as
arrays.  When every instancer of the scene is read so, the depsgraph's instances are not
walked at all (``covers``): the export visits ``depsgraph.objects`` only; otherwise the walk
passes over a bulk-read instancer's instances with one name look-up each.  Anything else
(collection instances, particles, vertex and face instances, nested or object instances)
goes through the walk, one instance at a time, where ``InstanceWalk`` works out how to
export each (instancer, object, mesh) once and then only copies matrices.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from ..compat import EVALUATED_GEOMETRY
from .geometry import STORED_INT, read_array
from .meshes import EVALUATED_AS_MESH, terminator_offset


def _makes_instances(obj) -> bool:
    """Whether a Geometry Nodes object's evaluated geometry yields anything but its own
    component (instances, or another kind of geometry, which come as instances); True where
    Blender cannot tell (``compat.EVALUATED_GEOMETRY``): the walk finds out."""
    if not EVALUATED_GEOMETRY:
        return True
    geometry = obj.evaluated_geometry()
    points = geometry.instances_pointcloud()
    if points is not None and len(points.points):
        return True
    own = {'MESH': 'mesh', 'POINTCLOUD': 'pointcloud'}.get(obj.type)
    return any(getattr(geometry, kind) is not None for kind in
               ('mesh', 'pointcloud', 'curves', 'volume', 'grease_pencil') if kind != own)


def _plain_mesh(reference):
    """The mesh of a GeometrySet reference holding a mesh and nothing else, else None."""
    if not hasattr(reference, "instances_pointcloud") or reference.mesh is None:
        return None
    nested = reference.instances_pointcloud()
    if nested is not None and len(nested.points):
        return None
    if reference.pointcloud is not None or reference.curves is not None or \
            reference.volume is not None or reference.grease_pencil is not None:
        return None
    return reference.mesh


class InstanceExporter:
    """Decides, once per instancer, whether its instances are read in bulk (module
    docstring), and if so exports them through ``meshes``."""

    def __init__(self, context, meshes, visible):
        self.context = context
        self.meshes = meshes
        self.visible = visible
        self.sources: dict = {}  # instancer name -> (geometry, points, meshes) or None
        self.bulk: dict[str, bool] = {}   # instancer name -> its instances were read in bulk

    def _bulk_source(self, parent):
        """(evaluated geometry, instance point cloud, mesh per reference) when the
        instancer's instances can be read in bulk (module docstring), else None.  The
        geometry is kept: the meshes it hands out live only as long as it does."""
        name = parent.name
        if name not in self.sources:
            self.sources[name] = self._read_source(parent)
        return self.sources[name]

    @staticmethod
    def _read_source(parent):
        if not EVALUATED_GEOMETRY or \
                parent.type not in ('MESH', 'POINTCLOUD') or parent.instance_type != 'NONE' or \
                len(parent.particle_systems) or \
                not any(m.type == 'NODES' for m in parent.modifiers):
            return None
        geometry = parent.evaluated_geometry()
        points = geometry.instances_pointcloud()
        if points is None or not len(points.points):
            return None
        # Any other kind of geometry would come as instances of the instancer too.
        own = 'mesh' if parent.type == 'MESH' else 'pointcloud'
        others = [kind for kind in ('mesh', 'pointcloud', 'curves', 'volume', 'grease_pencil')
                  if kind != own and getattr(geometry, kind) is not None]
        if others:
            return None
        references = geometry.instance_references()
        meshes = [_plain_mesh(reference) for reference in references]
        if any(mesh is None for mesh in meshes):
            return None
        return geometry, references, points, meshes

    def handles(self, instance) -> bool:
        """True if this instance (``is_instance``) was exported with its instancer's bulk."""
        parent = instance.parent
        if parent is None:
            return False
        name = parent.name
        done = self.bulk.get(name)
        if done is None:
            done = self.bulk[name] = self.export_instancer(instance, parent)
        return done

    def export_instancer(self, entry, parent) -> bool:
        """Export an instancer's instances in bulk if they can be (True), else False.  entry:
        one of its depsgraph entries (an instance, or the instancer's own), for visibility."""
        if not parent.modifiers:
            # No Geometry Nodes modifier, no bulk: asked of every object when the walk is
            # skipped, this spares each plain object its name look-up and four RNA reads.
            return False
        source = self._bulk_source(parent)
        if source is None:
            return False
        self.bulk[parent.name] = True
        if not self.visible(entry):
            return True  # hidden with its instancer: nothing to export, nothing to warn about
        _, _, points, meshes = source
        count = len(points.points)
        transforms = np.empty(count * 16, np.float32)
        points.attributes["instance_transform"].data.foreach_get("value", transforms)
        # Column-major 4 x 4 per instance: transposed, the rows.
        local = transforms.reshape(count, 4, 4).transpose(0, 2, 1).astype(np.float64)
        world = np.matmul(np.asarray(parent.matrix_world, np.float64), local)
        indices = self._reference_indices(points, count)
        holdout = self.context.is_holdout(parent)
        offset = terminator_offset(parent)
        for index, mesh in enumerate(meshes):
            chosen = indices == index if len(meshes) > 1 else slice(None)
            self.meshes.add_bulk(mesh, tuple(mesh.materials), world[chosen],
                                 f"{mesh.name} (instanced by {parent.name})", holdout, offset)
        return True

    def covers(self, objects, layer_objects) -> bool:
        """True when no object but bulk-read instancers makes instances, so the depsgraph's
        instances need not be walked at all (``scene``): no collection, vertex, face or
        particle instancing, no curve-like object (its mesh comes as an instance), and every
        Geometry Nodes object either makes no instances or is read in bulk.

        objects: ``depsgraph.objects``; layer_objects: the view layer's objects
        (``depsgraph.view_layer_eval.objects``).  A render depsgraph leaves out of
        ``depsgraph.objects`` an instancer not rendered itself (``show_instancer_for_render``
        off: a particle emitter, a vertex or face instancer) while its instances render, so
        when the view layer holds objects the depsgraph does not list, any instancer among
        them means a walk."""
        if len(layer_objects) != len(objects) and \
                any(obj.is_instancer for obj in layer_objects):
            return False
        for obj in objects:
            if obj.type in EVALUATED_AS_MESH or obj.is_instancer:
                return False
            if any(m.type == 'NODES' for m in obj.modifiers) and \
                    self._bulk_source(obj) is None and _makes_instances(obj):
                return False
        return True

    @staticmethod
    def _reference_indices(points, count: int) -> np.ndarray:
        attribute: Optional[object] = points.attributes.get(".reference_index")
        if attribute is None:
            return np.zeros(count, np.int64)
        return read_array(attribute.data, "value", 1, np.int64, stored=STORED_INT)


class InstanceWalk:
    """The depsgraph's instances that are not read in bulk, one at a time, at the cost of a
    few reads each.

    How an instance is exported (whether its instancer was read in bulk, whether it is
    visible, its type, its mesh's ``MeshUse``, the name it goes under) depends only on its
    instancer, its original object and its evaluated data (and, in a viewport depsgraph,
    whether a particle system made it: ``scene``'s visibility), so it is worked out once, for
    the first instance of each such key, by the full path (``export_entry``); the others
    cost six RNA reads, a dictionary look-up and a 64-byte matrix copy.  (``export_scene``
    of vertex instances in a viewport depsgraph, pip bpy 5.0.1, load ~6: 19 microseconds an
    instance when each took the full path, 5.1 with this: 0.51 s for 100,000.)  The key
    holds the evaluated data's pointer because the depsgraph hands every Geometry Nodes
    instance the same temporary object with another mesh.
    """

    SKIP = "skip"    # bulk-read with its instancer, hidden, or drawing nothing
    WHOLE = "whole"  # not a mesh: every instance takes the full path

    def __init__(self, bulk: InstanceExporter, meshes, visible, export_entry,
                 particles_matter: bool):
        self.bulk = bulk
        self.meshes = meshes
        self.visible = visible
        self.export_entry = export_entry
        self.particles_matter = particles_matter
        self.plans: dict = {}

    def __call__(self, instance) -> None:
        parent = instance.parent
        obj = instance.object
        data = obj.data
        key = (parent.as_pointer() if parent is not None else 0, obj.original.as_pointer(),
               data.as_pointer() if data is not None else 0)
        if self.particles_matter:
            key += (instance.particle_system is not None,)
        plan = self.plans.get(key)
        if plan is None:
            plan = self.plans[key] = self._plan(instance, obj)
        if plan is self.SKIP:
            return
        if plan is self.WHOLE:
            self.export_entry(instance)
            return
        plan.add(instance.matrix_world)

    def _plan(self, instance, obj):
        if self.bulk.handles(instance) or not instance.show_self or \
                not self.visible(instance):
            return self.SKIP
        if obj.type == 'MESH':
            return self.meshes.placement(instance)
        return self.WHOLE
