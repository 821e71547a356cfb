"""The open-team protocol (contract §6.4): each cell's scenario, every seat on the same
episodes, the leads over cells, the command's files and errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from hola_ray.commands import evaluate as command
from hola_ray.config.scenario import PursuitConfig, RewardConfig
from hola_ray.evaluation import open_teams
from hola_ray.policies.adapter import ScenarioAdapter
from hola_ray.policies.learned import random_export


@pytest.mark.parametrize("mode", open_teams.MODES)
@pytest.mark.parametrize("size", open_teams.SIZES)
def test_a_cells_scenario(mode, size):
    base = PursuitConfig(n_evaders=2, arenas=("open", "bar"), reward=RewardConfig(capture=3.0))
    config = open_teams.cell_scenario(base, "blocks", mode, size)
    assert (config.arena, config.arenas, config.n_pursuers) == ("blocks", (), size)
    assert (config.pursuer_slots, config.evader_slots, config.n_evaders) == (5, 2, 2)
    assert config.reward == PursuitConfig().reward  # returns counted alike
    if mode == "open":
        assert config.team.present == size - 1 and config.team.changes == 2
    else:
        assert not config.team.open
    with pytest.raises(ValueError, match="mode must be one of"):
        open_teams.cell_scenario(base, "open", "closed", 3)


def learner_file(tmp_path, name: str, n_pursuers: int, slots: int | None, seed: int):
    """An export of a random learner trained (so it says) for `n_pursuers` vs 2 in `slots`."""
    trained = PursuitConfig(n_pursuers=n_pursuers, n_evaders=2, obs_pursuers=slots)
    export = random_export(trained.obs_dim, seed=seed, bias_scale=0.5)
    path = tmp_path / f"{name}.pt"
    torch.save(export | {"scenario": trained.to_dict()}, path)
    return path


def test_every_seat_plays_the_cells_episodes_and_a_lead_is_the_cells_at_once(tmp_path):
    """A 3 vs 2 learner (adapted in 5 slots) and a 5-slot one, twice under two names: each
    cell's seats play the same episodes, so the twin's difference is 0 exactly and a tie;
    a lead's point difference is the mean of its cells' (equal episodes per cell)."""
    fixed = learner_file(tmp_path, "fixed", 3, None, 1)
    slots = learner_file(tmp_path, "slots", 5, 5, 2)
    learners = {
        "fixed": open_teams.learner_loader(fixed),
        "slots": open_teams.learner_loader(slots),
        "twin": open_teams.learner_loader(slots),
    }
    config = open_teams.cell_scenario(PursuitConfig(n_evaders=2), "open", "zero-shot", 4)
    assert isinstance(learners["fixed"](config), ScenarioAdapter)
    assert not isinstance(learners["slots"](config), ScenarioAdapter)
    results = open_teams.run_protocol(
        learners,
        ["het"],
        PursuitConfig(n_evaders=2, horizon=150),
        episodes=8,
        seeds=[0],
        arenas=["open"],
        sizes=[2, 4],
        say=lambda line: None,
    )
    cells = results["cells"]
    assert [(c["mode"], c["size"]) for c in cells] == [
        ("zero-shot", 2),
        ("zero-shot", 4),
        ("open", 2),
        ("open", 4),
    ]
    for c in cells:
        assert c["episodes"] == 8 and {"floor", "handwritten"} <= set(c["references"])
        same = c["differences"]["slots − twin"]
        assert same["success"]["mean"] == 0 and same["success"]["ci95"] == [0, 0]
        assert same["success"]["verdict"] == "tie"
    for mode in open_teams.MODES:
        d = results["leads"][f"{mode}/het"]["fixed − slots"]
        per_cell = [
            c["differences"]["fixed − slots"]["reward"]["mean"] for c in cells if c["mode"] == mode
        ]
        assert d["cells"] == 2 and d["episodes"] == 16
        assert d["difference"]["reward"]["mean"] == pytest.approx(np.mean(per_cell))
    lines = open_teams.table(results)
    rows = [line for line in lines if line.startswith("| open | open | 2 |")]
    assert len(rows) == 3
    scale = rows[0].rsplit("|", 2)[-2]
    for ref, f in cells[2]["references"].items():
        assert f"{ref} {f['success']['mean']:.1%}" in scale
    assert sum(line.startswith("| open | open |") for line in lines) == 2 * 3
    written = open_teams.report(results, tmp_path / "out")
    assert [p.name for p in written] == ["open-teams-open.png", "results.md"]


def test_the_command_writes_its_files_and_refuses_what_it_does_not_know(tmp_path, capsys):
    """The grid in the learner's own scenario, written to --out; an unknown size, and a
    learner of a scenario that differs beyond the team and the arena, refused in one line."""
    learner = learner_file(tmp_path, "mine", 3, None, 3)
    out = tmp_path / "protocol"
    argv = [str(learner), "--protocol", "open-teams", "--arenas", "bar", "--sizes", "3"]
    argv += ["--modes", "open", "--pool", "hot", "--episodes", "4", "--seeds", "0"]
    argv += ["--horizon", "150"]
    assert command.main([*argv, "--out", str(out)]) == 0
    results = json.loads((out / "results.json").read_text())
    assert [(c["arena"], c["mode"], c["size"], c["pool"]) for c in results["cells"]] == [
        ("bar", "open", 3, "hot")
    ]
    assert (out / "open-teams-bar.png").is_file() and (out / "results.md").is_file()
    capsys.readouterr()
    assert command.main([*argv[:-8], "--sizes", "6"]) == 2
    assert "--sizes: unknown [6]" in capsys.readouterr().err
    other = PursuitConfig(n_evaders=2, horizon=300)
    torch.save(random_export(other.obs_dim) | {"scenario": other.to_dict()}, tmp_path / "o.pt")
    assert command.main([str(tmp_path / "o.pt"), *argv]) == 2
    assert "differ beyond the team and the arena" in capsys.readouterr().err


def test_a_method_of_several_seeds_is_figured_over_its_seeds(tmp_path):
    """Methods of two trained seeds each: a cell's figure for a method is the mean of its
    seeds' (each seed's figures kept under `trials`), and its seeds pair with the other
    method's in the difference and the lead."""
    paths = {
        f"{m}-s{k}": learner_file(tmp_path, f"{m}{k}", 5, 5, 10 * i + k)
        for i, m in enumerate(("a", "b"))
        for k in (0, 1)
    }
    learners = {name: open_teams.learner_loader(p) for name, p in paths.items()}
    groups = {"a": ["a-s0", "a-s1"], "b": ["b-s0", "b-s1"]}
    results = open_teams.run_protocol(
        learners,
        ["het"],
        PursuitConfig(n_evaders=2, horizon=150),
        episodes=6,
        seeds=[0],
        arenas=["open"],
        modes=["zero-shot"],
        sizes=[3],
        say=lambda line: None,
        groups=groups,
        training_seeds={"a": [0, 1], "b": [0, 1]},
    )
    (cell,) = results["cells"]
    assert set(cell["learners"]) == {"a", "b"} and set(cell["trials"]) == set(paths)
    for method, names in groups.items():
        seeds = [cell["trials"][n]["reward"]["mean"] for n in names]
        assert cell["learners"][method]["reward"]["mean"] == pytest.approx(np.mean(seeds))
    d = results["leads"]["zero-shot/het"]["a − b"]["difference"]["reward"]
    assert d["mean"] == pytest.approx(cell["differences"]["a − b"]["reward"]["mean"])


