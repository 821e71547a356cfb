"""The four named arenas and their obstacles of three shapes (contract §6): the config, the
geometry worked by hand, and every arena × team size through PettingZoo's API test with the
batched core matching the PettingZoo env step for step."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test
from test_pettingzoo import _drive  # tests/env is on the path (pytest prepends it)

from hola_ray.config.scenario import ARENAS, PAPER_BARS, TeamChangeConfig
from hola_ray.env import BatchedPursuit, ConfigError, PursuitConfig
from hola_ray.env._arena import nearest_on_disc, nearest_static, pack_params
from hola_ray.env.core import INITIAL_STATE_KEYS
from hola_ray.env.pettingzoo_env import PursuitEnv

SIZES = [(n_p, n_e) for n_p in (2, 3, 4, 5) for n_e in (1, 2, 3)]


def test_a_named_arena_brings_its_obstacles_and_a_given_set_is_custom():
    assert PursuitConfig().arena == "paper" and PursuitConfig().obstacles == PAPER_BARS
    assert PursuitConfig().discs == ()
    open_room = PursuitConfig(arena="open")
    assert open_room.obstacles == () and open_room.discs == ()
    blocks = PursuitConfig.from_dict({"arena": "blocks"})
    assert (blocks.obstacles, blocks.discs) == ARENAS["blocks"] and len(blocks.discs) == 1
    assert PursuitConfig.from_dict(blocks.to_dict()) == blocks  # a manifest round trip
    mine = PursuitConfig.from_dict({"discs": [[1.0, 2.0, 0.3]]})
    assert mine.arena == "custom" and mine.obstacles == () and mine.discs == ((1.0, 2.0, 0.3),)
    # an older manifest: the paper's bars, no arena key
    old = {k: v for k, v in PursuitConfig().to_dict().items() if k not in ("arena", "discs")}
    assert PursuitConfig.from_dict(old) == PursuitConfig()
    with pytest.raises(ConfigError, match="arena must be one of open, bar, blocks, paper"):
        PursuitConfig.from_dict({"arena": "moon"})
    with pytest.raises(ConfigError, match="obstacles must be arena open's own"):
        PursuitConfig.from_dict({"arena": "open", "obstacles": [[1, 1, 0.5, 0.5]]})
    with pytest.raises(ConfigError, match=r"discs\[0\] must be inside the arena"):
        PursuitConfig.from_dict({"discs": [[0.1, 1.0, 0.3]]})
    with pytest.raises(ConfigError, match=r"discs\[0\] must be of positive radius"):
        PursuitConfig.from_dict({"discs": [[1.0, 1.0, 0.0]]})


@pytest.mark.parametrize("arena", list(ARENAS))
def test_every_arena_leaves_the_spawn_strips_clear(arena):
    config = PursuitConfig(arena=arena)
    for x0, x1, y0, y1 in (config.pursuer_spawn, config.evader_spawn):
        for x in np.linspace(x0, x1, 13):
            for y in np.linspace(y0, y1, 5):
                for cx, cy, w, h in config.obstacles:  # the walls aside
                    gap = math.hypot(max(abs(x - cx) - w / 2, 0), max(abs(y - cy) - h / 2, 0))
                    assert gap > 0.15, (arena, x, y)
                for cx, cy, r in config.discs:
                    assert math.hypot(x - cx, y - cy) - r > 0.15, (arena, x, y)


def test_the_nearest_point_of_a_disc_by_hand():
    assert nearest_on_disc(3.0, 4.0, 0.0, 0.0, 1.0) == pytest.approx((0.6, 0.8, 4.0))
    assert nearest_on_disc(0.2, 0.0, 0.0, 0.0, 1.0)[2] == 0.0  # inside: touching
    config = PursuitConfig(arena="blocks")
    p = pack_params(config)
    # beside the disc at (1.8, 2.5), r 0.35: 0.15 m off its rim, nearer than any box or wall
    qx, qy, d = nearest_static(1.8 + 0.5, 2.5, p.rects[0], p.discs[0], 3.6, 5.0)
    assert (qx, qy, d) == pytest.approx((2.15, 2.5, 0.15))


def test_a_pursuer_flying_into_the_disc_collides_and_the_room_has_none():
    """A pursuer set 0.3 m below the blocks arena's disc, heading straight at it (+y), at
    0.03 m a step: nearer than the safe radius 0.1 after (0.3 − 0.1) / 0.03 = 6.7 steps, so
    disabled at step 7; in the open room the same flight is clear."""
    start = {"pursuer_pos": np.array([[1.8, 1.85], [0.3, 0.5], [3.3, 0.5]])}
    steps = {}
    for arena in ("blocks", "open"):
        env = BatchedPursuit(PursuitConfig(arena=arena), 1)
        env.reset(seeds=[0], initial_state={0: start})
        for t in range(8):
            result = env.step(np.array([[0.5, 0.5, 0.5]]))
            if result.disabled[0, 0]:
                steps[arena] = t + 1
                break
    assert steps == {"blocks": 7}


@pytest.mark.parametrize("arena", list(ARENAS))
@pytest.mark.parametrize(("n_p", "n_e"), SIZES)
def test_pettingzoo_api_on_every_arena_and_team_size(arena, n_p, n_e):
    config = PursuitConfig(arena=arena, n_pursuers=n_p, n_evaders=n_e, horizon=120)
    parallel_api_test(PursuitEnv(config), num_cycles=150)


@pytest.mark.parametrize("arena", list(ARENAS))
@pytest.mark.parametrize(("n_p", "n_e"), SIZES)
def test_the_batched_core_matches_pettingzoo_on_every_arena_and_team_size(arena, n_p, n_e):
    config = PursuitConfig(arena=arena, n_pursuers=n_p, n_evaders=n_e, horizon=250)
    rng = np.random.default_rng(n_p * 10 + n_e)
    _drive(3, [1, 2, 3], lambda t, obs: rng.random((3, n_p)), config)


def test_observation_slots_pad_a_smaller_team_and_every_hand_written_policy_reads_them():
    """`obs_pursuers` 5 and `obs_evaders` 3 at 3 vs 2: each pursuer's observation is the
    paper's with an unobserved teammate slot (distance `unobserved_distance`, bearing 0)
    after each block's real ones; a hand-written pursuer acts the same on either."""
    from hola_ray.policies import make_policy

    plain = PursuitConfig(observe_headings=True)
    slots = PursuitConfig(observe_headings=True, obs_pursuers=5, obs_evaders=3)
    assert (plain.pursuer_slots, plain.evader_slots) == (3, 2) and plain.obs_pursuers is None
    assert PursuitConfig(obs_pursuers=3) == plain.__class__()  # no slot beyond the team
    assert dataclasses.replace(slots, n_pursuers=4).pursuer_slots == 5
    assert dataclasses.replace(plain, n_evaders=3).evader_slots == 3
    assert PursuitConfig().in_arena("blocks") == PursuitConfig(arena="blocks")
    assert slots.obs_dim == plain.obs_dim + 3 + 2 * 2 + 2  # an evader, 2 teammates, 2 headings
    a, b = BatchedPursuit(plain, 4), BatchedPursuit(slots, 4)
    a.reset(seeds=[0, 1, 2, 3])
    b.reset(seeds=[0, 1, 2, 3])
    for _ in range(30):
        a.step(np.full((4, 3), 0.55))
        b.step(np.full((4, 3), 0.55))
    la, lb = plain.layout, slots.layout
    far = plain.unobserved_distance
    for i in range(3):
        x, y = a.obs[:, i], b.obs[:, i]
        np.testing.assert_array_equal(x[:, :6], y[:, :6])  # the two evaders
        np.testing.assert_array_equal(y[:, 6:9], np.tile([far, 0, 0], (4, 1)))
        np.testing.assert_array_equal(
            x[:, la.obstacle : la.own], y[:, lb.obstacle : lb.obstacle + 6]
        )
        np.testing.assert_array_equal(y[:, lb.obstacle + 6 : lb.own], np.tile([far, 0] * 2, (4, 1)))
        np.testing.assert_array_equal(x[:, la.own : la.base_dim], y[:, lb.own : lb.base_dim])
        np.testing.assert_array_equal(x[:, la.base_dim :], y[:, lb.base_dim : lb.base_dim + 2])
        np.testing.assert_array_equal(y[:, lb.base_dim + 2 :], 0.0)
    for name in ("greedy", "vicsek", "apf-a-3", "surround-1", "surround-2"):
        got = make_policy(name, slots).act(b.obs.reshape(-1, slots.obs_dim))
        want = make_policy(name, plain).act(a.obs.reshape(-1, plain.obs_dim))
        np.testing.assert_array_equal(got, want, err_msg=name)
    assert PursuitConfig.from_dict(slots.to_dict()) == slots
    old = {k: v for k, v in plain.to_dict().items() if not k.startswith("obs_")}
    assert PursuitConfig.from_dict(old) == plain
    with pytest.raises(ConfigError, match=r"obs_pursuers must be an integer >= n_pursuers \(4\)"):
        PursuitConfig(n_pursuers=4, obs_pursuers=3)


