"""Core scenes shared by tests of the tree and of the direction bins."""

from __future__ import annotations

import numpy as np

import core


def dense_wall_scene(material: core.Material) -> core.Scene:
    """A wall of 20 x 20 x 100 spheres of radius 0.12 seen end on from (0, 0, 3): hundreds of
    spheres behind one another in every direction the eye looks, each touching its neighbours
    (spacing 0.19-0.21), lit by a point light behind the eye."""
    grid = np.stack(np.meshgrid(np.linspace(-2, 2, 20), np.linspace(-2, 2, 20),
                                np.linspace(-1, -20, 100)), -1).reshape(-1, 3)
    wall = core.SphereSet(grid, np.full(len(grid), 0.12), np.zeros(len(grid), np.int64),
                          (material,))
    return core.Scene(camera=core.ScreenCamera(40, 40, eye=(0, 0, 3)), sphere_sets=(wall,),
                      lights=(core.PointLight((0, 0, 10)),))
