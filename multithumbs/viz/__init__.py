"""Pictures of a reconstruction: overlay video, top-down trajectories, benchmark plots, the per-video report.

Modules: :mod:`~multithumbs.viz.palette` (colour of a global id), :mod:`~multithumbs.viz.pairing` (the
result coloured by its paired truth person), :mod:`~multithumbs.viz.labels` (outlined text),
:mod:`~multithumbs.viz.overlay` (meshes over the input frames), :mod:`~multithumbs.viz.plots` (matplotlib,
Agg backend), :mod:`~multithumbs.viz.report` (markdown) and :mod:`~multithumbs.viz.outputs`
(``write_video_outputs``: every picture and export of one video).
Heavy imports (matplotlib, rerun, pygltflib) stay inside the modules that need them.
"""
