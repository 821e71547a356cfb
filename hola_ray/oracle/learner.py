"""The Oracle's PPO learner (`OracleLearner`): the lean update (minibatches of the loss's
columns, a masked mean), the per-module optimizers and hyperparameters, and the
population-entropy bonus's connector placed before GAE (`hola_ray.oracle.connectors`)."""

from __future__ import annotations

import time
from typing import Any

import torch
from ray.rllib.algorithms.ppo.ppo import (
    LEARNER_RESULTS_KL_KEY,
    LEARNER_RESULTS_VF_EXPLAINED_VAR_KEY,
    LEARNER_RESULTS_VF_LOSS_UNCLIPPED_KEY,
)
from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner
from ray.rllib.connectors.learner.add_one_ts_to_episodes_and_truncate import (
    AddOneTsToEpisodesAndTruncate,
)
from ray.rllib.connectors.learner.general_advantage_estimation import GeneralAdvantageEstimation
from ray.rllib.core.columns import Columns
from ray.rllib.core.learner.learner import ENTROPY_KEY, POLICY_LOSS_KEY, VF_LOSS_KEY
from ray.rllib.evaluation.postprocessing import Postprocessing
from ray.rllib.utils.metrics import NUM_ENV_STEPS_SAMPLED_LIFETIME
from ray.rllib.utils.torch_utils import explained_variance

from hola_ray.oracle.connectors import AddOneTsInArrays, DropFrozenModules, PopulationEntropyBonus
from hola_ray.oracle.distribution import BetaTurn
from hola_ray.oracle.fused import FusedLoss
from hola_ray.oracle.minibatches import Minibatch, Minibatches
from hola_ray.oracle.module_training import ModuleTraining


class _Totals:
    """An update's trained rows per module (as sized ranges) and env steps, read by RLlib's
    step-count logging as it reads a minibatch."""

    def __init__(self, policy_batches: dict[str, range], env_steps: int):
        self.policy_batches = policy_batches
        self._env_steps = env_steps

    def env_steps(self) -> int:
        return self._env_steps


_LOSS_COLUMNS = (
    Columns.OBS,
    Columns.ACTIONS,
    Columns.ACTION_LOGP,
    Columns.LOSS_MASK,
    Postprocessing.ADVANTAGES,
    Postprocessing.VALUE_TARGETS,
)
"""what `OracleLearner.compute_loss_for_module` and the module's `forward_train` read"""


def _masked_means(mask: torch.Tensor | None):
    """(mean over the rows the loss mask keeps, the same as the loss takes it): the loss's
    mean keeps the masked rows as zeros rather than cutting them out (a gather less per
    step), the same gradient and the loss itself to within its float rounding."""
    if mask is None:
        return torch.mean, torch.mean
    num_valid = torch.sum(mask)

    def mean(x: torch.Tensor) -> torch.Tensor:
        return torch.sum(x[mask]) / num_valid

    def loss_mean(x: torch.Tensor) -> torch.Tensor:
        return torch.sum(torch.where(mask, x, 0.0)) / num_valid

    return mean, loss_mean


