"""From an occupancy's moments to a :class:`~jaxpose.pose.result.Pose`: the reference frame of the
inputs (:mod:`.frame`), :func:`~jaxpose.pose.pose.normalize` (:mod:`.pose`), the estimators by name
(:mod:`.estimators`), validity checks (:mod:`.validity`) and sensitivities (:mod:`.sensitivity`).
"""
