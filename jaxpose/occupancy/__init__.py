"""Where a shape is, on a grid: the OCSVM region {f >= 0} (:mod:`.svdd`, :mod:`.grid`), the robust
voxel solid (:mod:`.solid`) and the filled solid of a closed mesh (:mod:`.voxels`).

Knows nothing of files, poses or frames.
"""
