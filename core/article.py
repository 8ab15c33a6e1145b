"""The article's scene and settings, exactly as docs/article.md states them ("Scene",
"Camera and screen").

The article works in its own coordinates (Y up, camera looking down -Z); Glint keeps them.
"""

from __future__ import annotations

from .camera import ScreenCamera
from .light_sources import PointLight
from .materials import Material
from .scene import Scene, Sphere
from .settings import RenderSettings

ARTICLE_WIDTH, ARTICLE_HEIGHT = 300, 200
ARTICLE_MAX_DEPTH = 3
ARTICLE_LIGHT = (5.0, 5.0, 5.0)
ARTICLE_EYE = (0.0, 0.0, 1.0)


def _material(ambient, diffuse) -> Material:
    return Material(ambient=ambient, diffuse=diffuse, specular=(1.0, 1.0, 1.0),
                    shininess=100.0, reflection=0.5)


def article_spheres() -> tuple[Sphere, ...]:
    """The four spheres in the article's order (the order breaks ties)."""
    return (
        Sphere((-0.2, 0.0, -1.0), 0.7, _material((0.1, 0, 0), (0.7, 0, 0)), "red"),
        Sphere((0.1, -0.3, 0.0), 0.1, _material((0.1, 0, 0.1), (0.7, 0, 0.7)), "magenta"),
        Sphere((-0.3, 0.0, 0.0), 0.15, _material((0, 0.1, 0), (0, 0.6, 0)), "green"),
        Sphere((0.0, -9000.0, 0.0), 9000.0 - 0.7,
               _material((0.1, 0.1, 0.1), (0.6, 0.6, 0.6)), "floor"),
    )


def article_scene(width: int = ARTICLE_WIDTH, height: int = ARTICLE_HEIGHT) -> Scene:
    """The article's scene seen through its screen camera at width x height."""
    return Scene(
        camera=ScreenCamera(width=width, height=height, eye=ARTICLE_EYE),
        spheres=article_spheres(),
        lights=(PointLight(ARTICLE_LIGHT, name="light"),),
    )


def article_settings(**overrides) -> RenderSettings:
    """The article's semantics, depth 3, float64 (the reference's precision)."""
    values = dict(semantics="article", precision="float64", max_depth=ARTICLE_MAX_DEPTH)
    values.update(overrides)
    return RenderSettings(**values)
