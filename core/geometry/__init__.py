"""The geometry: every shape of a scene behind one interface (``Aggregate``), which the
integrators call (``nearest``, ``occluded``, ``spawn``, ``exclusions``, ``shared_origin``,
``segments_need_origin``, ``surface_keys``, ``build_frame_tables``) with ``core.rays``' types.

Modules: ``aggregate`` (the facade), ``policy`` (every threshold that picks a strategy),
``rules`` (the hit rules), shapes (``spheres``, ``triangles``), accelerators (``tree`` over
``bvh``, the tree, ``bvh_build`` and ``bvh_traverse``; ``cull``, flat culling; ``binning``
over ``bins_held``, ``bins``, ``bins_build`` and ``mirrors``, direction bins), the pair
kernels they hand their pairs to (``kernels``, ``pairs``), hit construction (``hits``), and
what they share (``cells``: cube-map cells and Morton codes; ``threads``).
"""

from .aggregate import ROOT_FORMULAS, Aggregate
from .policy import DEFAULT_POLICY, GeometryPolicy
from .rules import ARTICLE_RULES, HIT_RULES, HitRules

__all__ = ["Aggregate", "ARTICLE_RULES", "DEFAULT_POLICY", "GeometryPolicy", "HIT_RULES",
           "HitRules", "ROOT_FORMULAS"]
