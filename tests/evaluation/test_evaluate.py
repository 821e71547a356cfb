"""The zero-shot evaluation: who sits where, the BR-Prox score's reference, teammates
from a researcher's own module, and one clear error for a bad command line."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from hola_ray.commands.evaluate import main
from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.teams import draw_teams, play
from hola_ray.evaluation.zero_shot import br_prox, cell_returns, iqm
from hola_ray.policies.learned import random_export
from hola_ray.policies.registry import make_policy

CONFIG = dataclasses.replace(PursuitConfig(), horizon=150)


class Recorder:
    """A teammate that counts the rows it is asked to act on."""

    def __init__(self, policy):
        self.policy, self.rows, self.name = policy, 0, policy.name

    def act(self, obs):
        self.rows += len(obs)
        return self.policy.act(obs)

    def reset(self, mask=None):
        self.policy.reset(mask)


def test_draws_seat_the_learner_in_every_seat_and_only_pool_members_beside_it():
    rng = np.random.default_rng(0)
    teams = draw_teams(rng, 6000, n_p=3, members=4)
    assert ((teams == 0).sum(axis=1) == 1).all()  # the learner exactly once per episode
    assert teams.min() == 0 and teams.max() == 4  # nothing outside [learner, members 1…4]
    seat_share = (teams == 0).mean(axis=0)
    np.testing.assert_allclose(seat_share, 1 / 3, atol=0.03)  # every seat, uniformly
    member_share = np.bincount(teams[teams > 0], minlength=5)[1:] / (teams > 0).sum()
    np.testing.assert_allclose(member_share, 0.25, atol=0.02)
    # in episodes: every member and the learner act, and only they do
    learner = Recorder(make_policy("greedy", CONFIG))
    pool = [Recorder(make_policy(n, CONFIG)) for n in ("vicsek", "apf-a-10")]
    outsider = Recorder(make_policy("apf-a-3", CONFIG))
    play(learner, pool, CONFIG, episodes=12, seeds=[0])
    assert learner.rows > 0 and all(p.rows > 0 for p in pool) and outsider.rows == 0


def test_a_pool_member_scores_at_most_one_and_exactly_one_where_it_is_the_reference():
    members = [make_policy(n, CONFIG) for n in ("greedy", "vicsek", "apf-a-10")]
    reference = cell_returns(members, members, CONFIG, episodes=4, seeds=[0, 1])
    assert reference.shape == (9, 3, 2, 3)  # 3² combinations × 3 seats × 2 seeds × 3 members
    for k, member in enumerate(members):
        mine = cell_returns([member], members, CONFIG, episodes=4, seeds=[0, 1])[..., 0]
        np.testing.assert_array_equal(mine, reference[..., k])  # the same episodes
        scores, dropped = br_prox(reference, mine)
        assert scores.size + dropped == mine.size and (scores <= 1).all()
        best = reference.max(axis=-1)
        is_ref = (reference[..., k] == best) & (best > 0)
        assert is_ref.any()
        np.testing.assert_array_equal(br_prox(reference[is_ref], mine[is_ref])[0], 1.0)
    # sorted: −50, 0 | 1, 2, 2, 2 | 3, 100: the middle half
    assert iqm(np.array([0, 1, 2, 3, 100, -50, 2, 2])) == pytest.approx(1.75)


@pytest.fixture()
def learner_file(tmp_path):
    export = random_export(PursuitConfig().obs_dim, hidden=(8,))
    path = tmp_path / "mine.pt"
    torch.save(export, path)
    return path


PARTNER = """
from hola_ray.policies.greedy import Greedy


class Cautious:
    name = "cautious"

    def __init__(self, config):
        self.inner = Greedy(config)

    def act(self, obs):
        return self.inner.act(obs)

    def reset(self, mask=None):
        pass


def make(config):
    return Cautious(config)
