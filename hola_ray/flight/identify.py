"""The arena's response model fitted to the flown Crazyflie (`env.pursuer_response`,
`env.pursuer_response_delay`): how fast a drone's velocity follows the velocity its
heading commands, measured on policy-like commands (a heading held, or turned by up to
max_turn, at the control period)."""

from __future__ import annotations

import numpy as np

from hola_ray.config.scenario import PursuitConfig
from hola_ray.flight.dynamics import HEIGHT
from hola_ray.flight.world import Quadrotors


def identify(
    config: PursuitConfig | None = None, drones: int = 8, steps: int = 400, seed: int = 0
) -> dict[str, float]:
    """Fly `drones` Crazyflies on random heading commands for `steps` control periods and
    fit v[k+1] − v[k] = β·(c[k − d] − v[k]) by least squares for d = 0 and 1 (c the
    commanded velocity, v the drone's). Returns β and the residual share for each d, and
    the d that fits better."""
    config = config or PursuitConfig()
    rng = np.random.default_rng(seed)
    start = np.column_stack([0.4 * np.arange(drones), np.zeros(drones), np.full(drones, HEIGHT)])
    world = Quadrotors(start)
    heading = np.full(drones, np.pi / 2)
    velocities, commands = [world.vel[:, :2].copy()], []
    for _ in range(steps):
        turning = rng.random(drones) < 0.3
        heading = heading + np.where(turning, rng.uniform(-1, 1, drones) * config.max_turn, 0)
        command = config.pursuer_speed * np.column_stack([np.cos(heading), np.sin(heading)])
        world.fly(command, HEIGHT, config.dt)
        commands.append(command)
        velocities.append(world.vel[:, :2].copy())
    world.close()
    v, c = np.array(velocities), np.array(commands)  # [steps + 1, M, 2], [steps, M, 2]
    out: dict[str, float] = {}
    for delay in (0, 1):
        x = c[1 - delay : steps - delay] - v[1:steps]  # c[k − d] − v[k], k = 1 … steps − 1
        y = v[2:] - v[1:steps]
        x, y = x.ravel(), y.ravel()
        beta = float(x @ y / (x @ x))
        out[f"beta_delay_{delay}"] = round(beta, 4)
        out[f"unexplained_delay_{delay}"] = round(float(np.var(y - beta * x) / np.var(y)), 4)
    best = min((0, 1), key=lambda d: out[f"unexplained_delay_{d}"])
    out |= {"pursuer_response": out[f"beta_delay_{best}"], "pursuer_response_delay": best}
    return out