def _team_env(arena="paper", **team):
    config = PursuitConfig.from_dict({"n_pursuers": 5, "arena": arena, "team": team})
    return config, BatchedPursuit(config, 64)


def test_a_team_that_starts_short_keeps_its_waiting_seats_out_of_play():
    """`team.present` 3 of 5: seat 0 (fixed) and two drawn seats in play; the two waiting
    are neither observed nor obstacles, and the draw is the episode's own."""
    config, env = _team_env(present=3)
    env.reset(seeds=np.arange(64))
    present = env.pursuer_present.copy()
    assert (present.sum(axis=1) == 3).all() and present[:, 0].all()
    assert (env.pursuer_waiting == ~present).all() and (env.pursuer_active == present).all()
    assert len({tuple(row) for row in present.tolist()}) > 3  # the seats are drawn
    again = BatchedPursuit(config, 64)
    again.reset(seeds=np.arange(64))
    np.testing.assert_array_equal(again.pursuer_present, present)
    lay = config.layout
    for b in range(8):
        for i in np.flatnonzero(present[b]):
            mates = [j for j in range(5) if j != i]
            for slot, j in enumerate(mates):
                distance = env.obs[b, i, lay.teammates + 2 * slot]
                if not present[b, j]:
                    assert distance == config.unobserved_distance
    # a pursuer put on a waiting seat's spot does not collide with it
    b = 0
    waiting, playing = np.flatnonzero(~present[b]), np.flatnonzero(present[b])
    spot = env.pursuer_pos[b].copy()
    spot[playing[1]] = spot[waiting[0]] + [0.05, 0.0]
    env.reset(mask=np.eye(64, dtype=bool)[0], seeds=[0], initial_state={0: {"pursuer_pos": spot}})
    result = env.step(np.full((64, 5), 0.5))
    assert not result.disabled[0].any()