"""


def test_partner_from_a_module_in_a_temporary_directory(
    tmp_path, learner_file, capsys, monkeypatch
):
    (tmp_path / "my_partners.py").write_text(PARTNER)
    small = ["--episodes", "3", "--seeds", "0", "--cell-episodes", "1", "--json"]
    assert (
        main([str(learner_file), "--partner", f"{tmp_path / 'my_partners.py'}:make", *small]) == 0
    )
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    row = last["runs"]["mine"]["partners"]
    assert 0 <= row["success"] <= 1 and row["length"] > 0 and "score_iqm" in row
    monkeypatch.syspath_prepend(str(tmp_path))  # the module-name form
    assert main([str(learner_file), "--partner", "my_partners:make", *small]) == 0


def test_the_evaluation_plays_the_learners_number_of_evaders(learner_file, tmp_path):
    from hola_ray.commands.evaluate import learners_scenario

    assert learners_scenario([learner_file]).n_evaders == 2
    one = tmp_path / "one.pt"
    torch.save(random_export(PursuitConfig(n_evaders=1).obs_dim), one)  # no scenario recorded
    assert learners_scenario([one]) == PursuitConfig(n_evaders=1)
    assert main([str(learner_file), str(one), "--pool", "hot"]) == 2  # not one scenario


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--pool", "nope"], "error: unknown pool 'nope': give one of hot, het"),
        (["--partner", "no_colon"], "error: --partner expects MODULE:CALLABLE, got 'no_colon'"),
        (["--partner", "json:not_there"], "error: --partner json:not_there: json has no callable"),
        (["--partner", "no_such_module_x:make"], "error: --partner no_such_module_x:make: cannot"),
    ],
)
def test_a_bad_pool_or_partner_is_one_clear_error(learner_file, capsys, args, message):
    assert main([str(learner_file), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(message) and len(err.splitlines()) == 1


def test_replay_mixes_learned_and_hand_written_policies_with_a_legend(learner_file, tmp_path):
    from hola_ray.commands.replay import main as replay
    from hola_ray.commands.replay import resolve

    assert resolve(str(learner_file), PursuitConfig()).name == "mine"
    with pytest.raises(ValueError, match="unknown policy 'nobody'"):
        resolve("nobody", PursuitConfig())
    team = ["--team", str(learner_file), "greedy", "apf-a-10"]
    replay([*team, "--out", str(tmp_path / "r"), "--stride", "40"])  # a few frames
    assert sorted(p.suffix for p in (tmp_path / "r").iterdir()) == [".gif", ".png"]


def test_replay_plays_the_scenario_a_learner_was_trained_in(tmp_path, capsys):
    from hola_ray.commands.replay import main as replay

    one = PursuitConfig(n_evaders=1)
    path = tmp_path / "one.pt"
    torch.save(random_export(one.obs_dim, hidden=(8,)) | {"scenario": one.to_dict()}, path)
    out = ["--out", str(tmp_path / "r"), "--stride", "40"]
    assert replay(["--team", str(path), "vicsek", "greedy", *out]) == 0
    assert "'captures'" in capsys.readouterr().out


def test_learner_crash_is_the_learners_own_seat(config, straight):
    """A learner that never turns crashes almost every episode; its Vicsek teammates
    rarely do. An episode with a crashed seat is a collision."""
    from hola_ray.policies import Vicsek

    played = play(straight, [Vicsek(config)], config, 40, [0, 1])
    assert played["learner_crash"].shape == (80,)
    assert played["learner_crash"].mean() > 0.9
    assert played["teammate_crash"].mean() < played["learner_crash"].mean() / 3
    assert np.all(played["collision"] >= played["learner_crash"])
    assert np.all(played["collision"] >= (played["teammate_crash"] > 0))


def test_partner_combinations_ignore_the_learners_seat_and_the_order():
    from hola_ray.evaluation.teams import partner_combinations

    teams = np.array([[0, 1, 2], [2, 0, 1], [1, 2, 0], [0, 2, 2], [3, 0, 1]])
    ids = partner_combinations(teams, members=3)
    assert ids[0] == ids[1] == ids[2]  # {1, 2} in any seats
    assert len({ids[0], ids[3], ids[4]}) == 3  # {2, 2} and {1, 3} are other combinations


def test_evaluate_reports_at_drones_metrics_with_intervals(learner_file, capsys):
    small = ["--pool", "het", "--episodes", "6", "--seeds", "0", "1", "--cell-episodes", "1"]
    assert main([str(learner_file), *small, "--json"]) == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["runs"]["mine"]["het"]
    for m in ("success", "collision", "length", "steps_success", "reward", "learner_crash"):
        assert m in row and f"{m}_se" in row and len(row[f"{m}_ci95"]) == 2
    lo, hi = row["reward_ci95"]
    assert lo <= row["reward"] <= hi


NAN_PARTNER = """
import numpy as np


