"""Planning in a scene: walking paths on any scene's points (:mod:`.paths`) and the root
trajectories that follow them (:mod:`.trajectory`)."""

from jaxmotion.planning.paths import PointGrid, approach_point, point_grid, scene_path
from jaxmotion.planning.trajectory import path_trajectory, trajectory_features

__all__ = ["PointGrid", "approach_point", "path_trajectory", "point_grid", "scene_path",
           "trajectory_features"]
