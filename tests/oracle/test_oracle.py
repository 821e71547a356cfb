"""The Oracle in RLlib: partners follow φ, frozen partners act with the pushed weights, and
the plain-torch export plays exactly like RLlib's module. One Ray session for the module."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hola_ray.methods.config import RunConfig
from hola_ray.oracle import LEARNER, PartnerMapping, member_module
from hola_ray.oracle.connectors import mean_policy_logp
from hola_ray.policies.learned import (
    MLPPolicy,
    beta_concentrations,
    rescale_action,
)

CONFIG = RunConfig.from_dict(
    {
        "env": {"horizon": 60},
        "oracle": {
            "hidden": [32, 32],
            "train_batch": 400,
            "minibatch": 200,
            "epochs": 1,
            "envs_per_runner": 4,
            "env_steps": 400,
        },
        "population": {"max_size": 3, "initial_size": 3, "top_m": 1},
    }
)
OBS = np.random.default_rng(0).uniform(-1, 1, (64, CONFIG.env.obs_dim)).astype(np.float32)
UNIFORM_STD = 1 / np.sqrt(3)
"""The widest Beta with both concentrations ≥ 1 is the uniform: std 2/√12 on [−1, 1]."""


def beta_mean(inputs: np.ndarray) -> np.ndarray:
    """The Beta's deterministic action on [−1, 1] from RLlib's action-dist inputs [N, 2]."""
    c1, c0 = beta_concentrations(torch.as_tensor(inputs))
    return (2.0 * (c1 / (c1 + c0)) - 1.0)[:, 0].numpy()


def loss_batch(rng: np.random.Generator, n: int, masked: bool) -> dict[str, torch.Tensor]:
    """n random rows of the columns the PPO loss reads, with a loss mask keeping ~70 %."""
    f32 = torch.float32
    batch = {
        "obs": torch.as_tensor(rng.uniform(-1, 1, (n, CONFIG.env.obs_dim)), dtype=f32),
        "actions": torch.as_tensor(rng.uniform(-0.9, 0.9, (n, 1)), dtype=f32),
        "action_logp": torch.as_tensor(rng.normal(0, 0.3, n), dtype=f32),
        "action_dist_inputs": torch.as_tensor(rng.normal(0, 1, (n, 2)), dtype=f32),
        "advantages": torch.as_tensor(rng.normal(0, 2, n), dtype=f32),
        "value_targets": torch.as_tensor(rng.normal(0, 5, n), dtype=f32),
    }
    if masked:
        batch["loss_mask"] = torch.as_tensor(rng.uniform(size=n) < 0.7)
    return batch


@pytest.fixture(scope="module")
def oracle(ray_session):
    o = CONFIG.strategy.make_oracle(CONFIG)
    o.train(400, progress=False)  # weights pushed after a first train() are the hard case
    yield o
    o.stop()


def test_a_local_ray_without_the_dashboard_starts_no_dashboard_head(oracle):
    """This module's Ray, started as the commands start theirs without the dashboard
    (`lean_local_ray`), has no dashboard head (Ray 2.60 starts one regardless and waits
    for it), yet runs the Oracle's env runners and reports no dashboard."""
    import ray
    from ray._private import ray_constants

    started = ray._private.worker._global_node.all_processes
    assert ray_constants.PROCESS_TYPE_RAYLET in started
    assert ray_constants.PROCESS_TYPE_DASHBOARD not in started
    assert not ray._private.worker._global_node.webui_url
    assert ray.get_runtime_context().get_node_id()


def test_a_local_rays_workers_run_rays_own_worker_with_the_start_paused(oracle):
    """This module's Ray, started as the commands start theirs (`lean_local_ray`), runs each
    Python worker through `hola_ray/ray_worker.py`: Ray's own `default_worker.py` is the
    worker's `__main__`, and the worker started with the cyclic collector paused (off still,
    or resumed with the start frozen). Its env runners ran on such workers."""
    import gc
    import sys

    from hola_ray import ray_worker

    def state(*_):
        return sys.modules["__main__"].__file__, gc.isenabled(), gc.get_freeze_count()

    seen = oracle.algo.env_runner_group.foreach_env_runner(state, local_env_runner=False)
    assert seen
    for main, enabled, frozen in seen:
        assert main == ray_worker.default_worker()
        assert not enabled or frozen > 0, (enabled, frozen)


