"""The ground station's safety filter: set-points pass unchanged in free space, an approach
is held to gain × room left, and drones flown straight at the bars stop short of them."""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest

from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.rollout import rollout
from hola_ray.flight.guard import Guard


def test_free_space_set_points_pass_and_an_approach_is_held_to_the_room_left():
    config, guard = PursuitConfig(), Guard(margin=0.05, gain=2.0)
    pos = np.array([[[1.8, 2.0], [0.40, 4.4], [3.45, 0.6], [1.0, 3.0], [1.1, 3.0]]])
    v_sp = np.array([[[0.3, 0.0], [-0.3, 0.0], [0.3, 0.1], [0.3, 0.0], [-0.3, 0.0]]])
    flying = np.ones((1, 5), dtype=bool)
    v = guard(config, pos, v_sp, flying)
    np.testing.assert_array_equal(v[0, :2], v_sp[0, :2])  # far from all, or room enough
    # 0.15 m from the right wall: towards it at most 2 × (0.15 − 0.1 − 0.05) = 0
    assert v[0, 2, 0] == pytest.approx(0.0) and v[0, 2, 1] == pytest.approx(0.1)
    # two flying drones 0.1 m apart (inside κ 0.2): each backs away from the other
    assert v[0, 3, 0] < 0 < v[0, 4, 0]
    # a downed drone is an obstacle at the safe radius; it is never steered itself
    down = flying.copy()
    down[0, 4] = False
    v = guard(config, pos, v_sp, down)
    np.testing.assert_array_equal(v[0, 4], v_sp[0, 4])
    assert v[0, 3, 0] < 0  # still inside the safe radius (0.1) + margin of the wreck


def test_drones_flown_straight_at_walls_and_bars_stop_short_of_them_with_the_guard(straight):
    pytest.importorskip("pybullet")
    from hola_ray.flight import Crazyflies

    config = PursuitConfig(n_pursuers=3, n_evaders=1, horizon=200)
    team = [straight] * 3
    plain = rollout(config, team, 8, seed=9, dynamics=Crazyflies)
    guarded = rollout(
        config, team, 8, seed=9, dynamics=functools.partial(Crazyflies, guard=Guard())
    )
    assert plain.crashed.sum() >= 8  # straight up into a bar or the top wall
    assert guarded.crashed.sum() == 0


def test_the_guarded_arena_moves_as_the_arena_where_nothing_is_near(config):
    from hola_ray.env.core import BatchedPursuit
    from hola_ray.flight import GuardedArena

    env = BatchedPursuit(config, 4)
    env.reset(seeds=np.arange(4))
    env.pursuer_pos[:] = [[1.8, 1.8], [0.6, 3.0], [3.0, 3.3]]  # open floor, 0.4 m or more apart
    env.pursuer_heading[:] = np.pi / 2
    actions = np.array([[0.5, 0.0, 1.0]] * 4)
    placed = GuardedArena(env, Guard())(actions)
    turn = (2 * actions - 1) * config.max_turn + np.pi / 2
    step = config.pursuer_speed * config.dt * np.stack([np.cos(turn), np.sin(turn)], axis=-1)
    np.testing.assert_allclose(placed, env.pursuer_pos + step, atol=1e-12)


def test_the_fly_command_flies_and_plays_the_arena_through_the_guard(capsys):
    pytest.importorskip("pybullet")
    from hola_ray.commands.fly import main

    assert main(["ppo-1", "--guard", "--episodes", "2", "--horizon", "120", "--json"]) == 0
    figures = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert figures["guard"] == {"margin": Guard().margin, "gain": Guard().gain}
    assert 0 <= figures["collision"] <= 1 and 0 <= figures["kinematic_collision"] <= 1
