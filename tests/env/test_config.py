import math

import numpy as np
import pytest
import yaml

from hola_ray.env import ConfigError, EvaderConfig, PursuitConfig


@pytest.mark.parametrize(
    ("change", "field", "allowed"),
    [
        ({"pursuer_speed": -0.3}, "pursuer_speed", "> 0"),
        ({"evader_speed": 0.0}, "evader_speed", "> 0"),
        ({"n_pursuers": 0}, "n_pursuers", ">= 1"),
        ({"n_evaders": 0}, "n_evaders", ">= 1"),
        ({"horizon": 0}, "horizon", ">= 1"),
        ({"dt": float("nan")}, "dt", "a finite number"),
        ({"obstacles": [[3.5, 1.0, 0.65, 0.1]]}, "obstacles[0]", "inside the arena"),
        ({"obstacles": [[1.0, 1.0, -0.65, 0.1]]}, "obstacles[0]", "positive width"),
        ({"pursuer_spawn": [0.2, 3.4, 0.2, 5.8]}, "pursuer_spawn", "inside"),
        ({"capture_distance": -1}, "capture_distance", "> 0"),
        ({"unobserved_distance": 1.0}, "unobserved_distance", "largest observable"),
        ({"evader": {"max_turn": 4.0}}, "evader.max_turn", "(0, π]"),
        ({"evader": {"wander_hold_max": 5}}, "evader.wander_hold_max", ">= wander_hold_min"),
        ({"reward": {"collision": -10}}, "reward.collision", ">= 0"),
        ({"reward": {"obstacle_penalty": float("inf")}}, "reward.obstacle_penalty", "finite"),
        ({"reward": {"approach_scale": 0}}, "reward.approach_scale", "> 0"),
        ({"reward": {"approach": "both"}}, "reward.approach", "distance or own_move"),
        ({"reward": {"teammate_distance": True}}, "reward.teammate_distance", "a finite number"),
        ({"reward": {"shared": "yes"}}, "reward.shared", "true or false"),
        # types, before any range: one line each, naming the field
        ({"n_pursuers": True}, "n_pursuers", "an integer"),
        ({"horizon": True}, "horizon", "an integer"),
        ({"horizon": "1000"}, "horizon", "an integer"),
        ({"evader": {"wander_hold_min": 1.5}}, "evader.wander_hold_min", "an integer"),
        ({"evader": {"sensitivity_range": "2"}}, "evader.sensitivity_range", "a finite number"),
        ({"evader": {"max_turn": "1"}}, "evader.max_turn", "a finite number"),
        ({"obstacles": 5}, "obstacles", "a list"),
        ({"obstacles": [[1.0, 1.0, 0.5]]}, "obstacles[0]", "a list of 4 items"),
        ({"pursuer_spawn": [0.2, 3.4, "a", 0.8]}, "pursuer_spawn[2]", "a finite number"),
        ({"evader": None}, "evader", "a mapping"),
        ({"reward": 3}, "reward", "a mapping"),
        ({"reward": {"approach": 1}}, "reward.approach", "a string"),
    ],
)
def test_bad_values_name_the_field_and_range(change, field, allowed):
    with pytest.raises(ConfigError) as err:
        PursuitConfig.from_dict(change)
    message = str(err.value)
    assert message.startswith(field), message
    assert allowed in message


def test_unknown_keys_are_rejected():
    with pytest.raises(ConfigError, match="unknown key.*n_pursuer\\b"):
        PursuitConfig.from_dict({"n_pursuer": 3})
    with pytest.raises(ConfigError, match="evader.speed"):
        PursuitConfig.from_dict({"evader": {"speed": 1.0}})
    with pytest.raises(ConfigError, match="reward.capture_reward"):
        PursuitConfig.from_dict({"reward": {"capture_reward": 20.0}})


def test_defaults_match_spec_table():
    cfg = PursuitConfig()
    assert (cfg.arena_width, cfg.arena_height) == (3.6, 5.0)
    assert len(cfg.obstacles) == 5 and all(o[2:] == (0.65, 0.10) for o in cfg.obstacles)
    assert (cfg.pursuer_speed, cfg.evader_speed, cfg.dt, cfg.horizon) == (0.3, 0.6, 0.1, 1000)
    assert (cfg.capture_distance, cfg.perception_range, cfg.safe_radius) == (0.2, 2.0, 0.1)
    assert cfg.pursuer_collision_distance == 0.2
    assert (cfg.reward.capture, cfg.reward.collision, cfg.reward.approach_scale) == (10, 10, 0.3)
    assert cfg.reward.obstacle_penalty == cfg.reward.teammate_penalty == 0.0
    assert math.isclose(cfg.evader.max_turn, math.radians(30))
    # 2 evaders × 3 + obstacle 2 + 2 teammates × 2 + own 4
    assert cfg.obs_dim == 16


@pytest.mark.parametrize(("n_p", "n_e"), [(1, 1), (3, 2), (5, 3)])
@pytest.mark.parametrize("headings", [False, True])
def test_obs_dim_is_the_layouts(n_p, n_e, headings):

    from hola_ray.env import BatchedPursuit

    cfg = PursuitConfig(n_pursuers=n_p, n_evaders=n_e, observe_headings=headings)
    layout = cfg.layout
    assert cfg.obs_dim == layout.dim == layout.base_dim + (n_p - 1) * headings
    assert len(layout.bounds()[0]) == cfg.obs_dim
    # the simulator writes that many entries, and the input size reads back its evaders
    obs = BatchedPursuit(cfg, 1).reset(seeds=np.arange(1))
    assert obs.shape[-1] == cfg.obs_dim
    assert layout.evaders_for(cfg.obs_dim, n_p, headings) == n_e
    assert layout.evaders_for(cfg.obs_dim + 1, n_p, headings) is None


def test_yaml_round_trip(tmp_path):
    cfg = PursuitConfig(n_pursuers=4, n_evaders=1, evader=EvaderConfig(slip_range=0.4))
    path = tmp_path / "env.yaml"
    path.write_text(yaml.safe_dump({"env": cfg.to_dict()}))
    assert PursuitConfig.from_yaml(path) == cfg
