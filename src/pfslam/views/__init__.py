"""Views of a run: figures (:mod:`~pfslam.views.figures`: map.png, localization.png, error
plots), the video (:mod:`~pfslam.views.video`), the rerun viewer
(:mod:`~pfslam.views.rerunview`), the live observer that drives them during a run
(:mod:`~pfslam.views.live`) and what they share (:mod:`~pfslam.views.trace`).

May import: maps, frames, geometry, errors, and the filters' protocol
(:mod:`pfslam.filters.base`). Never a concrete filter, the pipeline or the CLI. Matplotlib,
imageio and rerun are imported where first needed.
"""
