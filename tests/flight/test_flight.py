"""The Crazyflie flight check: the PID cascade flies a pybullet Crazyflie where it is told,
the arena takes the flown positions, and `python -m hola_ray fly` reports both columns."""

from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import torch

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.core import BatchedPursuit
from hola_ray.evaluation.rollout import rollout
from hola_ray.flight import Crazyflies, Quadrotors
from hola_ray.policies.registry import make_policy

ROOT = Path(__file__).resolve().parents[2]


def test_a_crazyflie_tracks_a_velocity_set_point_and_holds_its_height():
    drones = Quadrotors(np.array([[1.0, 1.0, 1.0], [2.0, 1.0, 1.0]]))
    v_sp = np.array([[0.3, 0.0], [0.0, -0.3]])
    heights = []
    for _ in range(20):  # 2 s
        drones.fly(v_sp, 1.0, 0.1)
        heights.append(drones.pos[:, 2].copy())
    np.testing.assert_allclose(drones.vel[:, :2], v_sp, atol=0.03)
    assert np.abs(np.array(heights) - 1.0).max() < 0.15
    assert drones.pos[0, 0] > 1.45 and drones.pos[1, 1] < 0.55  # it went where it was sent
    # a 90° turn is not instant: the velocity lags the set-point for a few tenths of a second
    drones.fly(np.array([[0.0, 0.3], [0.3, 0.0]]), 1.0, 0.1)
    assert abs(drones.vel[0, 0]) > 0.1
    drones.close()


def test_the_arena_takes_placed_positions_and_the_kinematic_ones_change_nothing():
    config = PursuitConfig(n_evaders=1)
    greedy = make_policy("greedy", config)
    a, b = BatchedPursuit(config, 4), BatchedPursuit(config, 4)
    obs_a, obs_b = a.reset(seeds=np.arange(4)), b.reset(seeds=np.arange(4))
    for _ in range(60):
        actions = greedy.act(obs_a.reshape(-1, obs_a.shape[-1])).reshape(4, -1)
        active = a.pursuer_active.copy()
        head = a.pursuer_heading + (2 * actions - 1) * config.max_turn
        step = config.pursuer_speed * config.dt
        placed = a.pursuer_pos + step * np.stack([np.cos(head), np.sin(head)], -1)
        obs_a = a.step(actions).obs
        obs_b = b.step(actions, placed).obs
        np.testing.assert_allclose(obs_a, obs_b, atol=1e-5)
        np.testing.assert_allclose(a.pursuer_pos[active], b.pursuer_pos[active], atol=1e-12)
    # placed positions are taken as they are: a pursuer put on a bar has crashed
    c = BatchedPursuit(config, 1)
    c.reset(seeds=[0])
    where = c.pursuer_pos.copy()
    where[0, 0] = config.obstacles[0][:2]
    c.step(np.full((1, config.n_pursuers), 0.5), where)
    assert not c.pursuer_active[0, 0] and c.collided[0]


def test_a_flown_team_is_paired_with_the_arena_and_differs_from_it():
    config = PursuitConfig(n_evaders=1, horizon=250)
    team = [make_policy(n, config) for n in ("greedy", "vicsek", "greedy")]
    flown = rollout(config, team, 4, seed=1, dynamics=Crazyflies)
    arena = rollout(config, team, 4, seed=1)
    assert flown.length.max() <= 250 and arena.length.max() <= 250
    assert not np.array_equal(flown.team_return, arena.team_return)  # the dynamics matter
    again = rollout(config, team, 4, seed=1, dynamics=Crazyflies)
    np.testing.assert_array_equal(again.team_return, flown.team_return)  # deterministic


def test_the_fly_command_flies_one_short_episode_and_ends_on_a_json_line(tmp_path):
    cmd = [
        sys.executable,
        "-m",
        "hola_ray",
        "fly",
        "ppo-1",
        "--teammates",
        "greedy",
        "vicsek",
        "--episodes",
        "1",
        "--horizon",
        "300",
        "--replay",
        str(tmp_path / "r.png"),
    ]
    got = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert got.returncode == 0, got.stderr[-2000:]
    figures = json.loads(got.stdout.strip().splitlines()[-1])
    for key in ("success", "collision", "length"):
        assert 0 <= figures[key] <= (300 if key == "length" else 1)
        assert 0 <= figures[f"kinematic_{key}"] <= (300 if key == "length" else 1)
    for column in ("", "kinematic_"):  # one episode: a collision is a seat that crashed
        crashed = figures[f"{column}crash_seat0"] + figures[f"{column}crash_mates"] > 0
        assert figures[f"{column}collision"] == float(crashed)
    assert figures["scenario"] == "3 vs 2"
    assert (tmp_path / "r.png").stat().st_size > 10_000


def test_an_open_team_learner_exports_and_flies_in_teams_of_three_and_five(tmp_path):
    """A learner trained (so its export says) on 5 pursuer slots with teams of 2 to 5 in
    the four arenas: its ONNX manifest states those teams and arenas, and the fly command
    flies it in a team of 3 and one of 5 (its copies as teammates), and in another arena,
    beside the kinematic arena; a 3 vs 2 pool member flies as a teammate in the 5."""
    from hola_ray.commands import export, fly
    from hola_ray.config.scenario import ARENAS, TeamChangeConfig
    from hola_ray.policies.learned import random_export

    trained = PursuitConfig(
        n_pursuers=5,
        n_evaders=2,
        obs_pursuers=5,
        arenas=tuple(ARENAS),
        team=TeamChangeConfig(present=(2, 5), changes=2, min_team=2),
    )
    pt = tmp_path / "open.pt"
    torch.save(random_export(trained.obs_dim, seed=4) | {"scenario": trained.to_dict()}, pt)
    onnx = tmp_path / "open.onnx"
    assert export.main([str(pt), "--onnx", str(onnx)]) == 0
    team = json.loads(onnx.with_suffix(".json").read_text())["team"]
    assert (team["pursuers"], team["trained_pursuers"], team["team_changes"]) == (
        [1, 5],
        [2, 5],
        2,
    )
    assert team["arenas"] == list(ARENAS)
    runs = {
        "three": ["--pursuers", "3"],
        "five": ["--pursuers", "5", "--teammates", "open.onnx", "ppo-1", "greedy", "open.onnx"],
        "bar": ["--pursuers", "3", "--arena", "bar"],
    }
    for name, extra in runs.items():
        argv = [str(onnx), *extra, "--episodes", "1", "--horizon", "60", "--json"]
        argv = [str(tmp_path / a) if a == "open.onnx" else a for a in argv]
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            assert fly.main(argv) == 0, name
        figures = json.loads(out.getvalue().strip().splitlines()[-1])
        size = 5 if name == "five" else 3
        assert figures["scenario"] == f"{size} vs 2", name
        assert 1 <= figures["length"] <= 60 and 1 <= figures["kinematic_length"] <= 60


def test_the_report_names_repeated_teammates_once_with_their_count():
    from hola_ray.commands.fly import teammates_phrase

    assert teammates_phrase("a.onnx", ["a.onnx"] * 4) == "4 copies of itself"
    assert teammates_phrase("a.onnx", ["a.onnx", "ppo-1", "greedy", "a.onnx"]) == (
        "2 copies of itself, ppo-1, greedy"
    )
    assert teammates_phrase("a.onnx", ["ppo-1"]) == "ppo-1"
