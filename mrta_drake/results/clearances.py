"""How close the robots came to each other, to walls and to people, sample by sample.

Every clearance is surface to surface: centre distance minus the bodies' radii, m
(negative when they overlap; a wall's surface is the obstacle boundary). World frame.
"""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Clearances:
    """Clearances at T samples: ``robot_robot`` (T, P) for the robot index ``pairs``
    (P, 2), i < j; ``robot_wall`` (T, N); ``robot_human`` (T, N, M), NaN where the human is
    absent."""

    pairs: np.ndarray
    robot_robot: np.ndarray
    robot_wall: np.ndarray
    robot_human: np.ndarray

    def smallest(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per sample, the smallest robot-robot, robot-wall and robot-human clearance (T,)
        each, m; inf where there is no such pair."""
        T = len(self.robot_wall)
        return (_row_min(self.robot_robot), _row_min(self.robot_wall),
                _row_min(self.robot_human.reshape(T, -1)))


def clearances(obstacles, robot_xy, robot_radii, human_xy=None, human_radii=()) -> Clearances:
    """Clearances of robots at ``robot_xy`` (T, N, 2) with ``robot_radii`` (N,) from
    ``obstacles`` (anything with ``signed_distance(points)``, m), from each other and from
    humans at ``human_xy`` (T, M, 2; NaN where absent) with ``human_radii`` (M,)."""
    xy = np.asarray(robot_xy, dtype=float)
    T, N = xy.shape[:2]
    radii = np.broadcast_to(np.asarray(robot_radii, dtype=float), (N,))
    wall = obstacles.signed_distance(xy.reshape(-1, 2)).reshape(T, N) - radii
    i, j = np.triu_indices(N, 1)
    between = np.linalg.norm(xy[:, i] - xy[:, j], axis=-1) - radii[i] - radii[j]
    humans = np.zeros((T, 0, 2)) if human_xy is None else np.asarray(human_xy, dtype=float)
    human_radii = np.broadcast_to(np.asarray(human_radii, dtype=float), (humans.shape[1],))
    people = (np.linalg.norm(xy[:, :, None] - humans[:, None], axis=-1)
              - radii[None, :, None] - human_radii[None, None, :])
    return Clearances(np.stack([i, j], axis=1), between, wall, people)


def _row_min(values: np.ndarray) -> np.ndarray:
    """Per row, the smallest non-NaN value; inf for rows without one."""
    if values.shape[1] == 0:
        return np.full(len(values), np.inf)
    return np.where(np.isnan(values), np.inf, values).min(axis=1)
