"""The Oracle: RLlib multi-agent PPO (new API stack) over the pursuit arena (docs/contract.md §5).

One algorithm holds a trained module for the learner and a frozen module per population
slot. A stateful `PartnerMapping` puts the learner in a random pursuer slot and draws the
other slots from φ; in self-play (`Seating.partners` 0) there are no partners and every
slot is the learner. The Oracle is the one owner of what its env runners hold: `seat`
loads the partners whose slots changed and φ, pushed straight into every env runner (and
re-pushed, by the callback, into any env runner RLlib recreates), because weights set on a
frozen module otherwise reach the env runners only an iteration late. The same class, in
MEP mode, trains the initial population jointly with the population-entropy bonus.
"""

from __future__ import annotations

import math
import time
import weakref
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
from ray.rllib.algorithms.algorithm import Algorithm
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.callbacks.callbacks import RLlibCallback
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec
from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
from ray.rllib.utils.metrics import ENV_RUNNER_RESULTS, NUM_ENV_STEPS_SAMPLED_LIFETIME
from ray.tune.registry import register_env

from hola_ray import interrupt, third_party
from hola_ray.config.oracle import OracleConfig, Seating
from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.horizon import horizon_is_truncation
from hola_ray.env.pettingzoo_env import PursuitEnv
from hola_ray.evaluation.probe import reference_observations
from hola_ray.oracle.batched_runner import BatchedEnvRunner
from hola_ray.oracle.learner import OracleLearner
from hola_ray.oracle.mapping import LEARNER, PartnerMapping, member_module
from hola_ray.oracle.module import FrozenPartnerModule, PursuitCatalog, PursuitPPOModule
from hola_ray.oracle.overlap import OverlappedPPO
from hola_ray.oracle.stats import TrainStats
from hola_ray.policies.learned import MLPPolicy, export_trained
from hola_ray.progress import progress as progress_bar

ENV_NAME = "hola_ray_pursuit"
ModuleState = Mapping[str, Any]
"""An RLlib module's state: parameter name → numpy array."""


def _make_env(env_config: Mapping[str, Any]) -> ParallelPettingZooEnv:
    return ParallelPettingZooEnv(PursuitEnv(env_config["scenario"]))


def learner_seats_per_step(env: PursuitConfig, self_play: bool) -> float:
    """The seats the trained learner plays in an env step: its fixed seats where the team
    changes (one where it is kept whole); in self-play every pursuer in play, for a team
    that changes the mean of its starting sizes (its joins and leaves about even)."""
    if self_play:
        low, high = env.team.start_range(env.n_pursuers)
        return (low + high) / 2
    return len(env.team.learner_seats or (0,))


class _RepushOnRecreate(RLlibCallback):
    """An env runner that RLlib recreated lost φ and the partner weights: push them again.
    And on RLlib's own (PettingZoo) path, an episode cut at the horizon is truncated, not
    terminated (`hola_ray.env.horizon`; the batched runner builds its episodes so)."""

    def on_env_runners_recreated(self, *, algorithm, env_runner_group, env_runner_indices, **kw):
        pushed = _PUSHED.get(id(algorithm))
        if pushed is not None:
            pushed.push(env_runner_group, remote_ids=list(env_runner_indices), local=False)

    def on_episode_end(self, *, episode, env_runner=None, **kwargs) -> None:
        config = getattr(env_runner, "config", None)
        if not (config and config.learner_config_dict.get("horizon_terminates", False)):
            horizon_is_truncation(episode)


@dataclass
class _Pushed:
    """What the Oracle last pushed into the env runners (φ, salt, partner weights)."""

    phi: dict[str, float]
    salt: int
    weights: dict[str, ModuleState]

    def push(self, group, remote_ids: list[int] | None = None, local: bool = True) -> None:
        phi, salt, weights = self.phi, self.salt, self.weights

        def apply(runner) -> None:
            runner.config.policy_mapping_fn.set_phi(phi, salt)
            for mid, state in weights.items():
                runner.module[mid].set_state(state)
            # Episodes under way keep the partners they started with: start new ones so the
            # push takes effect now (no re-seeding)
            if hasattr(runner, "restart_episodes"):
                runner.restart_episodes()  # at its next sample
            elif getattr(runner, "env", None) is not None:
                runner.sample(num_timesteps=1, force_reset=True)  # one discarded vector step

        group.foreach_env_runner(apply, local_env_runner=local, remote_worker_ids=remote_ids)


