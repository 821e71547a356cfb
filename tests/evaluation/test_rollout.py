from __future__ import annotations

import numpy as np
import pytest

from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation import mean_and_se, rollout
from hola_ray.evaluation.table import table_rows
from hola_ray.evaluation.trajectory import record
from hola_ray.policies import Greedy, Vicsek


def test_mean_and_se_hand_worked():
    # mean 0.5; sample std of (0, 1, 0, 1) = sqrt(1/3); se = sqrt(1/3)/2 = 0.288675...
    assert mean_and_se(np.array([0, 1, 0, 1])) == pytest.approx((0.5, 0.2886751346))
    assert mean_and_se(np.array([3.0])) == (3.0, 0.0)


def test_rollout_is_deterministic_and_consistent(config):
    team = [Vicsek(config)] * 3
    a = rollout(config, team, 40, seed=3)
    b = rollout(config, team, 40, seed=3, batch_size=7)
    for field in ("success", "collision", "length", "team_return"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    assert np.array_equal(a.success, a.captures == config.n_evaders)
    assert np.all(a.length[~a.success & ~a.collision] == config.horizon)
    s = a.summary()
    assert s["episodes"] == 40 and 0 <= s["success"] <= 1 and s["success_se"] >= 0


def test_mixed_assignment_uses_each_policy_in_its_slots(config):
    pool = [Greedy(config), Vicsek(config)]
    assignment = np.array([[0, 0, 0], [1, 1, 1], [0, 1, 0]])
    mixed = rollout(config, pool, 3, assignment=assignment, seed=1)
    greedy = rollout(config, [pool[0]] * 3, 3, seed=1)
    vicsek = rollout(config, [pool[1]] * 3, 3, seed=1)
    assert mixed.length[0] == greedy.length[0]
    assert mixed.length[1] == vicsek.length[1]
    with pytest.raises(ValueError, match="assignment"):
        rollout(config, pool, 3, assignment=np.full((3, 3), 2))


def test_table_ii_rows_are_three_copies_against_one_evader_beside_the_paper():
    """Each row is three separate copies of the agent against one evader, pooled over the
    seeds, set beside the paper's figure with the difference."""
    from hola_ray.evaluation.table import PAPER_TABLE_II, format_table

    rows = table_rows(["greedy", "vicsek"], episodes=20, seeds=[0, 1])
    assert [r["agent"] for r in rows] == ["Greedy", "VICSEK"]
    one = PursuitConfig(n_evaders=1)
    for row, make in zip(rows, (Greedy, Vicsek), strict=True):
        runs = [rollout(one, [make(one) for _ in range(3)], 20, seed=s) for s in (0, 1)]
        success = np.concatenate([r.success for r in runs])
        assert (row["sr"], row["sr_se"]) == mean_and_se(success)
        assert row["ael"] == np.concatenate([r.length for r in runs]).mean()
        assert row["collision"] == np.concatenate([r.collision for r in runs]).mean()
        assert row["episodes"] == 40
        assert (row["paper_sr"], row["paper_ael"]) == PAPER_TABLE_II[row["agent"]]
    text = format_table(rows)
    assert f"{rows[0]['sr'] - 0.62:>+6.0%}" in text.splitlines()[2]  # Greedy's ΔSR


def test_crashed_says_which_seat_collided(config, straight):
    """A pursuer that never turns crashes in (nearly) every episode, in its own seat; the
    episode's collision flag is exactly 'some seat crashed'."""
    result = rollout(config, [straight, Vicsek(config), Vicsek(config)], 60, seed=5)
    assert result.crashed.shape == (60, config.n_pursuers)
    assert np.array_equal(result.collision, result.crashed.any(axis=1))
    assert result.crashed[:, 0].mean() > 0.9
    assert result.crashed[:, 0].mean() > 3 * result.crashed[:, 1:].mean()
    team = rollout(config, [Vicsek(config)] * 3, 60, seed=5)
    assert np.array_equal(team.collision, team.crashed.any(axis=1))


FIELDS = ("success", "collision", "length", "team_return", "captures", "crashed")


@pytest.mark.parametrize("mid", ["d3qn-g-1", "d3qn-g-2"])
def test_one_stateful_policy_in_several_seats_plays_as_separate_copies(mid):
    """D3QN-G holds its pair per row for `decision_interval` steps: one object listed for
    three seats must play the same episodes as three loaded copies (it once shared and
    overwrote one row state: 95.7 % against 96.3 % success, length 365 against 344)."""
    from hola_ray.evaluation.pools import load_pool

    one = PursuitConfig(n_evaders=1)
    shared = load_pool("het", one)[mid]
    copies = [load_pool("het", one)[mid] for _ in range(3)]
    a = rollout(one, [shared] * 3, 120, seed=7)
    b = rollout(one, copies, 120, seed=7)
    for field in FIELDS:
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)
    # the same object as two candidates of an assignment (the BR-Prox reference lists every
    # pool member twice: as the candidate and among the partners)
    teams = np.tile([[0, 1, 2]], (120, 1))
    c = rollout(one, [shared, shared, copies[2]], 120, assignment=teams, seed=7)
    for field in FIELDS:
        np.testing.assert_array_equal(getattr(c, field), getattr(b, field), err_msg=field)
    # and one recorded episode
    assert record(one, [shared] * 3, seed=4).metrics == record(one, copies, seed=4).metrics


def test_the_batched_path_plays_the_episodes_of_the_reference_path():
    """A learner among drawn teammates of every kind (learned, hand-written, D3QN-G with its
    per-row state), as validation and the zero-shot evaluation play them: the batched path
    (learned policies stacked, stateless ones asked for running episodes only) against the
    reference path (every policy on every row it seats): the same episodes, so the same
    outcomes but where an action's last bit rounds apart and an episode parts."""
    from hola_ray.evaluation.pools import load_pool, load_validation
    from hola_ray.evaluation.teams import draw_teams

    one = PursuitConfig(n_evaders=1)
    validation = list(load_validation("validation", one).values())
    members = [*validation, *load_pool("het", one).values()]  # learned, APF-A, Greedy, D3QN-G
    learner = validation[0]
    teams = draw_teams(np.random.default_rng(5), 200, 3, len(members))
    policies = [learner, *members]
    a = rollout(one, policies, 200, assignment=teams, seed=11)
    b = rollout(one, policies, 200, assignment=teams, seed=11, batched=False)
    same = (a.success == b.success) & (a.collision == b.collision) & (a.length == b.length)
    assert same.mean() >= 0.95, f"{same.mean():.0%} of episodes alike"
    assert abs(a.success.mean() - b.success.mean()) <= 0.03
