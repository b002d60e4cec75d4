"""Trajectory and map metrics: kitti (KITTI relative error), ate, rpe and mme (mean map entropy).

Trajectories are (n, 4, 4) arrays of poses with the same frame order, e.g. a ground truth and
MappingPipeline.trajectory.
"""
from ._gcmap.eval import ate, kitti, mme, rpe

__all__ = ["ate", "kitti", "mme", "rpe"]