_PUSHED: weakref.WeakValueDictionary[int, _Pushed] = weakref.WeakValueDictionary()
"""id(algorithm) → what its Oracle last pushed (held by the Oracle; gone with it)"""


class Oracle:
    """Multi-agent PPO over the learner and frozen population partners (or, with
    `mep_members`, the MEP pre-training of that many population members; or, for a
    self-play method, the learner alone in every slot)."""

    def __init__(self, env: PursuitConfig, config: OracleConfig, seating: Seating, seed: int):
        third_party.apply_rllib()  # before RLlib builds its connectors and seeds torch
        self.env, self.config, self.seating, self.seed = env, config, seating, seed
        self.mep = seating.mep
        n_p = env.n_pursuers
        if seating.self_play:
            self.members: list[str] = []
            self.modules = [LEARNER]
            # φ = the learner with certainty, and no separate learner seat: every slot
            self.mapping = PartnerMapping(n_p, {LEARNER: 1.0}, learner=False)
        else:
            slots = range(seating.mep_members if self.mep else seating.partners)
            self.members = [member_module(s) for s in slots]
            self.modules = self.members if self.mep else [LEARNER, *self.members]
            self.mapping = PartnerMapping(
                n_p,
                {m: 1.0 for m in self.members},
                learner=not self.mep,
                whole_team=seating.mep_self_play,
                # a team that changes keeps its fixed seats in play throughout: the learner's
                learner_seats=env.team.learner_seats,
            )
        self.trained = self.members if self.mep else [LEARNER]
        self.counts_samples = config.budget == "learner_samples" and not self.mep
        """`train(n)` counts the learner's own transitions (not env steps); MEP pre-training
        (every member trained) counts env steps"""
        self.seats = learner_seats_per_step(env, seating.self_play)
        """seats the trained learner plays per env step: a learner_samples batch of
        `train_batch` transitions spans train_batch / seats env steps"""
        self._pushed = _Pushed(phi=self.mapping.phi, salt=0, weights={})
        self._env_steps_before = 0  # a resumed run's env steps before this Oracle
        # registered per Oracle, not at import: Tune's registry lives in the Ray session,
        # and a process may start more than one (the test modules do)
        register_env(ENV_NAME, _make_env)
        self.loaded: dict[int, int] = {}
        """partner slot → the population node whose weights its module holds"""

        # The driver's own part of the build, done while RLlib waits for the env runners'
        # processes to start (4.8 s of the default run's 7.9): the spread probe's reference
        # observations, which draw from no random generator the build seeds. (torch's
        # optimizers no longer import torch._dynamo: `third_party.lazy_dynamo`.)
        with ThreadPoolExecutor(1) as aside:
            reference = aside.submit(reference_observations, env)
            self.algo: Algorithm = self._algorithm_config(self.trained, seed).build_algo()
            _PUSHED[id(self.algo)] = self._pushed  # read by _RepushOnRecreate
            # Every 4th of the reference observations (≈ 1,500): the per-iteration spread
            # then costs 4 ms instead of 24 (a tenth of a paper-PPO iteration otherwise)
            self._reference_obs = reference.result()[::4]

    def _algorithm_config(self, trainable: Sequence[str], seed: int) -> PPOConfig:
        o, env = self.config, self.env
        model = {
            "fcnet_hiddens": list(o.hidden),
            "fcnet_activation": "tanh",
            "vf_share_layers": False,
            "action_dist": o.action_dist,
            "proximity": o.model_features(env),
        }
        # Trained modules explore; frozen partners play their mean (oracle/module.py).
        frozen = set(self.modules) - set(trainable)
        specs = {
            m: RLModuleSpec(
                module_class=FrozenPartnerModule if m in frozen else PursuitPPOModule,
                catalog_class=PursuitCatalog,
                model_config=model,
            )
            for m in self.modules
        }
        # read by the env runners (horizon) and the learner (update)
        extra = {
            "horizon_terminates": o.horizon_terminates,
            "update": o.update,
            "overlap": o.overlap,
            "compile": o.compile,
        }
        if self.mep:
            extra |= {"mep_alpha": self.seating.mep_alpha, "mep_modules": self.members}
        return (
            PPOConfig(algo_class=OverlappedPPO)
            .environment(
                ENV_NAME,
                env_config={"scenario": env},
                # RLlib's pre-check takes a reset's agents for all the env will ever have; a
                # team that starts short has more (they join later): checked by the tests
                disable_env_checking=env.team.open,
            )
            .env_runners(
                env_runner_cls=BatchedEnvRunner if o.sampler == "batched" else None,
                num_env_runners=o.env_runners,
                num_envs_per_env_runner=o.envs_per_runner,
                rollout_fragment_length="auto",
                num_cpus_per_env_runner=1,
            )
            .multi_agent(
                # a list, not a set: RLlib builds the modules in this order, and a set of
                # strings iterates in an order that changes with PYTHONHASHSEED (so did
                # every initial weight, from one process to the next)
                policies=list(self.modules),
                policy_mapping_fn=self.mapping,
                policies_to_train=list(trainable),
            )
            .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs=specs))
            .training(
                train_batch_size_per_learner=(
                    math.ceil(o.train_batch / self.seats) if self.counts_samples else o.train_batch
                ),
                minibatch_size=o.minibatch,
                num_epochs=o.epochs,
                lr=o.lr_schedule,
                gamma=o.gamma,
                lambda_=o.gae_lambda,
                vf_loss_coeff=o.vf_coef,
                entropy_coeff=o.entropy_coef,
                clip_param=o.clip,
                use_kl_loss=o.kl_coef > 0,
                kl_coeff=o.kl_coef,
                vf_clip_param=o.vf_clip,
                grad_clip=o.grad_clip or None,
                grad_clip_by="global_norm",
            )
            .learners(
                num_gpus_per_learner=o.gpus_per_learner,
                learner_class=OracleLearner,
                learner_config_dict=extra,
            )
            .callbacks(_RepushOnRecreate)
            .fault_tolerance(restart_failed_env_runners=True)
            # no system-usage thread: it polls psutil, which nothing here reads, and each
            # stop waits for its sleep to end
            .debugging(seed=seed, log_level="ERROR", log_sys_usage=False)
            .reporting(metrics_num_episodes_for_smoothing=20)
        )

    # ---- partners -----------------------------------------------------------------------
    def set_partners(self, weights: Mapping[str, ModuleState]) -> None:
        """Load frozen partner modules (module id → RLlib module state) everywhere: the
        learner group and every env runner, effective for the very next episode."""
        unknown = set(weights) - set(self.members)
        if unknown:
            raise ValueError(f"no partner modules {sorted(unknown)}; have {self.members}")
        if not weights:
            return
        self.algo.learner_group.set_weights(dict(weights))
        self._pushed.weights.update(weights)
        _Pushed({**self._pushed.phi}, self._pushed.salt, dict(weights)).push(
            self.algo.env_runner_group
        )

    def set_phi(self, phi: Mapping[str, float], salt: int = 0) -> None:
        """Sample partner modules from φ (module id → probability) from the next episode on;
        `salt` makes each generation's slot draws differ for the same episode ids."""
        unknown = set(phi) - set(self.members)
        if unknown:
            raise ValueError(f"φ names modules {sorted(unknown)} that are not partners")
        self.mapping.set_phi(phi, salt)
        self._pushed.phi, self._pushed.salt = self.mapping.phi, salt
        _Pushed(self._pushed.phi, salt, {}).push(self.algo.env_runner_group)

    def seat(
        self,
        plan: Mapping[int, tuple[int, float]],
        states_of: Callable[[list[int]], Mapping[int, ModuleState]],
        salt: int = 0,
    ) -> None:
        """Seat a generation's partners: `plan` is slot → (population node, φ) as the
        coordinator gives it; the modules whose slot holds another node than before load
        that node's state (`states_of(nodes)`), then φ is drawn over the slots with φ > 0,
        `salt` making each generation's draws differ for the same episode ids."""
        changed = {slot: node for slot, (node, _) in plan.items() if self.loaded.get(slot) != node}
        if changed:
            states = states_of(list(changed.values()))
            self.set_partners({member_module(s): states[n] for s, n in changed.items()})
            self.loaded.update(changed)
        self.set_phi({member_module(s): p for s, (_, p) in plan.items() if p > 0}, salt=salt)

    # ---- training -----------------------------------------------------------------------
    def train(self, budget: int, desc: str = "oracle", progress: bool = True) -> TrainStats:
        """Run PPO updates until `budget` is spent: environment steps sampled, or with
        `oracle.budget: learner_samples` the learner's own transitions consumed."""
        done = before = iterations = 0
        env_steps = 0
        wall = 0.0
        learn_before, samples_before, grads_before = self._learner_counts()
        result: dict[str, Any] = {}
        log: list[dict[str, float]] = []
        unit = "sample" if self.counts_samples else "step"
        with progress_bar(budget, desc, unit, enabled=progress) as bar:
            while done < budget:
                interrupt.check()
                # overlapped sampling (oracle.overlap): ask for the next batch only if
                # another iteration follows; the first one's size is the config's batch
                step = done - before if iterations else self.config.train_batch
                self.algo.prefetch = done + step < budget
                start = time.perf_counter()
                result = self.algo.train()
                wall += time.perf_counter() - start
                runners = result.get("env_runners", {})
                steps = runners.get("num_env_steps_sampled", 0)
                # RLlib reported NaN here once in a 3M-step run (no runner failed): count
                # such an iteration as no steps rather than crash.
                steps = int(steps) if np.isfinite(steps) else 0
                env_steps += steps
                samples = self._learner_counts()[1] - samples_before
                before, done = done, (samples if self.counts_samples else env_steps)
                iterations += 1
                ret = runners.get("episode_return_mean", float("nan"))
                log.append(
                    {
                        "env_steps": env_steps,
                        "learner_samples": samples,
                        "return": float(ret),
                        **self._health(result),
                    }
                )
                bar.update(min(done - before, budget - bar.n))
                bar.set_postfix(
                    # RLlib's mean is NaN when no episode ended in the iteration
                    ret=f"{ret:.1f}" if np.isfinite(ret) else "– (no episode ended)",
                    std=f"{log[-1]['std_median']:.2f}",
                    sps=f"{env_steps / wall:.0f}",
                )
        # a batch asked for on a wrong guess is dropped: sampled with what `train` was given,
        # it must not reach the update after φ or the partners change
        self.algo.drain()
        learn, samples, grads = (
            now - then
            for now, then in zip(
                self._learner_counts(), (learn_before, samples_before, grads_before), strict=True
            )
        )
        sample = max(wall - learn, 0.0)
        runners = result.get("env_runners", {})
        module_return = {
            k: float(v) for k, v in runners.get("module_episode_returns_mean", {}).items()
        }
        return TrainStats(
            env_steps=env_steps,
            iterations=iterations,
            wall_s=wall,
            sample_s=sample,
            learn_s=learn,
            episode_return=float(runners.get("episode_return_mean", np.nan)),
            module_return=module_return,
            learner_samples=int(samples),
            gradient_steps=int(grads),
            iteration_log=tuple(log),
        )

    def _health(self, result: Mapping[str, Any]) -> dict[str, float]:
        """What says the trained policies are sound after an iteration: the widest trained
        module's spread on the reference observations, and RLlib's mean entropy, value loss,
        explained variance (and KL penalty, when on) over the trained modules."""
        weights = self.weights(self.trained)
        spreads = [self.policy(weights[m]).spread(self._reference_obs) for m in self.trained]
        learners = result.get("learners", {})
        row = {
            "std_median": max(s["std_median"] for s in spreads),
            "clipped": max(s["clipped"] for s in spreads),
        }
        keys = ["entropy", "vf_loss_unclipped", "vf_explained_var"]
        if self.config.kl_coef > 0:
            keys.append("mean_kl_loss")
        for key in keys:
            values = [learners[m][key] for m in self.trained if key in learners.get(m, {})]
            row[key] = float(np.mean(values)) if values else float("nan")
        return row

    def _learner_counts(self) -> tuple[float, int, int]:
        """The learner(s)' running totals: update seconds, trained-module transitions
        consumed, gradient steps."""
        results = self.algo.learner_group.foreach_learner(
            lambda lr: (lr.update_s, lr.samples, lr.gradient_steps)
        )
        rows = [r.get() for r in results if r.ok]
        return (
            float(sum(r[0] for r in rows)),
            int(sum(r[1] for r in rows)),
            int(sum(r[2] for r in rows)),
        )

    # ---- weights ------------------------------------------------------------------------
    def weights(self, module_ids: Sequence[str]) -> dict[str, dict[str, np.ndarray]]:
        """Current RLlib states of modules, read from the learner group (never a stale copy)."""
        return self.algo.learner_group.get_weights(list(module_ids))

    def set_trained_weights(self, weights: Mapping[str, ModuleState]) -> None:
        """Restore trained modules (on resume), learner group and env runners alike."""
        self.algo.learner_group.set_weights(dict(weights))
        _Pushed(self._pushed.phi, self._pushed.salt, dict(weights)).push(self.algo.env_runner_group)

    def training_state(self) -> dict[str, Any]:
        """What the learner's training carries into the next generation besides its weights
        (`OracleLearner.training_state`), and the env steps sampled so far (where the lr and
        entropy schedules are): a resumed run takes it up with `set_training_state`."""
        first, *_ = [
            r.get()
            for r in self.algo.learner_group.foreach_learner(
                lambda learner: learner.training_state(LEARNER)
            )
        ]
        key = (ENV_RUNNER_RESULTS, NUM_ENV_STEPS_SAMPLED_LIFETIME)
        steps = int(self.algo.metrics.peek(key, default=0))
        return first | {"env_steps": self._env_steps_before + steps}

    def start_schedules_at(self, env_steps: int) -> None:
        """Fresh optimizers whose schedules go on `env_steps` in (a resumed build)."""
        self._env_steps_before = int(env_steps)
        self.algo.learner_group.foreach_learner(
            lambda learner: learner.start_schedules_at(env_steps)
        )

    def set_training_state(self, state: Mapping[str, Any]) -> None:
        """Take up a saved `training_state` (on resume), on every learner."""
        self._env_steps_before = int(state["env_steps"])
        self.algo.learner_group.foreach_learner(
            lambda learner: learner.set_training_state(LEARNER, dict(state), state["env_steps"])
        )

    def reseed(self, salt: int) -> None:
        """Sample and shuffle from here on as generation `salt` of this run does, whatever was
        sampled before: every env runner restarts its episodes from generators of (seed,
        runner, salt) (`BatchedEnvRunner.reseed`; RLlib's own runner is not reseeded), and
        every learner's global generators (the minibatches' shuffles) from (seed, salt). A run
        resumed after generation salt − 1 then trains generation salt as the undisturbed
        run did."""
        words = [int(self.seed), int(salt)]
        self.algo.env_runner_group.foreach_env_runner(
            lambda runner: runner.reseed(salt) if hasattr(runner, "reseed") else None,
            local_env_runner=True,
        )
        self.algo.learner_group.foreach_learner(lambda learner: learner.reseed(words))

    def reset_learner(self, lr: float, entropy_coef: float) -> None:
        """Train the learner on with these hyperparameters and a fresh optimizer state."""
        self.algo.learner_group.foreach_learner(
            lambda learner: learner.reset_module(LEARNER, lr, entropy_coef)
        )

    def learner_hyperparameters(self) -> dict[str, float]:
        """The lr and entropy coefficient the learner trains with now."""
        (out,) = [
            r.get()
            for r in self.algo.learner_group.foreach_learner(
                lambda learner: learner.hyperparameters(LEARNER)
            )
        ]
        return out

    def export_state(self, state: ModuleState) -> dict[str, Any]:
        """The plain-torch export of an RLlib module state of this Oracle's modules."""
        return export_trained(self.config, state, self.env)

    def policy(self, state: ModuleState) -> MLPPolicy:
        """The deterministic policy that everything outside the Oracle plays."""
        return MLPPolicy(self.env, self.export_state(state))

    def stop(self) -> None:
        self.algo.stop()
