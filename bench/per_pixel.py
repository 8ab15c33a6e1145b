"""The article's program as the article writes it: Python loops over pixels, NumPy 3-vectors.

The functions and the loop body keep the article's structure and formulas line for line
(docs/article.md states them); the only additions are that the scene comes from a ``core.Scene``
(so any scene the bench uses can be rendered) and that ``render`` can be asked for some rows
and columns only, so that a test can check a crop of the 300 x 200 image in milliseconds.
"""

from __future__ import annotations

import numpy as np

from core import Scene, ScreenCamera


def normalize(vector):
    return vector / np.linalg.norm(vector)


def reflected(vector, axis):
    return vector - 2 * np.dot(vector, axis) * axis


def sphere_intersect(center, radius, ray_origin, ray_direction):
    b = 2 * np.dot(ray_direction, ray_origin - center)
    c = np.linalg.norm(ray_origin - center) ** 2 - radius ** 2
    delta = b ** 2 - 4 * c
    if delta > 0:
        t1 = (-b + np.sqrt(delta)) / 2
        t2 = (-b - np.sqrt(delta)) / 2
        if t1 > 0 and t2 > 0:
            return min(t1, t2)
    return None


def nearest_intersected_object(objects, ray_origin, ray_direction):
    distances = [sphere_intersect(obj['center'], obj['radius'], ray_origin, ray_direction)
                 for obj in objects]
    nearest_object = None
    min_distance = np.inf
    for index, distance in enumerate(distances):
        if distance and distance < min_distance:
            min_distance = distance
            nearest_object = objects[index]
    return nearest_object, min_distance


def article_objects(scene: Scene):
    """(camera, screen, light, objects) in the article's dictionaries."""
    camera = scene.camera
    if not isinstance(camera, ScreenCamera):
        raise ValueError("the per-pixel program renders ScreenCamera scenes only")
    if len(scene.lights) != 1:
        raise ValueError(f"the per-pixel program renders scenes with exactly one light, "
                         f"got {len(scene.lights)}")
    light = scene.lights[0]
    objects = [{
        'center': np.array(s.center), 'radius': s.radius,
        'ambient': np.array(s.material.ambient), 'diffuse': np.array(s.material.diffuse),
        'specular': np.array(s.material.specular), 'shininess': s.material.shininess,
        'reflection': s.material.reflection,
    } for s in scene.spheres]
    return (np.array(camera.eye), (camera.left, camera.top, camera.right, camera.bottom),
            {'position': np.array(light.position), 'ambient': np.array(light.ambient),
             'diffuse': np.array(light.diffuse), 'specular': np.array(light.specular)},
            objects)


def render(scene: Scene, max_depth: int = 3, rows=None, columns=None) -> np.ndarray:
    """(len(rows), len(columns), 3) float64: the article's image restricted to those rows and
    columns (default: all), row 0 = top."""
    camera, screen, light, objects = article_objects(scene)
    width, height = scene.camera.width, scene.camera.height
    rows = range(height) if rows is None else rows
    columns = range(width) if columns is None else columns
    ys = np.linspace(screen[1], screen[3], height)
    xs = np.linspace(screen[0], screen[2], width)
    image = np.zeros((len(rows), len(columns), 3))
    for i, y in enumerate(ys[list(rows)]):
        for j, x in enumerate(xs[list(columns)]):
            # screen is on the plane z = screen_z
            pixel = np.array([x, y, scene.camera.screen_z])
            origin = camera
            direction = normalize(pixel - origin)

            color = np.zeros((3))
            reflection = 1

            for k in range(max_depth):
                # check for intersections
                nearest_object, min_distance = nearest_intersected_object(
                    objects, origin, direction)
                if nearest_object is None:
                    break

                intersection = origin + min_distance * direction
                normal_to_surface = normalize(intersection - nearest_object['center'])
                shifted_point = intersection + 1e-5 * normal_to_surface
                intersection_to_light = normalize(light['position'] - shifted_point)

                _, min_distance = nearest_intersected_object(
                    objects, shifted_point, intersection_to_light)
                intersection_to_light_distance = np.linalg.norm(light['position'] - intersection)
                is_shadowed = min_distance < intersection_to_light_distance

                if is_shadowed:
                    break

                illumination = np.zeros((3))

                # ambient
                illumination += nearest_object['ambient'] * light['ambient']

                # diffuse
                illumination += (nearest_object['diffuse'] * light['diffuse']
                                 * np.dot(intersection_to_light, normal_to_surface))

                # specular
                intersection_to_camera = normalize(camera - intersection)
                H = normalize(intersection_to_light + intersection_to_camera)
                illumination += (nearest_object['specular'] * light['specular']
                                 * np.dot(normal_to_surface, H) ** (nearest_object['shininess'] / 4))

                # reflection
                color += reflection * illumination
                reflection *= nearest_object['reflection']

                origin = shifted_point
                direction = reflected(direction, normal_to_surface)

            image[i, j] = np.clip(color, 0, 1)
    return image
