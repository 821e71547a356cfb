"""The arena's response model (env.pursuer_response, pursuer_response_delay): 1 and 0
are the paper's kinematics; below 1 a pursuer's velocity follows the commanded one, and
the fitted model follows a flown Crazyflie closer than the kinematics do."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hola_ray.config.reader import ConfigError
from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.core import BatchedPursuit
from hola_ray.flight import Quadrotors
from hola_ray.flight.identify import identify


def straight_then_turn(config: PursuitConfig, steps: int = 12) -> np.ndarray:
    """Pursuer 0's positions: straight ahead (+y) for `steps`, then a 45° right turn held."""
    env = BatchedPursuit(config, 1)
    # pursuer 0 in the open lane between the lower bars, its teammates far to the sides
    start = {"pursuer_pos": np.array([[1.8, 0.5], [0.3, 0.5], [3.3, 0.5]])}
    env.reset(seeds=[3], initial_state={0: start})
    path = [env.pursuer_pos[0, 0].copy()]
    for k in range(2 * steps):
        actions = np.full((1, config.n_pursuers), 0.5)
        actions[0, 0] = 0.0 if k == steps else 0.5
        env.step(actions)
        path.append(env.pursuer_pos[0, 0].copy())
    return np.array(path)


def test_a_response_of_one_without_delay_is_the_kinematic_arena():
    base = PursuitConfig(n_evaders=1)
    same = dataclasses.replace(base, pursuer_response=1.0, pursuer_response_delay=0)
    np.testing.assert_array_equal(straight_then_turn(base), straight_then_turn(same))


def test_a_slow_response_starts_late_and_rounds_the_turn():
    base = PursuitConfig(n_evaders=1)
    slow = dataclasses.replace(base, pursuer_response=0.37, pursuer_response_delay=1)
    kin, lag = straight_then_turn(base), straight_then_turn(slow)
    assert np.allclose(lag[1], lag[0])  # the first step: nothing commanded acts yet
    step = np.linalg.norm(np.diff(lag, axis=0), axis=1)
    assert step[10] == pytest.approx(base.pursuer_speed * base.dt, rel=0.02)  # up to speed
    # the turn: the lagged pursuer still flies nearly straight one step after it
    heading = np.arctan2(*np.diff(lag, axis=0)[13][::-1])
    assert abs(heading - np.pi / 2) < abs(heading - np.pi / 4)
    assert np.linalg.norm(kin[-1] - lag[-1]) > 0.01  # behind by its late start and the curve


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("pursuer_response", 0.0),
        ("pursuer_response", 1.5),
        ("pursuer_response", True),
        ("pursuer_response_delay", 2),
    ],
)
def test_a_bad_response_setting_is_one_error(field, value):
    with pytest.raises(ConfigError, match=field):
        PursuitConfig(**{field: value})


def test_the_identified_response_predicts_a_flown_drone_better_than_the_kinematics():
    fit = identify(drones=4, steps=150, seed=1)
    assert fit["pursuer_response_delay"] == 1 and 0.2 < fit["pursuer_response"] < 0.6
    assert fit["unexplained_delay_1"] < fit["unexplained_delay_0"]
    # one-step velocity prediction on fresh commands: the fitted model against "at once"
    config = PursuitConfig()
    rng = np.random.default_rng(7)
    world = Quadrotors(np.array([[1.0, 1.0, 1.0], [2.0, 1.0, 1.0]]))
    heading, previous = np.full(2, np.pi / 2), np.zeros((2, 2))
    errors = {"fitted": [], "kinematic": []}
    for _ in range(80):
        heading = heading + rng.uniform(-1, 1, 2) * config.max_turn * (rng.random(2) < 0.4)
        command = config.pursuer_speed * np.column_stack([np.cos(heading), np.sin(heading)])
        v = world.vel[:, :2].copy()
        predicted = v + fit["pursuer_response"] * (previous - v)
        world.fly(command, 1.0, config.dt)
        errors["fitted"].append(np.linalg.norm(world.vel[:, :2] - predicted, axis=1))
        errors["kinematic"].append(np.linalg.norm(world.vel[:, :2] - command, axis=1))
        previous = command
    world.close()
    assert np.mean(errors["fitted"]) < 0.5 * np.mean(errors["kinematic"])