def test_teammates_leave_and_join_at_drawn_steps_within_the_rules():
    """Four changes in the window 0.1–0.6 of the horizon: the team in play changes by one
    at each, never seat 0, and no leave takes the pursuers flying below `min_team`; a
    joiner appears in the pursuers' spawn heading +y at the end of a step (it acts from
    the next); a leaver is out of play for good."""
    config, env = _team_env("open", present=3, changes=4, min_team=2)
    action = 0.55  # circling, 0.76 m across: most fly the whole window in the open room
    env.reset(seeds=np.arange(64))
    lo, hi = int(0.1 * config.horizon), int(0.6 * config.horizon)
    before = env.pursuer_present.copy()
    flying_before = env.pursuer_active.copy()
    joined = left = 0
    x0, x1, y0, y1 = config.pursuer_spawn
    for _ in range(hi + 1):
        env.step(np.full((64, 5), action))
        now = env.pursuer_present
        for b in np.flatnonzero(~env.done | (now != before).any(axis=1)):
            for i in np.flatnonzero(now[b] != before[b]):
                assert lo <= env.t[b] <= hi and i != 0
                if now[b, i]:
                    joined += 1
                    assert not env.pursuer_waiting[b, i]
                    assert env.pursuer_heading[b, i] == 0.5 * math.pi  # it acts next step
                    px, py = env.pursuer_pos[b, i]
                    assert x0 <= px <= x1 and y0 <= py <= y1
                else:
                    left += 1
                    assert not env.pursuer_waiting[b, i]  # landed: it does not come back
                    assert flying_before[b].sum() > 2  # min_team 2 still fly after it
        before = now.copy()
        flying_before = env.pursuer_active.copy()
    assert joined > 20 and left > 5  # 95 and 13 (a leave needs 3 flying)
    assert env.pursuer_present[:, 0].all()