def test_building_an_oracle_applies_the_rllib_fixes_in_its_processes(oracle):
    """`third_party.apply_rllib()` is called where the Oracle builds RLlib's parts, not by an
    import: in the driver and in every env runner (each its own process) both fixes are in
    place (torch's `lazy_dynamo` with them), and no env runner loaded the inductor."""
    from hola_ray import third_party

    here = third_party.rllib_in_place()
    assert here["fast_connectors"] and here["light_seeding"], here
    runners = oracle.algo.env_runner_group.foreach_env_runner(
        lambda runner: third_party.rllib_in_place(), local_env_runner=False
    )
    assert here["lazy_dynamo"], here
    fixed = {
        "fast_connectors": True,
        "light_seeding": True,
        "lazy_dynamo": True,
        "inductor_loaded": False,
    }
    assert runners and all(r == fixed for r in runners), runners


def random_state(oracle, seed):
    rng = np.random.default_rng(seed)
    base = oracle.weights([LEARNER])[LEARNER]
    return {
        k: (np.asarray(v) + rng.normal(0, 0.5, np.shape(v))).astype(np.float32)
        for k, v in base.items()
    }


@pytest.mark.parametrize("slot", [0, 1, 2])
def test_one_hot_phi_maps_every_partner_slot_to_that_module(oracle, slot):
    target = member_module(slot)
    oracle.set_phi({target: 1.0}, salt=slot)

    def sample_modules(runner):
        """Module ids of every pursuer slot in fresh episodes, read off the episodes.
        Enough steps for about 50 episodes: a slot the learner never drew in n episodes
        has chance 3·(2/3)^n (5% at n = 10, 5e-9 at n = 50)."""
        episodes = runner.sample(num_timesteps=2400, force_reset=True)
        return [{aid: ep.module_for(aid) for aid in ep.agent_ids} for ep in episodes]

    seen = oracle.algo.env_runner_group.foreach_env_runner(sample_modules, local_env_runner=False)
    assert seen and all(seen)
    learner_slots = set()
    for runner_episodes in seen:
        for mapping in runner_episodes:
            assert sorted(mapping.values()) == sorted([LEARNER, target, target])
            learner_slots |= {a for a, m in mapping.items() if m == LEARNER}
    assert learner_slots == {"pursuer_0", "pursuer_1", "pursuer_2"}  # a random slot


def test_mapping_is_consistent_within_an_episode_and_follows_phi():
    m = PartnerMapping(3, {"a": 3.0, "b": 1.0}, learner=True, salt=5)
    draws = [m.assignment(f"ep{k}") for k in range(4000)]
    assert all(d.count(LEARNER) == 1 for d in draws)
    assert draws[7] == m.assignment("ep7")
    partners = [x for d in draws for x in d if x != LEARNER]
    share_a = partners.count("a") / len(partners)
    assert abs(share_a - 0.75) < 4 * np.sqrt(0.75 * 0.25 / len(partners))


def test_a_whole_team_mapping_seats_one_member_in_every_slot_drawn_by_phi():
    """MEP's members in self-play: each episode one module, drawn from φ, in every seat."""
    m = PartnerMapping(3, {"a": 3.0, "b": 1.0}, learner=False, whole_team=True, salt=5)
    draws = [m.assignment(f"ep{k}") for k in range(4000)]
    assert all(len(set(d)) == 1 and len(d) == 3 for d in draws)
    assert draws[7] == m.assignment("ep7")
    share_a = sum(d[0] == "a" for d in draws) / len(draws)
    assert abs(share_a - 0.75) < 4 * np.sqrt(0.75 * 0.25 / len(draws))
    with pytest.raises(ValueError, match="no seat for the learner"):
        PartnerMapping(3, {"a": 1.0}, learner=True, whole_team=True)


