"""`BatchedEnvRunner`: RLlib's multi-agent env runner, sampling the batched core directly.

RLlib's `MultiAgentEnvRunner` steps each sub-environment through the PettingZoo wrapper,
runs its connector pipelines per step and grows every `MultiAgentEpisode` one
`add_env_step` at a time. This runner keeps its interface (weights, φ mapping, metrics,
episodes for the same learner pipeline) but samples all `num_envs_per_env_runner` episodes
with one `BatchedPursuit` step, one forward pass per module over every row that module
plays, and builds each episode chunk in one go from numpy buffers when `sample` returns.

The forward pass is the module's actor alone, in plain torch: the layers RLlib's module
holds (read in place, at the start of every `sample`, so pushed and synced weights count),
run as `MLPPolicy` runs an export (`hola_ray.policies.learned`), with the proximity
features computed once for all rows. RLlib's `_forward_exploration` also runs the critic's
encoder, which nothing reads while sampling (PPO's learner recomputes values), and calls
through a dozen `nn.Module`s per module and step; with the paper's ten partners that was
three quarters of the sampling time. Modules of other classes take RLlib's own forward.

What it reproduces of the reference path (tested against `MultiAgentEnvRunner`): the
episodes' observations, actions, rewards, terminations and truncations (one deliberate
difference: an episode cut at the horizon is truncated, its live agents not terminated, so
PPO bootstraps V(s_T) there; RLlib marks every agent of an episode whose agents are all
done terminated, the horizon's too), the agent → module
mapping (the runner's `policy_mapping_fn`, called once per agent at the start of every
episode), the module outputs kept for the learner (action distribution inputs and
log-probabilities), the unsquash of RLlib's [−1, 1] actions onto the Box, and the env
runner metrics the Oracle reads (env, agent and module steps; episode returns and lengths).
What it leaves out: per-step episode callbacks (`on_episode_step`), custom connectors (the
Oracle configures none), and lookback data in continued chunks (PPO does not read it).
"""

from __future__ import annotations

import time
from collections import defaultdict
from types import SimpleNamespace

import numpy as np
import torch
from ray.rllib.core.columns import Columns
from ray.rllib.env.multi_agent_env_runner import MultiAgentEnvRunner
from ray.rllib.env.multi_agent_episode import MultiAgentEpisode
from ray.rllib.env.single_agent_episode import SingleAgentEpisode
from ray.rllib.env.utils.infinite_lookback_buffer import InfiniteLookbackBuffer
from ray.rllib.utils.metrics import (
    NUM_AGENT_STEPS_SAMPLED,
    NUM_AGENT_STEPS_SAMPLED_LIFETIME,
    NUM_ENV_STEPS_SAMPLED,
    NUM_ENV_STEPS_SAMPLED_LIFETIME,
    NUM_EPISODES,
    NUM_EPISODES_LIFETIME,
    NUM_MODULE_STEPS_SAMPLED,
    NUM_MODULE_STEPS_SAMPLED_LIFETIME,
    WEIGHTS_SEQ_NO,
)

from hola_ray import third_party
from hola_ray.env.core import BatchedPursuit
from hola_ray.oracle.module import FrozenPartnerModule, PursuitPPOModule
from hola_ray.policies.learned import MLPPolicy, MLPStack, export_from_rllib
from hola_ray.process import pin_threads, quiet_ray_noise, seed_torch

SKIP = MultiAgentEpisode.SKIP_ENV_TS_TAG


class _Episode:
    """One sub-environment's episode while it runs: its id, who plays each slot, and where
    its current chunk began (env step within the episode, row of this sample's buffers)."""

    __slots__ = ("id_", "seed", "modules", "env_t_started", "agent_t_started", "row")

    def __init__(self, id_: str, seed: int, modules: list[str], n_p: int) -> None:
        self.id_ = id_
        self.seed = seed
        self.modules = modules
        self.env_t_started = 0
        self.agent_t_started = np.zeros(n_p, dtype=np.int64)
        self.row = 0


