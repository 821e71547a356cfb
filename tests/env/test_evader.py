"""The DACOOP escaper (contract §2): bounded turns, constant speed, flight, staying inside."""

from __future__ import annotations

import math

import numpy as np

from hola_ray.env import BatchedPursuit, PursuitConfig
from hola_ray.policies import Greedy


def _run(config, batch, steps, seed=0):
    env = BatchedPursuit(config, batch)
    env.reset(seeds=np.arange(batch) + seed)
    policy = Greedy(config)
    history = []
    for _ in range(steps):
        pos = env.evader_pos.copy()
        heading = env.evader_heading.copy()
        alive = env.evader_alive.copy()
        running = ~env.done
        env.step(policy.act(env.obs.reshape(-1, config.obs_dim)).reshape(batch, -1))
        history.append(
            (
                pos,
                heading,
                alive & running[:, None],
                env.evader_pos.copy(),
                env.evader_heading.copy(),
            )
        )
    return env, history


def test_turns_bounded_speed_constant_and_inside_arena():
    config = PursuitConfig()
    env, history = _run(config, 64, 400)
    step = config.evader_speed * config.dt
    for pos, heading, moving, new_pos, new_heading in history:
        turn = np.abs((new_heading - heading + np.pi) % (2 * np.pi) - np.pi)
        assert np.all(turn[moving] <= config.evader.max_turn + 1e-9)
        moved = np.linalg.norm(new_pos - pos, axis=-1)[moving]
        # a full step, or none when it would end within min_clearance of an obstacle
        assert np.all(np.isclose(moved, step) | (moved == 0.0))
        assert np.all((new_pos[..., 0] > 0) & (new_pos[..., 0] < config.arena_width))
        assert np.all((new_pos[..., 1] > 0) & (new_pos[..., 1] < config.arena_height))
    # no evader crosses a bar: bars are 0.1 thick, steps 0.06 long, min clearance 0.03
    for cx, cy, w, h in config.obstacles:
        inside = (np.abs(env.evader_pos[..., 0] - cx) < w / 2) & (
            np.abs(env.evader_pos[..., 1] - cy) < h / 2
        )
        assert not inside.any()


def test_evader_flees_a_close_pursuer():
    config = PursuitConfig(n_evaders=1)
    env = BatchedPursuit(config, 1)
    # evader in open space heading −y, a pursuer 0.5 below it: panic → it turns and runs up
    env.reset(
        seeds=[0],
        initial_state={
            0: {
                "evader_pos": np.array([[0.6, 2.3]]),
                "evader_heading": np.array([-math.pi / 2]),
                "pursuer_pos": np.array([[0.6, 1.8], [3.3, 0.3], [3.3, 4.7]]),
            }
        },
    )
    gaps = []
    for _ in range(15):
        env.step(np.full((1, 3), 0.5))
        gaps.append(np.linalg.norm(env.evader_pos[0, 0] - env.pursuer_pos[0, 0]))
    # a U-turn takes six 30° steps; then it opens the gap at twice the pursuer's speed
    assert math.sin(env.evader_heading[0, 0]) > 0.5
    assert np.all(np.diff(gaps[6:]) > 0.02) and gaps[-1] > 0.6, gaps


def test_calm_evader_wanders_forward_and_is_seed_deterministic():
    config = PursuitConfig(n_evaders=1)
    state = {0: {"evader_pos": np.array([[1.8, 3.3]]), "evader_heading": np.array([0.0])}}
    runs = []
    for _ in range(2):
        env = BatchedPursuit(config, 1)
        env.reset(seeds=[42], initial_state=state)
        env.step(np.full((1, 3), 0.5))
        runs.append(env.evader_heading.copy())
        # a wander heading is drawn within ±90° of the current one and turned toward ≤ 30°
        assert abs(env.evader_heading[0, 0]) <= math.radians(30) + 1e-12
    np.testing.assert_array_equal(runs[0], runs[1])
