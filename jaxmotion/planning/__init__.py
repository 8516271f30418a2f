"""Planning in a scene: walking paths on any scene's points (:mod:`.paths`) and the root
trajectories that follow them (:mod:`.trajectory`)."""

_HOMES = {"PointGrid": "paths", "approach_point": "paths", "point_grid": "paths",
          "scene_path": "paths", "path_trajectory": "trajectory",
          "trajectory_features": "trajectory"}
__all__ = ["PointGrid", "approach_point", "path_trajectory", "point_grid", "scene_path",
           "trajectory_features"]


def __getattr__(name):  # imported when used: a one-instruction generate needs none of it
    if name in _HOMES:
        import importlib

        return getattr(importlib.import_module(f"jaxmotion.planning.{_HOMES[name]}"), name)
    raise AttributeError(f"module 'jaxmotion.planning' has no attribute {name!r}")