def test_a_joiner_starts_its_episode_and_rew_counts_the_pursuers_in_play():
    """In a team that changes, a teammate's policy is reset on the rows where it joins (a
    stateful one's state is its episode's, not the waiting seat's), and REW and the
    teammate crash count the seats that were in play: the same joins, found by replaying
    the episodes' env with the same actions."""
    from hola_ray.env import BatchedPursuit
    from hola_ray.evaluation.metrics import zero_shot_values
    from hola_ray.evaluation.rollout import rollout
    from hola_ray.policies.base import Policy

    class Recorder(Policy):
        def __init__(self, config):
            super().__init__(config)
            self.calls = []

        def reset(self, mask=None):
            self.calls.append(np.asarray(mask).copy())

        def act(self, obs):
            return np.full(len(self._check(obs)), 0.55)

    team = {"present": 2, "changes": 3, "window": [0.0, 0.3]}
    config = PursuitConfig.from_dict(
        {"n_pursuers": 5, "arena": "open", "horizon": 200, "team": team}
    )
    mates, me = Recorder(config), Recorder(config)
    seeds = np.arange(32)
    assignment = np.tile([0, 1, 1, 1, 1], (32, 1))
    result = rollout(config, [me, mates], 32, assignment=assignment, episode_seeds=seeds)
    env = BatchedPursuit(config, 32)
    env.reset(seeds=seeds)
    joins, played = np.zeros((32, 5), dtype=int), env.pursuer_present.copy()
    while not env.done.all():
        waiting = env.pursuer_waiting & ~env.done[:, None]
        env.step(np.full((32, 5), 0.55))
        joins += waiting & env.pursuer_present
        played |= env.pursuer_present
    assert joins.sum() > 10 and len(me.calls) == 1  # seat 0 never joins
    assert mates.calls[0].all() and sum(int(c.sum()) for c in mates.calls[1:]) == joins.sum()
    np.testing.assert_array_equal(result.played, played)
    values = zero_shot_values(result, assignment == 0, 5)
    np.testing.assert_allclose(values["reward"], result.team_return / played.sum(axis=1))
    assert (played.sum(axis=1) < 5).any()  # the REW of a whole team would differ