class BatchedEnvRunner(MultiAgentEnvRunner):
    """A `MultiAgentEnvRunner` whose sub-environments are one `BatchedPursuit`."""

    def __init__(self, config, **kwargs) -> None:
        quiet_ray_noise()  # before RLlib builds the modules (its deprecation warnings)
        third_party.apply_rllib()  # before it builds its connectors and seeds torch
        super().__init__(config=config, **kwargs)
        if self.worker_index > 0 or self.config.num_env_runners == 0:
            # a remote runner, or the driver's own where it samples (`oracle.env_runners: 0`):
            # a driver left on torch's two threads beside numba's pool sampled at 1,956 env
            # steps a second instead of 7,300, and at 150–214 where a rollout of its own
            # (monitors played before the Oracle was built, on resuming) had set torch's
            # threads to 1 and back before this runner was built
            pin_threads(self.config.num_cpus_per_env_runner)
        if self.env is None:  # the local runner beside remote ones holds no env
            return
        self._pursuit = self.config.env_config["scenario"]
        self.agents = [f"pursuer_{i}" for i in range(self._pursuit.n_pursuers)]
        self.core = BatchedPursuit(self._pursuit, self.num_envs)
        seed = self.config.seed
        entropy = [int(seed), int(self.worker_index)] if seed is not None else None
        self._rng = np.random.default_rng(np.random.SeedSequence(entropy))
        self._episodes: list[_Episode | None] = [None] * self.num_envs
        self._obs_space = self.env.unwrapped.envs[0].unwrapped.get_observation_space(self.agents[0])
        self._act_space = self.env.unwrapped.envs[0].unwrapped.get_action_space(self.agents[0])
        self._low = float(self._act_space.low[0])
        self._high = float(self._act_space.high[0])
        # who plays each seat of each sub-environment: an index into _module_ids
        self._seat = np.zeros((self.num_envs, len(self.agents)), dtype=np.int64)
        self._module_ids: list[str] = []
        # module id → (module, its actor over the module's own parameter tensors): loading
        # weights (`set_state`) copies into those tensors, so the actor follows every push
        self._actors: dict[str, tuple[object, MLPPolicy | None]] = {}
        self._partners: _PartnerStack | None = None
        self._horizon_terminates = bool(
            self.config.learner_config_dict.get("horizon_terminates", False)
        )

    # ---- episodes -----------------------------------------------------------------------
    def restart_episodes(self) -> None:
        """Every sub-environment starts a new episode at the next sample (its partners drawn
        from the φ and weights it holds then); nothing is sampled or counted now."""
        self._needs_initial_reset = True

    def reseed(self, salt: int) -> None:
        """Draw from here on as a runner started with salt `salt` would: the episodes' seeds
        and ids from (run seed, runner, salt), the actions from torch's generator seeded
        likewise, and every sub-environment starting a new episode at the next sample. What
        it samples then depends on the weights and φ it holds, not on what it sampled before,
        so a run resumed at a generation samples as the undisturbed run did."""
        if self.env is None:
            return
        seed = self.config.seed
        words = [int(seed), int(self.worker_index), int(salt)] if seed is not None else None
        self._rng = np.random.default_rng(np.random.SeedSequence(words))
        if words is not None:
            seed_torch(words)
        self._module_ids = []  # seats are numbered again in the order episodes meet them
        self._needs_initial_reset = True

    def _start(self, mask: np.ndarray) -> None:
        """Reset the sub-environments in mask with fresh seeds and start their episodes."""
        idx = np.flatnonzero(mask)
        if not idx.size:
            return
        seeds = self._rng.integers(0, 2**63 - 1, size=idx.size, dtype=np.int64)
        self.core.reset(seeds=seeds, mask=mask)
        mapping = self.config.policy_mapping_fn
        for b, seed in zip(idx, seeds, strict=True):
            eid = self._rng.bytes(16).hex()
            stub = SimpleNamespace(id_=eid)
            modules = [mapping(agent, stub) for agent in self.agents]
            self._episodes[b] = _Episode(eid, int(seed), modules, len(self.agents))
            for i, mid in enumerate(modules):
                if mid not in self._module_ids:
                    self._module_ids.append(mid)
                self._seat[b, i] = self._module_ids.index(mid)

    # ---- sampling -----------------------------------------------------------------------
    def _sample(
        self,
        *,
        num_timesteps: int | None = None,
        num_episodes: int | None = None,
        explore: bool,
        random_actions: bool = False,
        force_reset: bool = False,
    ) -> list[MultiAgentEpisode]:
        if random_actions:
            raise NotImplementedError("BatchedEnvRunner samples from its modules only")
        B = self.num_envs
        for mid in self.module.keys():
            self.module[mid].eval()  # they only act here; PPO trains the learner's copies
        for mid in self.module.keys():
            module = self.module[mid]
            if self._actors.get(mid, (None,))[0] is not module:
                self._actors[mid] = (module, self._actor(module))
        self._partners = _PartnerStack.of(
            {
                mid: (module, actor)
                for mid, (module, actor) in self._actors.items()
                if isinstance(module, FrozenPartnerModule) and actor is not None
            }
        )
        if force_reset or num_episodes is not None or self._needs_initial_reset:
            self._ongoing_episodes_for_metrics.clear()
            self._start(np.ones(B, dtype=bool))
            self._needs_initial_reset = False
        if num_episodes is not None:
            self._needs_initial_reset = True
        steps = -(-num_timesteps // B) if num_timesteps is not None else None
        buf = _Buffers(self.core, steps or self._pursuit.horizon + 1)
        done_chunks: list[MultiAgentEpisode] = []
        ended_episodes = 0
        s = 0
        for e in self._episodes:
            e.row = 0
        while (s < steps) if steps is not None else (ended_episodes < num_episodes):
            if s == buf.capacity:
                buf.grow()
            live = self.core.pursuer_active & ~self.core.done[:, None]
            buf.obs[s] = self.core.obs
            buf.live[s] = live
            self._act(buf, s, live, explore)
            low, high = self._low, self._high
            to_env = low + (buf.actions[s, :, :, 0] + 1.0) * (0.5 * (high - low))
            result = self.core.step(np.clip(to_env, low, high))
            buf.next_obs[s] = result.obs
            buf.rewards[s] = result.reward
            # an agent's own episode ends when it crashes or its pursuer leaves (lands)
            buf.disabled[s] = result.disabled | (live & ~self.core.pursuer_present)
            buf.truncated[s] = result.truncated
            ended = result.terminated | result.truncated
            for b in np.flatnonzero(ended):
                done_chunks.append(self._chunk(buf, b, s + 1, done=True))
                self._log_done(done_chunks[-1])
                ended_episodes += 1
            if ended.any():
                self._start(ended)
                for b in np.flatnonzero(ended):
                    self._episodes[b].row = s + 1
            s += 1
        self._log_steps(buf, s)
        chunks = list(done_chunks)
        if num_episodes is not None:
            return chunks
        for b, e in enumerate(self._episodes):
            if e.row >= s:  # just started: nothing in it yet
                continue
            chunk = self._chunk(buf, b, s, done=False)
            self._ongoing_episodes_for_metrics[e.id_].append(chunk)
            chunks.append(chunk)
            # the next chunk continues where this one ends
            rows = slice(e.row, s)
            acted = buf.live[rows, b].sum(axis=0)
            e.agent_t_started += acted
            e.env_t_started += s - e.row
        return chunks

    def _actor(self, module) -> MLPPolicy | None:
        """The module's actor as a plain-torch `MLPPolicy` over its own parameter tensors
        (no copy), or None for a module this runner does not know the layout of."""
        if not isinstance(module, PursuitPPOModule):
            return None
        config = module.model_config
        state = module.state_dict()  # detached views of the parameters
        export = export_from_rllib(  # shares the module's parameter storage
            state,
            activation=config.get("fcnet_activation", "tanh"),
            dist=config.get("action_dist", "beta"),
            features=config.get("proximity"),
        )
        return MLPPolicy(self._pursuit, export)

    def _act(self, buf: _Buffers, s: int, live: np.ndarray, explore: bool) -> None:
        """Actions, log-probabilities and distribution inputs for every live agent at row s:
        the frozen partners' rows in one batched forward pass, each other module's rows in
        one of its own."""
        seat = np.where(live, self._seat, -1).ravel()
        obs = buf.obs[s].reshape(-1, buf.obs.shape[-1])
        actions = buf.actions[s].reshape(-1, 1)
        logp = buf.logp[s].reshape(-1)
        inputs = buf.dist_inputs[s].reshape(-1, buf.dist_inputs.shape[-1])
        stack = self._partners if explore else None
        slot_of = stack.slots(self._module_ids) if stack is not None else None
        x = None  # the observations with the actors' proximity features, for all rows
        with torch.no_grad():
            for m in np.unique(seat[seat >= 0]):
                rows = np.flatnonzero(seat == m)
                mid = self._module_ids[m]
                buf.module_steps[mid] += len(rows)
                if slot_of is not None and slot_of[m] >= 0:
                    continue  # a frozen partner: below, with the others
                actor = self._actors[mid][1]
                if actor is None:
                    din, act, lp = self._rllib_forward(self.module[mid], obs[rows], explore)
                else:
                    if x is None:
                        x = actor.with_features(obs)
                    din = actor.forward_features(x[rows])
                    dist = self._dist(self.module[mid], explore).from_logits(din)
                    if not explore:
                        dist = dist.to_deterministic()
                    act = dist.sample()
                    lp = dist.logp(act)
                actions[rows] = act.numpy().reshape(-1, 1)
                logp[rows] = 0.0 if lp is None else lp.numpy()
                inputs[rows] = din.numpy()
            if slot_of is None:
                return
            slot = np.where(seat >= 0, slot_of[seat], -1)
            rows = np.flatnonzero(slot >= 0)
            if not rows.size:
                return
            if x is None:
                x = stack.with_features(obs)
            din = stack.logits(x[rows], slot[rows])
            # as FrozenPartnerModule._forward_exploration: the mean, and no density
            act = stack.dist_cls.from_logits(din).to_deterministic().sample()
            actions[rows] = act.numpy().reshape(-1, 1)
            logp[rows] = 0.0
            inputs[rows] = din.numpy()

    @staticmethod
    def _dist(module, explore: bool):
        if explore:
            return module.get_exploration_action_dist_cls()
        return module.get_inference_action_dist_cls()

    def _rllib_forward(self, module, obs: np.ndarray, explore: bool):
        """RLlib's own forward pass (`_forward_exploration` / `_forward_inference`, without
        their train → eval → train switch: the modules are in eval mode): distribution
        inputs, actions, log-probabilities (None: none)."""
        batch = {Columns.OBS: torch.from_numpy(obs)}
        out = module._forward_exploration(batch) if explore else module._forward_inference(batch)
        din = out[Columns.ACTION_DIST_INPUTS]
        if Columns.ACTIONS in out:
            return din, out[Columns.ACTIONS], out.get(Columns.ACTION_LOGP)
        dist = self._dist(module, explore).from_logits(din)
        if not explore:
            dist = dist.to_deterministic()
        act = dist.sample()
        return din, act, dist.logp(act)

    # ---- episode chunks -----------------------------------------------------------------
    def _chunk(self, buf: _Buffers, b: int, stop: int, done: bool) -> MultiAgentEpisode:
        """The chunk of sub-environment b from its episode's `row` to row `stop`."""
        e = self._episodes[b]
        rows = slice(e.row, stop)
        n = stop - e.row
        live = buf.live[rows, b]  # [n, n_p]
        episode = MultiAgentEpisode(
            id_=e.id_,
            observation_space={a: self._obs_space for a in self.agents},
            action_space={a: self._act_space for a in self.agents},
            agent_module_ids={
                a: e.modules[i] for i, a in enumerate(self.agents) if live[:, i].any()
            },
            agent_to_module_mapping_fn=self.config.policy_mapping_fn,
            len_lookback_buffer=0,
        )
        episode.env_t_started = e.env_t_started
        episode.env_t = e.env_t_started + n
        truncated = bool(done and buf.truncated[stop - 1, b])
        horizon_ends = truncated and self._horizon_terminates  # the ablation's old marking
        # The horizon truncates: the agents alive at it are truncated, not terminated, so
        # the learner bootstraps V(s_T) there. (RLlib's own runner marks every agent of an
        # episode whose agents are all done terminated, the horizon's too.)
        for i, agent in enumerate(self.agents):
            acted = np.flatnonzero(live[:, i])
            if not acted.size:
                continue
            # the rows it acted: from its chunk's start or from when it joined, one run
            first, k = int(acted[0]), int(acted.size)
            rows_i = slice(e.row + first, e.row + first + k)
            t0 = int(e.agent_t_started[i])
            disabled = bool(buf.disabled[e.row + first + k - 1, b, i])
            obs = np.concatenate([buf.obs[e.row + first, b, i][None], buf.next_obs[rows_i, b, i]])
            sa = SingleAgentEpisode(
                id_=f"{e.id_}/{agent}",
                agent_id=agent,
                module_id=e.modules[i],
                multi_agent_episode_id=e.id_,
                observations=obs.copy(),
                observation_space=self._obs_space,
                infos=[{} for _ in range(k + 1)],
                actions=buf.actions[rows_i, b, i].copy(),
                action_space=self._act_space,
                rewards=buf.rewards[rows_i, b, i].copy(),
                extra_model_outputs={
                    Columns.ACTION_DIST_INPUTS: buf.dist_inputs[rows_i, b, i].copy(),
                    Columns.ACTION_LOGP: buf.logp[rows_i, b, i].copy(),
                    WEIGHTS_SEQ_NO: np.full(k, self._weights_seq_no, dtype=np.int64),
                },
                terminated=disabled or (done and (horizon_ends or not truncated)),
                truncated=truncated and first + k == n and (horizon_ends or not disabled),
                t_started=t0,
                len_lookback_buffer=0,
            )
            episode.agent_episodes[agent] = sa
            episode.agent_t_started[agent] = t0
            mapping = [SKIP] * first + list(range(t0, t0 + k + 1)) + [SKIP] * (n - first - k)
            episode.env_t_to_agent_t[agent] = InfiniteLookbackBuffer(data=mapping, lookback=0)
        episode.is_terminated = done and (horizon_ends or not truncated)
        episode.is_truncated = truncated
        episode.custom_data["seed"] = e.seed  # replays as PursuitEnv.reset(seed=…)
        now = time.perf_counter()
        episode._start_time = episode._last_step_time = now
        return episode

    # ---- metrics ------------------------------------------------------------------------
    def _log_steps(self, buf: _Buffers, steps: int) -> None:
        """Env, agent and module step counts of this sample, logged once."""
        env_steps = steps * self.num_envs  # an episode that ends is reset at once
        self.metrics.log_value(NUM_ENV_STEPS_SAMPLED, env_steps, reduce="sum")
        self.metrics.log_value(
            NUM_ENV_STEPS_SAMPLED_LIFETIME, env_steps, reduce="lifetime_sum", with_throughput=True
        )
        self._log_env_steps(metric=self._metrics_num_env_steps_sampled, num_steps=env_steps)
        per_agent = buf.live[:steps].sum(axis=(0, 1))
        for i, agent in enumerate(self.agents):
            self.metrics.log_value(
                (NUM_AGENT_STEPS_SAMPLED, agent), int(per_agent[i]), reduce="sum"
            )
            self.metrics.log_value(
                (NUM_AGENT_STEPS_SAMPLED_LIFETIME, agent), int(per_agent[i]), reduce="lifetime_sum"
            )
        for mid, count in buf.module_steps.items():
            self.metrics.log_value((NUM_MODULE_STEPS_SAMPLED, mid), count, reduce="sum")
            self.metrics.log_value(
                (NUM_MODULE_STEPS_SAMPLED_LIFETIME, mid), count, reduce="lifetime_sum"
            )

    def _log_done(self, episode: MultiAgentEpisode) -> None:
        self.metrics.log_value(NUM_EPISODES, 1, reduce="sum")
        self.metrics.log_value(NUM_EPISODES_LIFETIME, 1, reduce="lifetime_sum")
        self._done_episodes_for_metrics.append(episode)


class _PartnerStack:
    """The frozen partners' actors as one batched forward pass (`MLPStack`, its layers
    copied at the start of each `sample`, so pushed weights count)."""

    def __init__(self, ids: list[str], modules: list, actors: list[MLPPolicy]) -> None:
        self.ids = ids
        self.dist_cls = modules[0].get_inference_action_dist_cls()
        self.stack = MLPStack(actors)
        self.with_features = self.stack.with_features
        self.logits = self.stack.logits
        self._slots: tuple[int, np.ndarray] = (-1, np.zeros(0, np.int64))

    @classmethod
    def of(cls, partners: dict[str, tuple[object, MLPPolicy]]) -> _PartnerStack | None:
        """The stack of these partners, or None when there are none or their actors differ
        in layout (each then takes its own forward pass)."""
        if not partners:
            return None
        modules = [m for m, _ in partners.values()]
        actors = [a for _, a in partners.values()]
        same = MLPStack.compatible(actors) and all(type(m) is type(modules[0]) for m in modules)
        return cls(list(partners), modules, actors) if same else None

    def slots(self, module_ids: list[str]) -> np.ndarray:
        """For each index into the runner's module ids: that partner's slot here, or −1."""
        if self._slots[0] != len(module_ids):
            slot = {mid: k for k, mid in enumerate(self.ids)}
            self._slots = (
                len(module_ids),
                np.array([slot.get(mid, -1) for mid in module_ids], np.int64),
            )
        return self._slots[1]


class _Buffers:
    """One `sample` call's data, row s = the s-th vector step: what each agent saw and did."""

    def __init__(self, core: BatchedPursuit, capacity: int) -> None:
        B, n_p, dim = core.obs.shape
        self.capacity = capacity
        self.obs = np.zeros((capacity, B, n_p, dim), np.float32)
        self.next_obs = np.zeros_like(self.obs)
        self.live = np.zeros((capacity, B, n_p), bool)
        self.actions = np.zeros((capacity, B, n_p, 1), np.float32)
        self.logp = np.zeros((capacity, B, n_p), np.float32)
        self.dist_inputs = np.zeros((capacity, B, n_p, 2), np.float32)
        self.rewards = np.zeros((capacity, B, n_p), np.float64)
        self.disabled = np.zeros((capacity, B, n_p), bool)
        self.truncated = np.zeros((capacity, B), bool)
        self.module_steps: dict[str, int] = defaultdict(int)

    def grow(self) -> None:
        for name in (
            "obs",
            "next_obs",
            "live",
            "actions",
            "logp",
            "dist_inputs",
            "rewards",
            "disabled",
            "truncated",
        ):
            a = getattr(self, name)
            setattr(self, name, np.concatenate([a, np.zeros_like(a)]))
        self.capacity *= 2
