"""Glint's version, one place for every part that states it: the extension's manifest
(``blender_manifest.toml``, checked equal by the tests), the core's pip package
(``pyproject.toml`` reads it from here) and the cluster's check that a worker runs the
submitter's Glint (``core.cluster``).  This module imports nothing."""

VERSION = "0.1.0"