class Bad:
    name = "bad"

    def __init__(self, shape, value):
        self.shape, self.value = shape, value

    def act(self, obs):
        return np.full(self.shape(len(obs)), self.value)

    def reset(self, mask=None):
        pass


def nan(config):
    return Bad(lambda n: n, float("nan"))


def wide(config):
    return Bad(lambda n: (n, 2), 0.5)


def boom(config):
    raise RuntimeError("no such hardware")
"""


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda tmp: [str(tmp / "nowhere.pt")], "nowhere.pt: no such file or directory"),
        (lambda tmp: [str(tmp)], "neither a run directory with learner.pt"),
        (lambda tmp: [_write(tmp / "notes.pt", b"just some text\n")], "not a torch export"),
        (lambda tmp: [_truncated(tmp)], "not a torch export"),
        (lambda tmp: [_learner(tmp), "--pool", "nope"], "unknown pool 'nope'"),
        (lambda tmp: [_learner(tmp), "--partner", _partners(tmp, "boom")], "raised RuntimeError"),
        (lambda tmp: [_learner(tmp), "--partner", _partners(tmp, "wide")], "returned shape"),
        (lambda tmp: [_learner(tmp), "--partner", _partners(tmp, "nan")], "non-finite action"),
        (lambda tmp: [_learner(tmp), "--episodes", "0"], "must be at least 1"),
    ],
)
def test_every_bad_input_is_one_line_and_exit_code_2(tmp_path, capsys, make, message):
    assert main(make(tmp_path)) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1 and "Traceback" not in err


def test_a_d3qn_g_export_is_evaluated_as_a_learner(capsys):
    """D3QN-G reads the first evader only: it plays the evaluation's scenario (3 vs 2)."""
    from hola_ray.evaluation.pools import POOLS_DIR

    small = ["--episodes", "4", "--seeds", "0", "--cell-episodes", "1", "--json"]
    assert main([str(POOLS_DIR / "het" / "d3qn-g-1.pt"), "--pool", "hot", *small]) == 0
    out = capsys.readouterr().out
    assert "3 pursuers vs 2 evader(s)" in out
    assert 0 <= json.loads(out.strip().splitlines()[-1])["runs"]["d3qn-g-1"]["hot"]["success"] <= 1


def _write(path, data: bytes) -> str:
    path.write_bytes(data)
    return str(path)


def _learner(tmp) -> str:
    path = tmp / "mine.pt"
    torch.save(random_export(PursuitConfig().obs_dim, hidden=(8,)), path)
    return str(path)


def _truncated(tmp) -> str:
    whole = (tmp / "whole.pt").as_posix()
    torch.save(random_export(PursuitConfig().obs_dim, hidden=(8,)), whole)
    data = (tmp / "whole.pt").read_bytes()
    return _write(tmp / "cut.pt", data[: len(data) // 2])


def _partners(tmp, name: str) -> str:
    (tmp / "bad_partners.py").write_text(NAN_PARTNER)
    return f"{tmp / 'bad_partners.py'}:{name}"


def test_learners_of_one_file_name_are_told_apart_by_their_folder(learner_file, tmp_path, capsys):
    for run in ("run-a", "run-b"):
        (tmp_path / run).mkdir()
        (tmp_path / run / "best.pt").write_bytes(learner_file.read_bytes())
    small = ["--pool", "het", "--episodes", "2", "--seeds", "0", "--cell-episodes", "1", "--json"]
    assert (
        main([str(tmp_path / "run-a" / "best.pt"), str(tmp_path / "run-b" / "best.pt"), *small])
        == 0
    )
    out = capsys.readouterr().out
    last = json.loads(out.strip().splitlines()[-1])
    assert set(last["runs"]) == {"run-a/best", "run-b/best"}
    row = last["runs"]["run-a/best"]["het"]
    assert 0 <= row["learner_crash"] <= 1 and 0 <= row["teammate_crash"] <= 1
    assert "learner's own" in out