def test_a_d3qn_export_plays_every_cell_as_a_learner():
    """A D3QN-G trained at 3 pursuers, given as a learner, plays a cell of 5 slots and of
    2 to 5 pursuers through the adapter (its state of 3 built in the team it knows)."""
    from hola_ray.evaluation.rollout import rollout

    make = open_teams.learner_loader("pools/het/d3qn-g-1.pt")
    for size in (2, 3, 5):
        cell = open_teams.cell_scenario(PursuitConfig(n_evaders=2), "bar", "open", size)
        learner = make(cell)
        result = rollout(cell, [learner] * cell.n_pursuers, 4, seed=1)
        assert result.success.shape == (4,)


def test_a_grid_stopped_part_way_plays_only_the_cells_it_had_not_kept(tmp_path):
    """A cell kept by a first run (stopped after it) is taken as it was, the others are
    played, and the whole equals an uninterrupted run's, leads included; under other
    settings a kept cell is played again."""
    path = learner_file(tmp_path, "slots", 5, 5, 2)
    played_sizes = []

    def loader(config):
        played_sizes.append(config.n_pursuers)
        return open_teams.learner_loader(path)(config)

    grid = {
        "pools": ["het"],
        "base": PursuitConfig(n_evaders=2, horizon=150),
        "episodes": 4,
        "seeds": [0],
        "arenas": ["open"],
        "modes": ["zero-shot"],
        "say": lambda line: None,
    }
    whole = open_teams.run_protocol({"a": loader}, sizes=[2, 3], **grid)
    kept = open_teams.CellCache(tmp_path / "kept", {"learners": {"a": "sha of a"}})
    open_teams.run_protocol({"a": loader}, sizes=[2], cache=kept, **grid)
    assert sorted(p.name for p in (tmp_path / "kept").iterdir()) == [
        "open-zero-shot-2-het.json",
        "open-zero-shot-2-het.npz",
    ]
    played_sizes.clear()
    resumed = open_teams.run_protocol({"a": loader}, sizes=[2, 3], cache=kept, **grid)
    assert played_sizes == [3]
    assert json.dumps(resumed) == json.dumps(whole)
    other = open_teams.CellCache(tmp_path / "kept", {"learners": {"a": "sha of another a"}})
    played_sizes.clear()
    open_teams.run_protocol({"a": loader}, sizes=[2], cache=other, **grid)
    assert played_sizes == [2]