def test_the_team_is_drawn_beside_the_flight():
    """The team's draws have streams of their own: an open team starts where the whole team
    would, seeded alike, and which teammate leaves or joins does not hang on how the
    pursuers flew: two ways of flying meet the same teams wherever nobody has crashed."""
    config, circling = _team_env("open", present=3, changes=4, min_team=2, window=[0.0, 0.05])
    whole = BatchedPursuit(dataclasses.replace(config, team=TeamChangeConfig()), 64)
    other = BatchedPursuit(config, 64)
    for env in (circling, whole, other):
        env.reset(seeds=np.arange(64))
    for key in INITIAL_STATE_KEYS:
        np.testing.assert_array_equal(getattr(circling, key), getattr(whole, key))
    np.testing.assert_array_equal(circling.pursuer_present, other.pursuer_present)
    clean = np.ones(64, dtype=bool)
    compared = 0
    for _ in range(int(0.05 * config.horizon) + 1):  # the changes come before crashes do
        before = circling.pursuer_present.copy()
        circling.step(np.full((64, 5), 0.55))
        other.step(np.full((64, 5), 0.45))
        for env in (circling, other):
            clean &= ~env.done & (env.pursuer_active == env.pursuer_present).all(axis=1)
        np.testing.assert_array_equal(circling.pursuer_present[clean], other.pursuer_present[clean])
        compared += int((circling.pursuer_present != before)[clean].any(axis=1).sum())
    assert not np.array_equal(circling.pursuer_pos, other.pursuer_pos)  # they flew apart
    assert compared > 50  # team changes met alike by both (105 of them)


def test_the_paper_team_draws_nothing_more():
    """With the team closed (the default) no seat waits and the episode's stream is the
    paper's: the same first 50 steps as a scenario whose team section is spelled out."""
    a = BatchedPursuit(PursuitConfig(), 8)
    b = BatchedPursuit(PursuitConfig.from_dict({"team": {"changes": 0, "present": None}}), 8)
    a.reset(seeds=np.arange(8))
    b.reset(seeds=np.arange(8))
    for _ in range(50):
        a.step(np.full((8, 3), 0.6))
        b.step(np.full((8, 3), 0.6))
    np.testing.assert_array_equal(a.evader_pos, b.evader_pos)
    assert a.pursuer_present.all() and not a.pursuer_waiting.any()


def test_the_arena_drawing_holds_every_box_and_disc(tmp_path):
    from matplotlib import patches
    from matplotlib.figure import Figure

    from hola_ray.env.render import arenas_figure, draw_arena

    ax = Figure().add_subplot()
    draw_arena(ax, PursuitConfig(arena="blocks"))
    circles = [p for p in ax.patches if isinstance(p, patches.Circle)]
    assert [(c.center, c.radius) for c in circles] == [((1.8, 2.5), 0.35)]
    filled = [p for p in ax.patches if isinstance(p, patches.Rectangle) and p.get_fill()]
    assert len(filled) == 2  # the two squares (the walls and spawn strips are outlines)
    arenas_figure(str(tmp_path / "arenas.png"))
    assert (tmp_path / "arenas.png").stat().st_size > 1000


def test_pettingzoo_agents_are_the_pursuers_in_play():
    """PettingZoo's API test with a team that starts at 3 of 5 and changes four times
    early; agents who join appear with their first observation, agents who leave end."""
    config = PursuitConfig.from_dict(
        {
            "n_pursuers": 5,
            "horizon": 300,
            "team": {"present": 3, "changes": 4, "window": [0.02, 0.3]},
        }
    )
    parallel_api_test(PursuitEnv(config), num_cycles=300)
    env = PursuitEnv(config)
    rng = np.random.default_rng(0)
    came = went = 0
    for seed in range(20):
        env.reset(seed=seed)
        assert len(env.agents) == 3 and "pursuer_0" in env.agents
        while env.agents:
            live = list(env.agents)
            obs, _, term, _, _ = env.step({a: rng.random(1).astype(np.float32) for a in live})
            for a in set(env.agents) - set(live):
                came += 1
                assert a in obs and env.core.pursuer_present[0, env._index[a]]
            for a in live:
                i = env._index[a]
                if term[a] and not env.core.pursuer_present[0, i]:
                    went += 1
    assert came > 5 and went > 5