class OracleLearner(ModuleTraining, PPOTorchLearner):
    """PPO learner of the Oracle and of MEP pre-training.

    - Its pipeline drops the frozen partners' rows before GAE (`DropFrozenModules`), and with
      `mep_alpha` > 0 in `learner_config_dict` adds the population-entropy bonus to the
      rewards of the `mep_modules` before GAE.
    - A train batch can hold no step of a trained module: when the learner collided early
      in every vector env's episode, the sampled window holds only its frozen partners
      playing on. RLlib's update then fails (no minibatch at all); this learner skips
      that update instead and counts it as `num_skipped_updates`.
    - Frozen partner modules get no optimizer, and a minibatch's gradient step is one
      backward pass, one global-norm clip per trained module (RLlib's rule:
      g · min(1, c / max(‖g‖ + 1e-6, c))) and one fused Adam step. RLlib's own path zeroes,
      checks and steps an optimizer per module of the population (11 in the paper's
      setting) and clips tensor by tensor: 2.4× the time of the torch work itself. A
      minibatch whose gradient is not finite is skipped (counted as
      `num_nonfinite_gradient_steps`), where RLlib would zero the bad tensors and step.
    - Minibatches are cut by index (`hola_ray.oracle.minibatches`), RLlib's step counters
      logged once per update, and the PPO loss builds only the terms its gradient needs
      (`compute_loss_for_module`). RLlib's off-policyness figure (gradient updates since
      the sampler's weights) is not logged: in PPO it only counts the minibatches.
      `oracle.update: rllib` keeps RLlib's own pipeline, iterator, loss and logging.
    """

    update_s: float = 0.0
    """Seconds spent in `update` so far (the learner pipeline and SGD). RLlib's own
    learner_update_timer is a moving average, not a per-iteration time."""
    samples: int = 0
    """Transitions of the trained modules this learner consumed so far: every step a
    trained module acted in the updates' episodes (each seat it played)"""
    gradient_steps: int = 0
    """Minibatch gradient steps applied to a trained module so far"""
    step_s: float = 0.0
    """Seconds of `update_s` spent in the minibatch steps themselves (forward, loss,
    backward, clip, Adam: `_uncompiled_update`); the rest is the learner pipeline (GAE)
    and RLlib's loop around the steps"""

    def update(self, *args, training_data=None, **kwargs):
        start = time.perf_counter()
        try:
            episodes = getattr(training_data, "episodes", None) or kwargs.get("episodes")
            if episodes is not None and not any(self._trains_on(ep) for ep in episodes):
                self.metrics.log_value("num_skipped_updates", 1, reduce="sum")
                return self.metrics.reduce()
            if episodes is not None:
                self.samples += sum(self._trained_steps(ep) for ep in episodes)
            return super().update(*args, training_data=training_data, **kwargs)
        finally:
            self.update_s += time.perf_counter() - start

    def _trained_steps(self, episode) -> int:
        """The steps of a (multi-agent) episode chunk that a trained module acted in."""
        agents = getattr(episode, "agent_episodes", None)
        if agents is None:
            return len(episode)
        return sum(
            len(sa)
            for aid, sa in agents.items()
            if self.should_module_be_updated(episode.module_for(aid))
        )

    def compute_loss_for_module(self, *, module_id, config, batch, fwd_out):
        """RLlib's PPO loss (`PPOTorchLearner.compute_loss_for_module`, the same terms and
        masking), less the work nothing reads: the entropy enters the graph only when its
        coefficient is not 0, the sampler's action distribution is built only for the KL
        penalty, and the logged statistics are computed once per update, from the last
        minibatch (what RLlib's window-1 logging keeps), in `after_gradient_based_update`."""
        if not self._lean:
            return super().compute_loss_for_module(
                module_id=module_id, config=config, batch=batch, fwd_out=fwd_out
            )
        module = self.module[module_id].unwrapped()
        _, loss_mean = _masked_means(batch.get(Columns.LOSS_MASK))
        dist = module.get_train_action_dist_cls().from_logits(fwd_out[Columns.ACTION_DIST_INPUTS])
        ratio = torch.exp(dist.logp(batch[Columns.ACTIONS]) - batch[Columns.ACTION_LOGP])
        advantages = batch[Postprocessing.ADVANTAGES]
        surrogate = torch.min(
            advantages * ratio,
            advantages * torch.clamp(ratio, 1 - config.clip_param, 1 + config.clip_param),
        )
        values = module.compute_values(batch, embeddings=fwd_out.get(Columns.EMBEDDINGS))
        vf_loss = torch.pow(values - batch[Postprocessing.VALUE_TARGETS], 2.0)
        vf_clipped = torch.clamp(vf_loss, 0, config.vf_clip_param)
        per_row = -surrogate + config.vf_loss_coeff * vf_clipped
        coeff = self.entropy_coeff_schedulers_per_module[module_id].get_current_value()
        if coeff:
            per_row = per_row - coeff * dist.entropy()
        total = loss_mean(per_row)
        kl = None
        if config.use_kl_loss:
            prev = module.get_exploration_action_dist_cls().from_logits(
                batch[Columns.ACTION_DIST_INPUTS]
            )
            kl = loss_mean(prev.kl(dist))
            total = total + self.curr_kl_coeffs_per_module[module_id] * kl
        self._keep_stats(module_id, batch, surrogate, vf_loss, vf_clipped, values, dist.entropy, kl)
        return total

    def _keep_stats(self, module_id, batch, surrogate, vf_loss, vf_clipped, values, entropy, kl):
        """Keep what the update logs of this minibatch's loss (RLlib's window-1 figures),
        computed only if it is the update's last (`after_gradient_based_update`);
        `entropy`: a function giving the policy's entropy per row, called then."""

        def stats() -> dict[str, torch.Tensor]:
            mean, _ = _masked_means(batch.get(Columns.LOSS_MASK))
            with torch.no_grad():
                return {
                    POLICY_LOSS_KEY: -mean(surrogate),
                    VF_LOSS_KEY: mean(vf_clipped),
                    LEARNER_RESULTS_VF_LOSS_UNCLIPPED_KEY: mean(vf_loss),
                    LEARNER_RESULTS_VF_EXPLAINED_VAR_KEY: explained_variance(
                        batch[Postprocessing.VALUE_TARGETS], values
                    ),
                    ENTROPY_KEY: mean(entropy()),
                    LEARNER_RESULTS_KL_KEY: (
                        kl.detach() if kl is not None else torch.zeros((), device=values.device)
                    ),
                }

        self._last_stats[module_id] = stats

    def after_gradient_based_update(self, *, timesteps) -> None:
        if self._env_steps_before:  # a resumed run: its schedules go on where they were
            steps = timesteps.get(NUM_ENV_STEPS_SAMPLED_LIFETIME, 0) + self._env_steps_before
            timesteps = {**timesteps, NUM_ENV_STEPS_SAMPLED_LIFETIME: steps}
        self._log_trained_totals()
        for module_id, stats in self._last_stats.items():
            self.metrics.log_dict(stats(), key=module_id, window=1)
        self._last_stats = {}
        for key, norm in self._last_norms.items():  # the last minibatch's, as window 1 keeps
            self.metrics.log_value(key, norm, window=1)
        self._last_norms = {}
        super().after_gradient_based_update(timesteps=timesteps)

    def configure_optimizers_for_module(self, module_id, config=None) -> None:
        if not self.should_module_be_updated(module_id):
            return  # frozen partners: weights are set, never stepped
        params = self.get_parameters(self._module[module_id])
        self.register_optimizer(
            module_id=module_id,
            optimizer=torch.optim.Adam(params, fused=True),
            params=params,
            lr_or_lr_schedule=config.lr,
        )

    def _create_iterator_if_necessary(
        self,
        *,
        training_data,
        num_total_minibatches: int = 0,
        num_epochs: int = 1,
        minibatch_size: int | None = None,
        shuffle_batch_per_epoch: bool = False,
        **kwargs,
    ):
        """The update's minibatches (`hola_ray.oracle.minibatches`) from the train batch the
        learner pipeline built, the modules not trained left out as RLlib does."""
        if training_data.data_iterators or not self._lean:
            return super()._create_iterator_if_necessary(
                training_data=training_data,
                num_total_minibatches=num_total_minibatches,
                num_epochs=num_epochs,
                minibatch_size=minibatch_size,
                shuffle_batch_per_epoch=shuffle_batch_per_epoch,
                **kwargs,
            )
        batch = self._make_batch_if_necessary(training_data=training_data)
        columns = {
            mid: {
                k: v
                for k, v in module_batch.items()
                if isinstance(v, torch.Tensor) and k in self._read_columns(mid)
            }
            for mid, module_batch in batch.policy_batches.items()
            if self.should_module_be_updated(mid, batch)
        }
        if not columns:
            return {}
        if any(self.module[mid].is_stateful() for mid in columns):
            raise ValueError("the Oracle's modules are not recurrent; its minibatches cut rows")
        self._trained_rows = dict.fromkeys(columns, 0)
        self._env_steps_trained = 0
        self._minibatches = 0
        return Minibatches(
            columns,
            env_steps=batch.env_steps(),
            num_epochs=num_epochs,
            minibatch_size=minibatch_size,
            shuffle=shuffle_batch_per_epoch or num_epochs > 1,
            num_total_minibatches=num_total_minibatches,
        )

    def _read_columns(self, module_id: str) -> frozenset[str]:
        """The train batch's columns the lean loss and the module's forward pass read: the
        minibatches gather these alone (the episodes' rewards, terminations, sequence
        numbers are GAE's, done with by then)."""
        read = set(_LOSS_COLUMNS)
        if self.config.get_config_for_module(module_id).use_kl_loss:
            read.add(Columns.ACTION_DIST_INPUTS)  # the sampler's distribution, for the KL
        return frozenset(read)

    def _log_metrics(self, batch) -> None:
        if not isinstance(batch, Minibatch):
            super()._log_metrics(batch)

    def _log_steps_trained_metrics(self, batch) -> None:
        """Counted per minibatch, logged once per update (`_log_trained_totals`)."""
        if not isinstance(batch, Minibatch):
            return super()._log_steps_trained_metrics(batch)
        for mid, rows in batch.rows.items():
            self._trained_rows[mid] += rows
        self._env_steps_trained += batch.env_steps()
        self._minibatches += 1

    def _log_trained_totals(self) -> None:
        """RLlib's trained-step counters (the lifetime ones drive its schedules) and its
        Prometheus counters, for the whole update at once: the same sums as per minibatch."""
        if not self._minibatches:
            return
        totals = _Totals(
            {mid: range(n) for mid, n in self._trained_rows.items()}, self._env_steps_trained
        )
        super()._log_steps_trained_metrics(totals)
        super()._log_metrics(totals)
        self._minibatches = 0

    def _uncompiled_update(self, batch, **kwargs):
        start = time.perf_counter()
        try:
            return self._step(batch)
        finally:
            self.step_s += time.perf_counter() - start

    def _step(self, batch):
        """One minibatch's forward pass, loss, backward pass, clip and optimizer steps."""
        if not self._lean:
            self._compute_off_policyness(batch)
        fused = self._fused_losses(batch)
        if fused is None:
            fwd_out = self.module.forward_train(batch)
            loss_per_module = self.compute_losses(fwd_out=fwd_out, batch=batch)
        else:
            fwd_out, loss_per_module = {}, {}
            for mid, loss in fused.items():
                coeff = self.entropy_coeff_schedulers_per_module[mid].get_current_value()
                config = self.config.get_config_for_module(mid)
                loss_per_module[mid], terms = loss(batch[mid], config, float(coeff))
                logits = terms["logits"]
                self._keep_stats(
                    mid,
                    batch[mid],
                    terms["surrogate"],
                    terms["vf_loss"],
                    terms["vf_clipped"],
                    terms["values"],
                    lambda logits=logits: BetaTurn.from_logits(logits).entropy(),
                    None,
                )
        trained = [m for m in loss_per_module if self._module_optimizers.get(m)]
        if not trained:
            return fwd_out, loss_per_module, {}
        for optim in self._optimizer_parameters:
            optim.zero_grad(set_to_none=True)
        total = sum(loss_per_module[m] for m in trained)
        if total.grad_fn is None:
            return fwd_out, loss_per_module, {}
        total.backward()
        self.gradient_steps += 1
        for mid in trained:
            clip = self.config.get_config_for_module(mid).grad_clip
            for name, optim in self.get_optimizers_for_module(mid):
                grads = [
                    p.grad for g in optim.param_groups for p in g["params"] if p.grad is not None
                ]
                if not grads:
                    continue
                norm = torch.linalg.vector_norm(torch.stack(torch._foreach_norm(grads)))
                if self._lean:  # logged once per update (`after_gradient_based_update`)
                    self._last_norms[(mid, f"gradients_{name}_global_norm")] = norm
                else:
                    self.metrics.log_value((mid, f"gradients_{name}_global_norm"), norm, window=1)
                if not torch.isfinite(norm):
                    self.metrics.log_value((mid, "num_nonfinite_gradient_steps"), 1, reduce="sum")
                    continue
                if clip:
                    torch._foreach_mul_(grads, min(1.0, clip / max(norm.item() + 1e-6, clip)))
                optim.step()
        return fwd_out, loss_per_module, {}

    def _fused_losses(self, batch) -> dict[str, FusedLoss] | None:
        """The fused loss of every module in the minibatch, or None (RLlib's update, or a
        module of another shape): the update runs the module's forward pass and the lean
        loss instead."""
        if not self._lean or self._loss_path == "module":
            return None
        out = {}
        for mid in batch:
            module = self.module[mid].unwrapped()
            known = self._fused_by_module.get(mid)
            if known is None or known[0] is not module:  # new, or RLlib rebuilt it
                fused = FusedLoss.of(
                    module,
                    self.config.get_config_for_module(mid),
                    compile=self._loss_path == "compiled",
                )
                self._fused_by_module[mid] = known = (module, fused)
            if known[1] is None:
                return None
            out[mid] = known[1]
        return out

    def set_loss_path(self, path: str) -> None:
        """How the lean update computes its loss from now on: `compiled` (the fused loss,
        `hola_ray.oracle.fused`, compiled: oracle.compile true), `eager` (the same function
        uncompiled: oracle.compile false), or `module` (RLlib's forward pass, then
        `compute_loss_for_module`: the path before the fused loss, kept to measure against)."""
        if path not in ("compiled", "eager", "module"):
            raise ValueError(f"no loss path {path!r}: compiled, eager or module")
        self._loss_path = path
        self._fused_by_module = {}

    def _trains_on(self, episode) -> bool:
        """Whether a (multi-agent) episode chunk holds a step of a module being trained."""
        agents = getattr(episode, "agent_episodes", None)
        if agents is None:
            return len(episode) > 0
        return any(
            len(sa) > 0 and self.should_module_be_updated(episode.module_for(aid))
            for aid, sa in agents.items()
        )

    def build(self) -> None:
        from hola_ray import third_party
        from hola_ray.process import pin_threads, quiet_ray_noise

        quiet_ray_noise()  # a remote learner's process: before RLlib builds its modules
        third_party.apply_rllib()  # and its connectors (a no-op where the Oracle applied them)
        super().build()
        extra = self.config.learner_config_dict
        self._lean = extra.get("update", "lean") == "lean"
        self._loss_path = "compiled" if extra.get("compile", False) else "eager"
        """how the lean update computes its loss (`set_loss_path`)"""
        self._fused_by_module: dict[str, tuple[torch.nn.Module, FusedLoss | None]] = {}
        """module id → (the module, its fused loss or None where it has none)"""
        if extra.get("overlap") and self.config.num_env_runners > 0:
            # the env runners sample on their own CPUs during the update (oracle/overlap.py):
            # the learner keeps to its own instead of spinning torch threads against them
            pin_threads(self.config.num_cpus_per_learner)
        """oracle.update: lean, or RLlib's own pipeline, iterator and loss"""
        self._last_stats: dict[str, Any] = {}
        """module id → the statistics of its last minibatch's loss, logged after the update"""
        self._last_norms: dict[tuple[str, str], torch.Tensor] = {}
        """(module id, key) → its last minibatch's gradient norm, logged after the update"""
        self._trained_rows: dict[str, int] = {}
        self._env_steps_trained = self._minibatches = 0
        """this update's trained rows per module, env steps and minibatches, so far"""
        self._env_steps_before = 0
        """env steps a resumed run had sampled before this Oracle (its schedules' offset)"""
        if self._learner_connector is None:
            return
        if self._lean:
            trained = [m for m in self.module.keys() if self.should_module_be_updated(m)]
            self._learner_connector.insert_before(
                GeneralAdvantageEstimation, DropFrozenModules(trained=trained)
            )
            pipeline = self._learner_connector
            if any(isinstance(p, AddOneTsToEpisodesAndTruncate) for p in pipeline.connectors):
                pipeline.insert_before(AddOneTsToEpisodesAndTruncate, AddOneTsInArrays())
                pipeline.remove(AddOneTsToEpisodesAndTruncate)
        alpha = float(extra.get("mep_alpha", 0.0))
        if alpha > 0.0:
            self._learner_connector.insert_before(
                GeneralAdvantageEstimation,
                PopulationEntropyBonus(alpha=alpha, module_ids=extra["mep_modules"]),
            )
