"""The arena's pursuers flown as Crazyflies: the `dynamics` a rollout or a recording takes.

Each control period (the arena's dt) the policies act on observations built from the
drones' true positions; each action turns the commanded heading θ exactly as in the arena
(Δθ = (2a − 1)·max_turn); the drone's PID cascade then tracks the velocity set-point
v·(cos θ, sin θ) at a fixed height for one period, and the arena takes where the drone
really is (`BatchedPursuit.step(actions, placed)`): captures and collisions are judged on
the true positions, the evaders react to them. A disabled pursuer's drone stops being
simulated (it is down; the arena keeps its last position as an obstacle point), as do the
drones of an episode that has ended.
"""

from __future__ import annotations

import numpy as np

from hola_ray.env.core import BatchedPursuit
from hola_ray.flight.crazyflie import CrazyflieModel
from hola_ray.flight.world import Quadrotors

HEIGHT = 1.0
"""m: the height the drones hold"""


class Crazyflies:
    """Crazyflies for every pursuer of every episode of `env`'s batch, in one pybullet
    world (episodes overlap in space; the bodies never touch)."""

    def __init__(
        self, env: BatchedPursuit, height: float = HEIGHT, model: CrazyflieModel | None = None
    ) -> None:
        self.env, self.height = env, height
        b, n = env.pursuer_pos.shape[:2]
        start = np.concatenate(
            [env.pursuer_pos.reshape(b * n, 2), np.full((b * n, 1), height)], axis=1
        )
        self.world = Quadrotors(start, model or CrazyflieModel())
        self.path = [self.world.pos.reshape(b, n, 3).copy()]
        """the drones' true positions [B, n, 3] at each control step, the start first"""

    def __call__(self, actions: np.ndarray) -> np.ndarray:
        """Fly one control period; where each pursuer is at its end [B, n, 2]."""
        env, config = self.env, self.env.config
        b, n = env.pursuer_pos.shape[:2]
        flying = env.pursuer_active & ~env.done[:, None]
        turn = (2.0 * np.clip(actions, 0.0, 1.0) - 1.0) * config.max_turn
        heading = env.pursuer_heading + turn
        v_sp = config.pursuer_speed * np.stack([np.cos(heading), np.sin(heading)], axis=-1)
        v_sp[~flying] = 0.0
        self.world.live = flying.reshape(-1).copy()
        self.world.fly(v_sp.reshape(b * n, 2), self.height, config.dt)
        here = self.world.pos.reshape(b, n, 3)
        self.path.append(here.copy())
        return here[..., :2].copy()

    def close(self) -> None:
        self.world.close()