def test_a_team_size_drawn_per_episode():
    """`team.present` [2, 5]: each episode of one batch starts with its own team, every
    size from 2 to 5 among 64 episodes, seat 0 in play in each; a manifest round trip."""
    config, env = _team_env(present=[2, 5])
    assert config.team.present == (2, 5) and config.team.present_range == (2, 5)
    assert PursuitConfig.from_dict(config.to_dict()) == config
    env.reset(seeds=np.arange(64))
    sizes = env.pursuer_present.sum(axis=1)
    assert set(sizes.tolist()) == {2, 3, 4, 5} and env.pursuer_present[:, 0].all()
    with pytest.raises(ConfigError, match="team.present must be in"):
        PursuitConfig.from_dict({"n_pursuers": 3, "team": {"present": [2, 4]}})
    with pytest.raises(ConfigError, match="a pair"):
        PursuitConfig.from_dict({"n_pursuers": 3, "team": {"present": [3, 2]}})


def test_a_learner_samples_batch_spans_the_env_steps_its_seats_fill():
    """`learner_samples`: a batch of train_batch transitions spans train_batch / seats env
    steps: one seat for a whole team, the fixed ones where it changes, every pursuer in
    play in self-play (for a team that changes, the mean of its starting sizes)."""
    from hola_ray.oracle.trainer import learner_seats_per_step

    def env(**team):
        return PursuitConfig.from_dict({"n_pursuers": 5, "team": team})

    assert learner_seats_per_step(PursuitConfig(), False) == 1
    assert learner_seats_per_step(PursuitConfig(), True) == 3
    assert learner_seats_per_step(env(present=4, changes=2, fixed=2), False) == 2
    assert learner_seats_per_step(env(present=[2, 5], changes=2), True) == 3.5
    assert learner_seats_per_step(env(), True) == 5


def test_the_learner_sits_in_the_seat_that_stays_when_the_team_changes():
    """Evaluation's teams: the learner in a random seat for a closed team (the draws as
    they were), in seat 0 when the team changes; an open evaluation plays end to end and a
    crash counts only for a seat in play."""
    from hola_ray.evaluation.teams import draw_teams, play
    from hola_ray.policies import make_policy

    closed = draw_teams(np.random.default_rng(3), 500, 5, 2)
    rng = np.random.default_rng(3)
    mates = rng.integers(1, 3, size=(500, 5))
    mates[np.arange(500), rng.integers(0, 5, size=500)] = 0
    np.testing.assert_array_equal(closed, mates)
    assert len(set(np.argwhere(closed == 0)[:, 1].tolist())) == 5
    opened = draw_teams(np.random.default_rng(3), 500, 5, 2, fixed=1)
    assert (opened[:, 0] == 0).all() and (opened[:, 1:] > 0).all()

    config = PursuitConfig.from_dict(
        {"arena": "blocks", "n_pursuers": 5, "team": {"present": [2, 5], "changes": 2}}
    )
    learner = make_policy("vicsek", config)
    members = [make_policy(name, config) for name in ("greedy", "surround-1")]
    played = play(learner, members, config, 40, [0])
    assert played["success"].shape == (40,)
    assert 0.0 <= played["learner_crash"].mean() <= played["collision"].mean() <= 1.0


def test_a_learner_may_control_k_of_the_seats():
    """`team.fixed: 2` of 5: training maps both fixed seats of every episode to the learner
    and counts two of its transitions per env step; evaluation seats it in both (the other
    seats drawn as for one), its crash is one of its seats', a teammate crash the share of
    the other three."""
    from types import SimpleNamespace

    from hola_ray.evaluation.metrics import zero_shot_values
    from hola_ray.evaluation.teams import draw_teams, partner_combinations, play
    from hola_ray.oracle.mapping import LEARNER, PartnerMapping
    from hola_ray.policies import make_policy

    config = PursuitConfig.from_dict(
        {"n_pursuers": 5, "team": {"present": 4, "changes": 2, "fixed": 2}}
    )
    assert config.team.learner_seats == (0, 1) and PursuitConfig().team.learner_seats is None
    mapping = PartnerMapping(5, {"member_0": 1.0, "member_1": 1.0}, True, learner_seats=(0, 1))
    for episode in range(20):
        seats = mapping.assignment(str(episode))
        assert seats[:2] == [LEARNER, LEARNER] and LEARNER not in seats[2:]
    one = draw_teams(np.random.default_rng(4), 300, 5, 3, fixed=1)
    two = draw_teams(np.random.default_rng(4), 300, 5, 3, fixed=2)
    assert (two[:, :2] == 0).all() and np.array_equal(two[:, 2:], one[:, 2:])
    assert len(set(partner_combinations(two, 3).tolist())) == 10  # multisets of 3 of 3
    crashed = np.array([[False, True, True, False, False], [False, False, False, False, True]])
    result = SimpleNamespace(
        crashed=crashed,
        success=np.array([False, True]),
        collision=crashed.any(axis=1),
        length=np.array([100, 50]),
        team_return=np.array([5.0, 10.0]),
        played=np.array([[True] * 5, [True, True, True, False, True]]),
    )
    values = zero_shot_values(result, two[:2] == 0, 5)
    np.testing.assert_array_equal(values["learner_crash"], [1.0, 0.0])
    np.testing.assert_allclose(values["teammate_crash"], [1 / 3, 1 / 2])  # of those in play
    np.testing.assert_allclose(values["reward"], [5.0 / 5, 10.0 / 4])
    learner = make_policy("vicsek", config)
    played = play(learner, [make_policy("greedy", config)], config, 24, [0])
    assert played["learner_crash"].shape == (24,)


