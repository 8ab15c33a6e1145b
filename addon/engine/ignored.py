"""Scene settings that change what Cycles renders and that Glint does not honour, named in one
warning per render (``ignored_settings_warning``), so nothing is dropped silently.

Glint has no motion blur, no depth of field with anti-aliasing off (whose one ray per
pixel cannot sample the lens), no anamorphic aperture,
shadow catchers, indirect-only collections, Freestyle, multiview, view-layer material
overrides, per-object ray visibility or lights without shadows, and the article semantics
has no holdouts; each of these, where the scene uses it, is listed.
"""

from __future__ import annotations

#: Cycles' per-object ray visibility flags and how the Object properties name them.
RAY_VISIBILITY = {"visible_camera": "camera", "visible_shadow": "shadow",
                  "visible_diffuse": "diffuse", "visible_glossy": "glossy",
                  "visible_transmission": "transmission"}


#: Object types whose ray visibility and holdout flags mean nothing to a render of geometry.
NOT_GEOMETRY = {'LIGHT', 'CAMERA', 'EMPTY', 'LIGHT_PROBE', 'SPEAKER', 'ARMATURE', 'LATTICE'}


def _layer_collections(layer_collection):
    yield layer_collection
    for child in layer_collection.children:
        yield from _layer_collections(child)


def _names(items, limit=5) -> str:
    items = sorted(items)
    shown = ", ".join(f"'{name}'" for name in items[:limit])
    return shown + (f" and {len(items) - limit} more" if len(items) > limit else "")


def ignored_settings(depsgraph, camera_override=None) -> list[str]:
    """The settings of the evaluated scene Glint ignores (module docstring), as phrases."""
    scene, view_layer = depsgraph.scene_eval, depsgraph.view_layer
    render = scene.render
    found = []
    if render.use_motion_blur:
        found.append("motion blur")
    camera = camera_override if camera_override is not None else scene.camera
    if camera is not None and camera.type == 'CAMERA' and camera.data.dof.use_dof:
        if scene.glint.anti_aliasing == 'OFF':
            found.append(f"depth of field (camera '{camera.name}'), which needs anti-aliasing "
                         f"samples")
        if camera.data.dof.aperture_ratio != 1.0:
            found.append(f"the aperture ratio of camera '{camera.name}'")
    if render.use_freestyle:
        found.append("Freestyle")
    if render.use_multiview:
        found.append("stereoscopy (multiview)")
    if getattr(view_layer, "material_override", None) is not None:
        found.append(f"the material override of view layer '{view_layer.name}'")
    # Holdouts are rendered (``export``), except in the article's model.
    article = scene.glint.semantics == 'ARTICLE'
    holdout, indirect = [], []
    for layer_collection in _layer_collections(view_layer.layer_collection):
        if layer_collection.exclude:
            continue
        if layer_collection.holdout and article:
            holdout.append(layer_collection.name)
        if layer_collection.indirect_only:
            indirect.append(layer_collection.name)
    if holdout:
        found.append(f"holdout collections {_names(holdout)} (article semantics)")
    if indirect:
        found.append(f"indirect-only collections {_names(indirect)}")
    objects = [instance.object for instance in depsgraph.object_instances
               if not instance.is_instance]
    lights = [obj for obj in objects if obj.type == 'LIGHT']
    objects = [obj for obj in objects if obj.type not in NOT_GEOMETRY]
    flags = (("is_holdout", "holdout", " (article semantics)"),) if article else ()
    for flag, label, note in flags + (("is_shadow_catcher", "shadow catcher", ""),):
        marked = {obj.name for obj in objects if getattr(obj, flag, False)}
        if marked:
            found.append(f"{label} objects {_names(marked)}{note}")
    hidden_from = {}
    for obj in objects:
        for flag, ray in RAY_VISIBILITY.items():
            if not getattr(obj, flag, True):
                hidden_from.setdefault(ray, set()).add(obj.name)
    for ray, names in hidden_from.items():
        found.append(f"objects invisible to {ray} rays {_names(names)}")
    no_shadow = {obj.name for obj in lights if not getattr(obj.data, "use_shadow", True)}
    if no_shadow:
        found.append(f"lights without shadows {_names(no_shadow)}")
    return found


def ignored_settings_warning(depsgraph, camera_override=None) -> list[str]:
    """[one warning] naming every ignored setting the scene uses, or []."""
    found = ignored_settings(depsgraph, camera_override)
    if not found:
        return []
    return [f"Glint ignores these settings, which change what Cycles renders: "
            f"{'; '.join(found)}"]
