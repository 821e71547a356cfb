"""The arena's pursuers flown as Crazyflies: the `dynamics` a rollout or a recording takes.

Each control period (the arena's dt) the policies act on observations built from the
drones' true positions; each action turns the commanded heading θ exactly as in the arena
(Δθ = (2a − 1)·max_turn); the drone's PID cascade then tracks the velocity set-point
v·(cos θ, sin θ) at a fixed height for one period, and the arena takes where the drone
really is (`BatchedPursuit.step(actions, placed)`): captures and collisions are judged on
the true positions, the evaders react to them. A disabled pursuer's drone stops being
simulated (it is down; the arena keeps its last position as an obstacle point), as do the
drones of an episode that has ended. With a `guard` the ground station filters each
drone's set-point every velocity-loop step (`hola_ray.flight.guard`).
"""

from __future__ import annotations

import numpy as np

from hola_ray.env.core import BatchedPursuit
from hola_ray.flight.crazyflie import CrazyflieModel
from hola_ray.flight.guard import Guard
from hola_ray.flight.world import PHYSICS_HZ, VELOCITY_EVERY, Quadrotors

HEIGHT = 1.0
"""m: the height the drones hold"""


TICK = VELOCITY_EVERY / PHYSICS_HZ
"""s: how often the ground station sends a guarded set-point (each velocity-loop step)"""


def set_points(env: BatchedPursuit, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The velocity set-points [B, n, 2] the policies' actions command (each action turns
    the heading exactly as in the arena; zero for a drone that is down or whose episode
    ended) and which drones fly [B, n]."""
    config = env.config
    flying = env.pursuer_active & ~env.done[:, None]
    turn = (2.0 * np.clip(actions, 0.0, 1.0) - 1.0) * config.max_turn
    heading = env.pursuer_heading + turn
    v_sp = config.pursuer_speed * np.stack([np.cos(heading), np.sin(heading)], axis=-1)
    v_sp[~flying] = 0.0
    return v_sp, flying


class Crazyflies:
    """Crazyflies for every pursuer of every episode of `env`'s batch, in one pybullet
    world (episodes overlap in space; the bodies never touch)."""

    def __init__(
        self,
        env: BatchedPursuit,
        height: float = HEIGHT,
        model: CrazyflieModel | None = None,
        guard: Guard | None = None,
    ) -> None:
        self.env, self.height, self.guard = env, height, guard
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
        v_sp, flying = set_points(env, actions)
        self.world.live = flying.reshape(-1).copy()
        if self.guard is None:
            self.world.fly(v_sp.reshape(b * n, 2), self.height, config.dt)
        else:  # a new set-point each velocity-loop step
            for _ in range(round(config.dt / TICK)):
                here = self.world.pos.reshape(b, n, 3)[..., :2]
                v = self.guard(config, here, v_sp, flying)
                self.world.fly(v.reshape(b * n, 2), self.height, TICK)
        here = self.world.pos.reshape(b, n, 3)
        self.path.append(here.copy())
        return here[..., :2].copy()

    def close(self) -> None:
        self.world.close()


class GuardedArena:
    """The arena's own kinematics with the ground station's `guard` between the policy and
    the move: each set-point filtered every `TICK` and followed at once (the guarded
    counterpart of `Crazyflies` for the paired column)."""

    def __init__(self, env: BatchedPursuit, guard: Guard) -> None:
        self.env, self.guard = env, guard

    def __call__(self, actions: np.ndarray) -> np.ndarray:
        env, config = self.env, self.env.config
        v_sp, flying = set_points(env, actions)
        pos = env.pursuer_pos.copy()
        for _ in range(round(config.dt / TICK)):
            pos += self.guard(config, pos, v_sp, flying) * TICK
        return pos