def test_an_arena_drawn_per_episode_plays_as_that_arena_does():
    """`env.arenas`: each episode draws its layout beside its own stream (all four among
    64), then plays exactly as a scenario fixed in that arena seeded alike: the same start,
    observations, rewards, moves, step for step, to the end. Padding a layout with spare
    shapes changes nothing. A mix of one arena draws nothing: the paper's episodes."""
    mixed = PursuitConfig(arenas=("open", "bar", "blocks", "paper"), horizon=300)
    assert mixed.arena == "open" and PursuitConfig.from_dict(mixed.to_dict()) == mixed
    batch = BatchedPursuit(mixed, 64)
    batch.reset(seeds=np.arange(64))
    assert set(batch.layout_index.tolist()) == {0, 1, 2, 3}
    picks = [int(np.flatnonzero(batch.layout_index == a)[0]) for a in range(4)]
    twins = []
    for b in picks:
        twin = BatchedPursuit(batch.config_of(b), 1)
        assert twin.config.arena == batch.arena_of(b) == mixed.arenas[batch.layout_index[b]]
        assert not twin.config.arenas
        twin.reset(seeds=[b])
        for key in INITIAL_STATE_KEYS:
            np.testing.assert_array_equal(getattr(twin, key)[0], getattr(batch, key)[b])
        np.testing.assert_array_equal(twin.obs[0], batch.obs[b])
        twins.append(twin)
    rng = np.random.default_rng(5)
    collided = 0
    for _ in range(mixed.horizon):
        actions = rng.random((64, 3))
        running = ~batch.done.copy()
        result = batch.step(actions)
        for b, twin in zip(picks, twins, strict=True):
            if running[b]:
                out = twin.step(actions[b : b + 1])
                np.testing.assert_array_equal(out.obs[0], result.obs[b])
                np.testing.assert_array_equal(out.reward[0], result.reward[b])
                np.testing.assert_array_equal(twin.evader_pos[0], batch.evader_pos[b])
        if batch.done[picks].all():
            break
    for b, twin in zip(picks, twins, strict=True):
        assert twin.episode_metrics(0) == batch.episode_metrics(b)
        collided += twin.collided[0]
    assert collided > 0  # random headings crash: the obstacles were there to hit
    one = BatchedPursuit(PursuitConfig(arenas=("paper",)), 8)
    paper = BatchedPursuit(PursuitConfig(), 8)
    np.testing.assert_array_equal(one.reset(seeds=np.arange(8)), paper.reset(seeds=np.arange(8)))


def test_an_arena_mix_names_known_arenas_once_each():
    with pytest.raises(ConfigError, match=r"arenas\[1\] must be one of"):
        PursuitConfig(arenas=("open", "custom"))
    with pytest.raises(ConfigError, match="named once each"):
        PursuitConfig(arenas=("open", "open"))
    with pytest.raises(ConfigError, match="arena must be one of arenas"):
        PursuitConfig(arena="paper", arenas=("open", "bar"))
    assert PursuitConfig(arena="bar", arenas=("open", "bar")).obstacles == ARENAS["bar"][0]
    assert PursuitConfig(arenas=("bar", "open")).in_arena("open").arenas == ()


