"""Canonical frames of meshes and point clouds: :func:`~jaxpose.rotation.rotation.frame_of` by name
(:mod:`.rotation`), the ``core`` frame and the solid (:mod:`.core`), the ``head`` frame (:mod:`.head`), the body's
parts found in the depth field (:mod:`.parts`).
"""
