"""Canonical frames of meshes and point clouds: :func:`~jaxpose.rotation.rotation.frame_of` by name
(:mod:`.rotation`), the body's parts found in the depth field (:mod:`.parts`).
"""