@pytest.mark.parametrize("n_p", [2, 5])
def test_pettingzoo_api_and_the_core_with_arenas_drawn_per_episode(n_p):
    config = PursuitConfig(
        arenas=tuple(ARENAS), n_pursuers=n_p, n_evaders=2, horizon=150, obs_pursuers=5
    )
    parallel_api_test(PursuitEnv(config), num_cycles=150)
    rng = np.random.default_rng(n_p)
    _drive(4, [7, 8, 9, 10], lambda t, obs: rng.random((4, n_p)), config)


def test_a_member_of_an_open_team_is_judged_as_the_papers_team_in_its_own_slots():
    """The bar of contract §5.1 is for 3 pursuers: a population for open teams is judged at
    3 vs its evaders in the paper's arena, read in its own slots; the paper's team as is."""
    paper = PursuitConfig(n_evaders=2)
    assert paper.judged() is paper and PursuitConfig(arena="bar").judged().arena == "bar"
    open_team = PursuitConfig(
        n_pursuers=5,
        n_evaders=2,
        obs_pursuers=5,
        arenas=("open", "blocks"),
        team=TeamChangeConfig(present=(2, 5), changes=2),
    )
    judged = open_team.judged()
    assert (judged.n_pursuers, judged.pursuer_slots, judged.n_evaders) == (3, 5, 2)
    assert (judged.arena, judged.arenas, judged.team.open) == ("paper", (), False)
    assert judged.layout == open_team.layout  # its members read it as they trained


def test_the_team_sizes_an_episode_can_reach_and_the_seats_a_learner_holds():
    """`sizes`: the paper's team alone where closed (one pursuer too); where it changes,
    from the smallest start less a leave a change (not below `min_team` or the fixed
    seats) to the largest start plus a join a change (not beyond the seats). A team that
    changes keeps a learner's seat; a member below 3 slots is judged in its own team."""
    T = TeamChangeConfig
    assert T().sizes(3) == (3,) and T().sizes(1) == (1,) and T().sizes(5) == (5,)
    assert T(present=5, changes=1).sizes(5) == (4, 5)
    assert T(present=(2, 5), changes=2, min_team=2).sizes(5) == (2, 3, 4, 5)
    assert T(present=3, changes=1, min_team=3).sizes(5) == (3, 4)
    assert T(present=4, changes=3, fixed=3).sizes(5) == (3, 4, 5)
    assert T(present=(2, 3)).sizes(5) == (2, 3)
    with pytest.raises(ConfigError, match="team.fixed must be >= 1 where the team changes"):
        PursuitConfig.from_dict({"team": {"changes": 1, "fixed": 0}})
    assert PursuitConfig.from_dict({"team": {"fixed": 0}}).team.learner_seats is None
    pair = PursuitConfig(n_pursuers=2)
    assert pair.judged() is pair
    drawn = PursuitConfig(n_pursuers=2, arenas=("open", "bar")).judged()
    assert (drawn.n_pursuers, drawn.arena, drawn.arenas) == (2, "paper", ())


def test_a_replay_draws_the_episodes_own_arena_and_only_the_pursuers_in_play(tmp_path):
    """An episode of drawn arenas and a team that changes, recorded: it names the arena it
    was played in (the one its seed draws), and a seat waiting to join is out of play in
    the record until it joins; the drawing and the GIF are made of that arena."""
    from hola_ray.env.render import animate_trajectory, plot_trajectory
    from hola_ray.evaluation.trajectory import record
    from hola_ray.policies import make_policy

    config = PursuitConfig.from_dict(
        {
            "arenas": ["bar", "blocks"],
            "n_pursuers": 5,
            "horizon": 150,
            "team": {"present": 3, "changes": 2, "window": [0.05, 0.3]},
        }
    )
    team = [make_policy("greedy", config)] * 5
    drawn = set()
    for seed in range(6):
        traj = record(config, team, seed=seed)
        core = BatchedPursuit(config, 1)
        core.reset(seeds=[seed])
        assert traj.arena == core.arena_of(0) and traj.scenario(config).arena == traj.arena
        present = traj.present()
        assert present[0].sum() == 3 and present[:, 0].all()  # seat 0 never leaves
        drawn.add(traj.arena)
    assert drawn == {"bar", "blocks"}
    plot_trajectory(config, traj, str(tmp_path / "t.png"))
    assert animate_trajectory(config, traj, str(tmp_path / "t.gif"), stride=25) > 1
    assert (tmp_path / "t.png").stat().st_size > 10_000