def test_frozen_partner_acts_with_the_pushed_weights(oracle):
    before = MLPPolicy(
        CONFIG.env, CONFIG.export(oracle.weights([member_module(1)])[member_module(1)])
    )
    state = random_state(oracle, seed=1)
    oracle.set_partners({member_module(1): state})
    oracle.set_phi({member_module(1): 1.0})
    expected = MLPPolicy(CONFIG.env, CONFIG.export(state))

    def partner_actions(runner):
        """The partner's observations, action-distribution means and actions (in RLlib's
        [−1, 1] action space) in freshly sampled episodes."""
        obs, means, actions = [], [], []
        for ep in runner.sample(num_timesteps=200, force_reset=True):
            for aid in ep.agent_ids:
                if ep.module_for(aid) != member_module(1):
                    continue
                sa = ep.agent_episodes[aid]
                n = len(sa)
                obs.append(np.asarray(sa.get_observations(slice(0, n))))
                inputs = np.asarray(sa.get_extra_model_outputs("action_dist_inputs", slice(0, n)))
                means.append(beta_mean(inputs))
                actions.append(np.asarray(sa.get_actions(slice(0, n)))[:, 0])
        return np.concatenate(obs), np.concatenate(means), np.concatenate(actions)

    for obs, means, actions in oracle.algo.env_runner_group.foreach_env_runner(
        partner_actions, local_env_runner=False
    ):
        assert len(means) > 50
        # A frozen partner plays its mean, with no exploration noise, like the Grapher.
        np.testing.assert_array_equal(actions, means)
        # Float32 matmuls over a batch of 4 (the env runner) and of all rows (here) round
        # differently in the last bits; the weights before the push differ by far more.
        np.testing.assert_allclose(means, expected.mean(obs).numpy(), rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(rescale_action(actions), expected.act(obs), rtol=0, atol=1e-5)
        assert np.abs(means - before.mean(obs).numpy()).max() > 0.05


def test_the_learner_still_explores(oracle):
    def learner_noise(runner):
        out = []
        for ep in runner.sample(num_timesteps=200, force_reset=True):
            for aid in ep.agent_ids:
                if ep.module_for(aid) == LEARNER:
                    sa = ep.agent_episodes[aid]
                    n = len(sa)
                    inputs = np.asarray(
                        sa.get_extra_model_outputs("action_dist_inputs", slice(0, n))
                    )
                    out.append(np.asarray(sa.get_actions(slice(0, n)))[:, 0] - beta_mean(inputs))
        return np.concatenate(out)

    for noise in oracle.algo.env_runner_group.foreach_env_runner(
        learner_noise, local_env_runner=False
    ):
        assert len(noise) > 50 and np.std(noise) > 0.1  # sampled from its Beta


def test_exported_learner_equals_rllib_forward_inference_and_rescaling(local_learner, oracle):
    from gymnasium.spaces import Box
    from ray.rllib.utils.spaces.space_utils import unsquash_action

    state = oracle.weights([LEARNER])[LEARNER]
    policy = oracle.policy(state)
    assert policy.dist == "beta"

    def deterministic(module) -> np.ndarray:
        """RLlib's inference path: forward_inference, the module's own action distribution
        made deterministic, sampled: the normalised action [N, 1]."""
        with torch.no_grad():
            out = module.forward_inference({"obs": torch.from_numpy(OBS)})
            dist = module.get_inference_action_dist_cls().from_logits(out["action_dist_inputs"])
            return dist.to_deterministic().sample().numpy()

    # In this process (same torch threads): bit for bit.
    module = local_learner(oracle.algo).module[LEARNER]
    space = Box(0.0, 1.0, (1,), np.float32)
    expected = np.stack([unsquash_action(a, space) for a in deterministic(module)])[:, 0]
    np.testing.assert_array_equal(policy.act(OBS), expected)

    def rllib_actions(runner):
        from ray.rllib.utils.spaces.space_utils import unsquash_action

        runner.module[LEARNER].set_state(state)
        space = runner.env.envs[0].unwrapped.action_space["pursuer_0"]
        return np.stack([unsquash_action(a, space) for a in deterministic(runner.module[LEARNER])])[
            :, 0
        ]

    # In an env runner (one torch thread, another summation order): to the last float32 bit.
    for actions in oracle.algo.env_runner_group.foreach_env_runner(
        rllib_actions, local_env_runner=False
    ):
        np.testing.assert_allclose(policy.act(OBS), actions, rtol=0, atol=2e-7)
    assert 0.0 <= policy.act(OBS).min() and policy.act(OBS).max() <= 1.0


def test_rescaling_matches_rllib_including_clipping():
    from gymnasium.spaces import Box
    from ray.rllib.utils.spaces.space_utils import unsquash_action

    space = Box(0.0, 1.0, (1,), np.float32)
    raw = np.array([-3.0, -1.0, -0.25, 0.0, 0.6, 1.0, 2.5], dtype=np.float32)
    expected = np.array([unsquash_action(a[None], space)[0] for a in raw])
    np.testing.assert_array_equal(rescale_action(raw), expected)
    np.testing.assert_allclose(rescale_action(raw), [0, 0, 0.375, 0.5, 0.8, 1, 1])


def test_mean_policy_logp_is_the_log_of_the_mixture_density(local_learner, oracle):
    modules = {m: local_learner(oracle.algo).module[m] for m in oracle.members[:2]}
    obs = torch.from_numpy(OBS[:8])
    actions = torch.linspace(-0.9, 0.9, 8)[:, None]
    with torch.no_grad():
        got = mean_policy_logp(modules, list(modules), obs, actions)
    dens = []
    for module in modules.values():
        with torch.no_grad():
            inputs = module.forward_inference({"obs": obs})["action_dist_inputs"].double()
        a = torch.nn.functional.softplus(inputs[:, 0]) + 1  # concentrations, as BetaTurn's
        b = torch.nn.functional.softplus(inputs[:, 1]) + 1
        x = (actions[:, 0].double() + 1) / 2
        log_norm = torch.lgamma(a + b) - torch.lgamma(a) - torch.lgamma(b)
        # density of the turn a ∈ [−1, 1]: the Beta's density of x = (a + 1)/2, halved
        dens.append(torch.exp(log_norm + (a - 1) * x.log() + (b - 1) * (1 - x).log()) / 2)
    expected = torch.log((dens[0] + dens[1]) / 2).numpy()
    np.testing.assert_allclose(got.numpy(), expected, rtol=1e-5, atol=1e-6)


def test_spread_stays_bounded_while_training():
    """The Beta cannot widen past the uniform, whatever the entropy bonus (here 0.05, five
    times the paper's), and nothing it samples leaves the Box: the Gaussian it replaces
    reached a median std of 536 with 98 % of its samples clipped."""
    wide = RunConfig.from_dict(
        CONFIG.to_dict()
        | {"oracle": CONFIG.to_dict()["oracle"] | {"entropy_coef": 0.05, "lr": 0.01}}
    )
    oracle = wide.strategy.make_oracle(wide, seed=3)
    try:
        stats = oracle.train(1600, progress=False)

        def sampled(runner):
            return np.concatenate(
                [
                    np.asarray(
                        ep.agent_episodes[aid].get_actions(slice(0, len(ep.agent_episodes[aid])))
                    )[:, 0]
                    for ep in runner.sample(num_timesteps=200, force_reset=True)
                    for aid in ep.agent_ids
                    if ep.module_for(aid) == LEARNER and len(ep.agent_episodes[aid])
                ]
            )

        actions = np.concatenate(
            oracle.algo.env_runner_group.foreach_env_runner(sampled, local_env_runner=False)
        )
    finally:
        oracle.stop()
    assert stats.iterations >= 4
    for row in stats.iteration_log:
        assert 0 < row["std_median"] <= UNIFORM_STD + 1e-6
        assert 0 <= row["clipped"] < 0.05  # uniform: 1 % of samples within 0.01 of ±1
    assert len(actions) > 50 and np.all(np.abs(actions) < 1)


def seated_modules(oracle, timesteps: int) -> list[dict[str, str]]:
    """Each episode the remote env runners sample (`timesteps` each): agent → module."""

    def modules(runner):
        return [
            {aid: ep.module_for(aid) for aid in ep.agent_ids}
            for ep in runner.sample(num_timesteps=timesteps, force_reset=True)
        ]

    seen = oracle.algo.env_runner_group.foreach_env_runner(modules, local_env_runner=False)
    return [m for runner in seen for m in runner]


def test_self_play_seats_the_learner_in_every_slot():
    config = RunConfig.from_dict(CONFIG.to_dict() | {"method": "sp"})
    oracle = config.strategy.make_oracle(config)
    try:
        assert oracle.modules == [LEARNER] and oracle.members == []
        episodes = seated_modules(oracle, 300)
        stats = oracle.train(400, progress=False)
    finally:
        oracle.stop()
    assert len(episodes) >= 4
    for mapping in episodes:
        assert mapping == {f"pursuer_{i}": LEARNER for i in range(3)}
    assert stats.module_return.keys() <= {LEARNER}


def test_mep_in_self_play_seats_one_member_in_every_slot_of_an_episode():
    """MEP pre-training as MEP trains it: every episode is one member's self-play, and every
    member gets episodes."""
    from hola_ray.config.oracle import Seating
    from hola_ray.oracle import Oracle

    seating = Seating(mep_members=3, mep_alpha=0.05, mep_self_play=True)
    oracle = Oracle(CONFIG.env, CONFIG.oracle, seating, seed=0)
    try:
        episodes = seated_modules(oracle, 600)
        stats = oracle.train(400, progress=False)
    finally:
        oracle.stop()
    assert len(episodes) >= 8
    teams = [set(mapping.values()) for mapping in episodes]
    assert all(len(mapping) == 3 for mapping in episodes)
    assert all(len(team) == 1 for team in teams)
    assert set().union(*teams) == {member_module(k) for k in range(3)}
    assert stats.module_return.keys() <= {member_module(k) for k in range(3)}


def test_train_runs_updates_until_its_steps_and_logs_each(local_learner, oracle):
    """`train(n)` runs PPO iterations of `train_batch` steps until n are sampled, logs one
    row per iteration, and takes the update's time from the learner's own clock."""
    learner = local_learner(oracle.algo)
    # one iteration first: the env runners' step counts also hold what earlier tests of
    # the module sampled by hand, and RLlib reports them with the next iteration
    oracle.train(1, progress=False)
    clock = learner.update_s
    stats = oracle.train(1000, progress=False)  # batches of 400: three iterations
    steps = [row["env_steps"] for row in stats.iteration_log]
    assert stats.iterations == len(steps) == 3
    assert np.all(np.diff([0, *steps]) >= CONFIG.oracle.train_batch)  # whole batches
    assert steps[-2] < 1000 <= steps[-1] == stats.env_steps  # stops once n are sampled
    assert learner.update_s > clock and stats.learn_s == pytest.approx(learner.update_s - clock)
    # and no system-usage thread beside it (RLlib's default polls psutil every 0.7 s)
    assert not oracle.algo._monitor.is_alive()


def test_the_lean_gradient_step_equals_rllibs_and_frozen_partners_have_no_optimizer(
    local_learner, oracle
):
    """OracleLearner's minibatch step (one backward, RLlib's global-norm clip, the Adam step)
    moves the learner's weights exactly as RLlib's TorchLearner path does from the same
    weights and optimizer state; population members are never stepped."""
    import copy

    from ray.rllib.core.learner.torch.torch_learner import TorchLearner

    learner = local_learner(oracle.algo)
    assert all(not learner.get_optimizers_for_module(m) for m in oracle.members)
    module = learner.module[LEARNER]
    rng = np.random.default_rng(3)
    n = 128
    batch = {
        LEARNER: {
            "obs": torch.as_tensor(
                rng.uniform(-1, 1, (n, CONFIG.env.obs_dim)), dtype=torch.float32
            ),
            "actions": torch.as_tensor(rng.uniform(-0.9, 0.9, (n, 1)), dtype=torch.float32),
            "action_logp": torch.as_tensor(rng.normal(0, 0.3, n), dtype=torch.float32),
            "action_dist_inputs": torch.as_tensor(rng.normal(0, 1, (n, 2)), dtype=torch.float32),
            # large advantages and targets: the gradient's norm is far above the clip
            "advantages": torch.as_tensor(rng.normal(0, 50, n), dtype=torch.float32),
            "value_targets": torch.as_tensor(rng.normal(0, 50, n), dtype=torch.float32),
        }
    }
    ((_, optim),) = learner.get_optimizers_for_module(LEARNER)
    params0 = copy.deepcopy(module.state_dict())
    optim0 = copy.deepcopy(optim.state_dict())

    def step(update) -> tuple[dict[str, torch.Tensor], dict[str, torch.Tensor]]:
        """The weights after one step and the (clipped) gradients it applied."""
        module.load_state_dict(params0)
        optim.load_state_dict(copy.deepcopy(optim0))
        update(learner, batch)
        weights = {k: v.clone() for k, v in module.state_dict().items()}
        grads = {k: p.grad.clone() for k, p in module.named_parameters() if p.grad is not None}
        return weights, grads

    lean, lean_grads = step(type(learner)._uncompiled_update)
    # the lean step keeps its norm to log once per update (`after_gradient_based_update`)
    norm = learner._last_norms[(LEARNER, "gradients_default_optimizer_global_norm")]
    assert float(norm) > 10 * CONFIG.oracle.grad_clip  # the clip did act
    rllib, rllib_grads = step(TorchLearner._uncompiled_update)
    assert max(float((lean[k] - params0[k]).abs().max()) for k in lean) > 1e-5
    assert lean_grads.keys() == rllib_grads.keys() and lean_grads
    clipped = torch.sqrt(sum((g.double() ** 2).sum() for g in lean_grads.values()))
    assert float(clipped) == pytest.approx(CONFIG.oracle.grad_clip, rel=1e-5)
    for k in lean_grads:
        np.testing.assert_allclose(lean_grads[k], rllib_grads[k], rtol=1e-6, atol=1e-9, err_msg=k)
    for k in lean:
        np.testing.assert_allclose(lean[k].numpy(), rllib[k].numpy(), rtol=0, atol=1e-7, err_msg=k)


def test_the_train_batch_holds_the_learners_rows_only_with_gae_on_them(local_learner, oracle):
    """The frozen partners' rows leave the learner pipeline before GAE (no critic pass on
    them); the learner's rows get advantages and value targets as before."""
    from ray.rllib.core.learner.training_data import TrainingData

    from hola_ray.oracle.connectors import DropFrozenModules

    learner = local_learner(oracle.algo)
    pieces = [type(p).__name__ for p in learner._learner_connector.connectors]
    assert pieces.index(DropFrozenModules.__name__) < pieces.index("GeneralAdvantageEstimation")
    oracle.set_phi({m: 1.0 / len(oracle.members) for m in oracle.members})
    (episodes,) = oracle.algo.env_runner_group.foreach_env_runner(
        lambda runner: runner.sample(num_timesteps=400, force_reset=True),
        local_env_runner=False,
    )
    modules = {ep.module_for(aid) for ep in episodes for aid in ep.agent_ids}
    assert LEARNER in modules and modules & set(oracle.members)  # partners played too
    batch = learner._make_batch_if_necessary(TrainingData(episodes=episodes))
    assert set(batch.policy_batches) == {LEARNER}
    rows = batch.policy_batches[LEARNER]
    assert len(rows["advantages"]) == len(rows["value_targets"]) == len(rows["obs"]) > 0


@pytest.mark.parametrize("entropy_coef", [0.0, 0.05])
@pytest.mark.parametrize("masked", [False, True])
def test_the_lean_ppo_loss_equals_rllibs_with_its_gradients_and_logged_figures(
    local_learner, oracle, entropy_coef, masked
):
    """OracleLearner's PPO loss gives RLlib's loss and gradients, and logs the same figures
    (those of the update's last minibatch), with or without the entropy term and a loss
    mask."""
    from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner
    from ray.rllib.utils.schedules.scheduler import Scheduler

    learner = local_learner(oracle.algo)
    module = learner.module[LEARNER]
    config = learner.config.get_config_for_module(LEARNER)
    schedulers = learner.entropy_coeff_schedulers_per_module
    kept = schedulers[LEARNER]
    schedulers[LEARNER] = Scheduler(fixed_value_or_schedule=entropy_coef, framework="torch")
    batch = loss_batch(np.random.default_rng(5), 96, masked)

    def loss_of(compute) -> tuple[float, dict[str, torch.Tensor], dict[str, float]]:
        module.zero_grad(set_to_none=True)
        learner._last_stats = {}
        fwd_out = module.forward_train(batch)
        loss = compute(learner, module_id=LEARNER, config=config, batch=batch, fwd_out=fwd_out)
        loss.backward()
        for mid, stats in learner._last_stats.items():  # the lean loss logs after the update
            learner.metrics.log_dict(stats(), key=mid, window=1)
        learner._last_stats = {}
        keys = ["policy_loss", "vf_loss", "vf_loss_unclipped", "vf_explained_var", "entropy"]
        logged = {
            k: float(torch.as_tensor(learner.metrics.peek((LEARNER, k))).detach()) for k in keys
        }
        grads = {k: p.grad.clone() for k, p in module.named_parameters() if p.grad is not None}
        return float(loss.detach()), grads, logged

    try:
        lean = loss_of(type(learner).compute_loss_for_module)
        rllib = loss_of(PPOTorchLearner.compute_loss_for_module)
    finally:
        schedulers[LEARNER] = kept
    assert lean[0] == pytest.approx(rllib[0], rel=1e-6)
    assert lean[1].keys() == rllib[1].keys() and lean[1]
    for k in lean[1]:
        np.testing.assert_allclose(lean[1][k], rllib[1][k], rtol=1e-5, atol=1e-8, err_msg=k)
    assert lean[2] == pytest.approx(rllib[2], rel=1e-6)


@pytest.mark.parametrize(
    "path,entropy_coef,masked",
    [("eager", 0.0, False), ("eager", 0.05, True), ("compiled", 0.05, True)],
)
def test_the_fused_loss_gives_the_lean_losss_step_gradients_and_logged_figures(
    local_learner, oracle, path, entropy_coef, masked
):
    """The fused loss (hola_ray/oracle/fused.py) takes the same gradient step as RLlib's
    forward pass and the lean loss: uncompiled to float rounding, compiled within 1e-5, with
    the same logged figures; the module's own parameters are the ones stepped."""
    import copy

    from ray.rllib.utils.schedules.scheduler import Scheduler

    learner = local_learner(oracle.algo)
    module = learner.module[LEARNER]
    schedulers = learner.entropy_coeff_schedulers_per_module
    kept = schedulers[LEARNER]
    schedulers[LEARNER] = Scheduler(fixed_value_or_schedule=entropy_coef, framework="torch")
    batch = {LEARNER: loss_batch(np.random.default_rng(11), 128, masked)}
    ((_, optim),) = learner.get_optimizers_for_module(LEARNER)
    params0 = copy.deepcopy(module.state_dict())
    optim0 = copy.deepcopy(optim.state_dict())

    def step(loss_path: str):
        module.load_state_dict(params0)
        optim.load_state_dict(copy.deepcopy(optim0))
        learner.set_loss_path(loss_path)
        learner._last_stats = {}
        _, losses, _ = learner._uncompiled_update(batch)
        grads = {k: p.grad.clone() for k, p in module.named_parameters() if p.grad is not None}
        logged = {k: float(v) for k, v in learner._last_stats[LEARNER]().items()}
        weights = {k: v.clone() for k, v in module.state_dict().items()}
        return float(losses[LEARNER].detach()), grads, logged, weights

    try:
        reference = step("module")
        fused = step(path)
    finally:
        schedulers[LEARNER] = kept
        learner.set_loss_path("compiled" if CONFIG.oracle.compile else "eager")
        module.load_state_dict(params0)
        optim.load_state_dict(optim0)
    tolerance = 1e-6 if path == "eager" else 1e-5
    assert fused[0] == pytest.approx(reference[0], rel=tolerance)
    assert fused[1].keys() == reference[1].keys()
    assert len(fused[1]) == len(list(module.parameters()))
    for k in fused[1]:
        # rounding relative to the tensor's largest entry: the compiled tanh is within 4e-7
        # of torch's, and its sums over rows run in another order
        scale = float(reference[1][k].abs().max())
        np.testing.assert_allclose(
            fused[1][k], reference[1][k], rtol=0, atol=3 * tolerance * scale, err_msg=k
        )
    assert fused[2] == pytest.approx(reference[2], rel=tolerance, abs=1e-7)
    moved = max(float((fused[3][k] - params0[k]).abs().max()) for k in params0)
    assert moved > 1e-5  # the module's own weights took the step
    for k in fused[3]:
        np.testing.assert_allclose(fused[3][k], reference[3][k], rtol=0, atol=1e-6, err_msg=k)


def test_the_fused_loss_is_used_only_for_the_plain_beta_network():
    """`FusedLoss.of` takes tanh MLPs with linear heads and the Beta turn, nothing else."""
    from hola_ray.oracle.fused import _mlp_params

    linear, tanh = torch.nn.Linear(3, 4), torch.nn.Tanh()
    head = torch.nn.Linear(4, 2)
    encoder = torch.nn.Sequential(linear, tanh)
    assert _mlp_params(encoder, torch.nn.Sequential(head)) == [
        linear.weight,
        linear.bias,
        head.weight,
        head.bias,
    ]
    assert (
        _mlp_params(torch.nn.Sequential(linear, torch.nn.ReLU()), torch.nn.Sequential(head)) is None
    )
    assert _mlp_params(encoder) is None  # ends in an activation, not a layer


def test_a_reset_learner_trains_on_with_its_new_hyperparameters_and_a_fresh_optimizer(
    local_learner, oracle
):
    """PBT's explore: the lr and entropy coefficient set for an agent are the ones its
    training uses (RLlib's schedulers would otherwise put the config's back every update),
    and the previous agent's Adam moments are gone."""
    before = oracle.learner_hyperparameters()
    assert before == pytest.approx({"lr": CONFIG.oracle.lr, "entropy_coef": 0.01})
    learner = local_learner(oracle.algo)
    (_, optim), *_ = learner.get_optimizers_for_module(LEARNER)
    assert optim.state  # trained already: Adam has moments
    try:
        oracle.reset_learner(lr=1.234e-4, entropy_coef=0.0321)
        assert not optim.state
        oracle.train(400, progress=False)
        assert oracle.learner_hyperparameters() == pytest.approx(
            {"lr": 1.234e-4, "entropy_coef": 0.0321}
        )
        assert all(g["lr"] == pytest.approx(1.234e-4) for g in optim.param_groups)
    finally:
        oracle.reset_learner(before["lr"], before["entropy_coef"])


def test_an_overlapped_oracle_samples_during_the_update_and_never_trains_on_an_old_phi():
    """`oracle.overlap`: the next batch is asked for before each update but the last of a
    `train` call, so after `set_phi` every trained episode follows the new φ."""
    data = CONFIG.to_dict()
    data["oracle"]["overlap"] = True
    built = RunConfig.from_dict(data)
    oracle = built.strategy.make_oracle(built)
    group = oracle.algo.learner_group
    seen: list[tuple[int, set[str]]] = []  # per update: requests in flight, partner modules
    update = group.update

    def recording_update(*, episodes, **kwargs):
        partners = {ep.module_for(a) for ep in episodes for a in ep.agent_ids} - {LEARNER}
        seen.append((oracle.algo._in_flight, partners))
        return update(episodes=episodes, **kwargs)

    group.update = recording_update
    try:
        for target in (member_module(0), member_module(1)):
            oracle.set_phi({target: 1.0})
            seen.clear()
            stats = oracle.train(1000, progress=False)  # batches of 400: three iterations
            assert oracle.algo._in_flight == 0  # nothing left sampling with this φ
            assert stats.iterations == 3 and 1000 <= stats.env_steps < 1400
            assert [n for n, _ in seen] == [1, 1, 0]  # overlapped but for the last update
            assert all(partners == {target} for _, partners in seen), seen
    finally:
        oracle.stop()


def test_the_lean_pipeline_builds_rllibs_train_batch(local_learner, oracle):
    """The learner pipeline with `AddOneTsInArrays` in place of RLlib's
    AddOneTsToEpisodesAndTruncate builds the same train batch from the same episodes: every
    column, value and row order (GAE's advantages and value targets included)."""
    import copy

    from ray.rllib.connectors.learner.add_one_ts_to_episodes_and_truncate import (
        AddOneTsToEpisodesAndTruncate,
    )

    from hola_ray.oracle.connectors import AddOneTsInArrays

    learner = local_learner(oracle.algo)
    lean = learner._learner_connector
    assert any(isinstance(p, AddOneTsInArrays) for p in lean.connectors)
    rllib = copy.deepcopy(lean)
    rllib.insert_before(AddOneTsInArrays, AddOneTsToEpisodesAndTruncate())
    rllib.remove(AddOneTsInArrays)
    assert [type(p).__name__ for p in rllib.connectors][0] == "AddOneTsToEpisodesAndTruncate"
    oracle.set_phi({m: 1.0 / len(oracle.members) for m in oracle.members})
    (episodes,) = oracle.algo.env_runner_group.foreach_env_runner(
        lambda runner: runner.sample(num_timesteps=400, force_reset=True),
        local_env_runner=False,
    )
    assert any(ep.is_done for ep in episodes) and any(not ep.is_done for ep in episodes)

    def built(pipeline) -> dict:
        return pipeline(
            rl_module=learner.module,
            batch={},
            episodes=copy.deepcopy(episodes),
            shared_data={},
            metrics=learner.metrics,
        )

    ours, theirs = built(lean), built(rllib)
    assert ours.keys() == theirs.keys() == {LEARNER}
    assert ours[LEARNER].keys() == theirs[LEARNER].keys()
    for column, value in theirs[LEARNER].items():
        assert torch.equal(torch.as_tensor(ours[LEARNER][column]), torch.as_tensor(value)), column
    mask = torch.as_tensor(ours[LEARNER]["loss_mask"])
    assert 0 < int((~mask).sum()) < len(mask)  # one masked bootstrap row per chunk


def test_every_method_starts_its_learner_from_the_same_weights_on_a_seed(ray_session):
    """One start for every method (a comparison measures the methods): on a seed, the
    learner's initial weights are the same whether the Oracle seats it in every slot (sp),
    beside partners (hola; fcp, mep, hola_r and uniform seat it alike) or among PBT's
    agents; another seed differs."""
    starts = {}
    for method, seed in (("sp", 3), ("hola", 3), ("pbt", 3), ("hola", 4)):
        raw = CONFIG.to_dict() | {"method": method, "seed": seed}
        raw["oracle"] = raw["oracle"] | {"env_runners": 0}  # no sampling here: no runner actor
        config = RunConfig.from_dict(raw)
        oracle = config.strategy.make_oracle(config)
        try:
            starts[method, seed] = oracle.weights([LEARNER])[LEARNER]
        finally:
            oracle.stop()
    reference = starts["sp", 3]
    for key, state in starts.items():
        same = all(np.array_equal(reference[k], state[k]) for k in reference)
        assert same == (key[1] == 3), key


def test_an_oracle_sampling_in_the_driver_pins_its_threads_whatever_ran_before(ray_session):
    """`oracle.env_runners: 0` samples in the driver: its runner pins torch and numba to the
    runner's CPUs, as a remote runner does, whatever the process set before (a resumed run
    plays its lost monitors first, and a rollout sets torch's threads to 1 and back; left on
    two, that driver sampled at 150–214 env steps a second instead of thousands)."""
    import numba

    raw = CONFIG.to_dict()
    raw["oracle"] = raw["oracle"] | {"env_runners": 0}
    config = RunConfig.from_dict(raw)
    from hola_ray.env.core import BatchedPursuit

    env = BatchedPursuit(config.env, 4)  # the simulator's pool started, as a rollout does
    env.step(np.zeros((4, config.env.n_pursuers)), None)
    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        oracle = config.strategy.make_oracle(config)
        try:
            assert torch.get_num_threads() == 1
            assert numba.get_num_threads() == 1
        finally:
            oracle.stop()
    finally:
        torch.set_num_threads(threads)
