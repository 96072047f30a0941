"""Files users take to other tools: per-person world SMPL ``.npz`` (:mod:`~multithumbs.export.smpl`), cameras
``.npz`` and a COLMAP text model (:mod:`~multithumbs.export.cameras`), BVH per person (:mod:`~multithumbs.export.bvh`),
an animated GLB (:mod:`~multithumbs.export.glb`) and a rerun recording (:mod:`~multithumbs.export.rrd`).

Shared helpers: posed meshes and the world's up direction (:mod:`~multithumbs.export.posed`), atomic
writes (:mod:`~multithumbs.export.files`). Heavy imports (pygltflib, rerun) stay inside the writers.
"""
