"""PPO whose env runners sample the next train batch while the learner updates on this one.

RLlib's PPO (new API stack) samples, then updates, then pushes the weights: on two cores
the env runner's core idles through the update and the learner's through the sampling.
`OverlappedPPO` (`oracle.overlap: true`) asks the remote env runners for batch k+1 before
the learner starts on batch k. The runners then sample batch k+1 with the weights of update
k-1, one update behind the learner: PPO's ratio is taken against the sampler's own action
log-probabilities (as always), so the clipped objective starts a little off the sampler's
policy instead of on it. The weights of update k are pushed as RLlib pushes them (without
waiting); a Ray actor runs its calls in order, so batch k+2 is sampled with them.

The Oracle says before each iteration whether another one follows (`prefetch`): the last
iteration of a `train` call asks for nothing more, so no batch sampled with an old φ or
old partners is ever trained on; `drain` drops a request still in flight (an estimate of
the last iteration missed). Without remote env runners (`oracle.env_runners: 0`) it is
RLlib's PPO.
"""

from __future__ import annotations

from ray.rllib.algorithms.ppo import PPO
from ray.rllib.core import ALL_MODULES
from ray.rllib.execution.rollout_ops import synchronous_parallel_sample
from ray.rllib.utils.metrics import (
    ENV_RUNNER_RESULTS,
    ENV_RUNNER_SAMPLING_TIMER,
    LEARNER_RESULTS,
    LEARNER_UPDATE_TIMER,
    NUM_ENV_STEPS_SAMPLED_LIFETIME,
    NUM_MODULE_STEPS_TRAINED_LIFETIME,
    SYNCH_WORKER_WEIGHTS_TIMER,
    TIMERS,
)

_TAG = "hola_ray_overlapped_sample"


def _sample(runner):
    return runner.sample(), runner.get_metrics()


class OverlappedPPO(PPO):
    """RLlib's PPO with sampling overlapped with the update (the module's doc)."""

    prefetch: bool = True
    """whether the iteration about to run asks for the next batch before it updates"""
    _in_flight: int = 0
    """sample requests sent to the remote env runners and not collected yet"""

    @property
    def overlaps(self) -> bool:
        return bool(self.config.learner_config_dict.get("overlap")) and (
            self.env_runner_group.num_remote_env_runners() > 0
        )

    def training_step(self) -> None:
        if not self.overlaps:
            return super().training_step()
        group = self.env_runner_group
        with self.metrics.log_time((TIMERS, ENV_RUNNER_SAMPLING_TIMER)):
            if not self._in_flight:
                self._request()
            results = group.fetch_ready_async_reqs(tags=_TAG, timeout_seconds=None)
            self._in_flight = 0
            episodes = [e for _, (eps, _) in results for e in eps]
            metrics = [m for _, (_, m) in results]
            if not episodes:  # every runner failed: sample as RLlib does (it restores them)
                episodes, metrics = synchronous_parallel_sample(
                    worker_set=group,
                    max_env_steps=self.config.total_train_batch_size,
                    sample_timeout_s=self.config.sample_timeout_s,
                    _uses_new_env_runners=True,
                    _return_metrics=True,
                )
                if not episodes:
                    return
            if self.prefetch:
                self._request()  # batch k+1, sampled while the learner updates on batch k
            self.metrics.aggregate(metrics, key=ENV_RUNNER_RESULTS)

        with self.metrics.log_time((TIMERS, LEARNER_UPDATE_TIMER)):
            learner_results = self.learner_group.update(
                episodes=episodes,
                timesteps={
                    NUM_ENV_STEPS_SAMPLED_LIFETIME: self.metrics.peek(
                        (ENV_RUNNER_RESULTS, NUM_ENV_STEPS_SAMPLED_LIFETIME)
                    ),
                    NUM_MODULE_STEPS_TRAINED_LIFETIME: self.metrics.peek(
                        (LEARNER_RESULTS, ALL_MODULES, NUM_MODULE_STEPS_TRAINED_LIFETIME),
                        default=0,
                    ),
                },
                num_epochs=self.config.num_epochs,
                minibatch_size=self.config.minibatch_size,
                shuffle_batch_per_epoch=self.config.shuffle_batch_per_epoch,
            )
            self.metrics.aggregate(learner_results, key=LEARNER_RESULTS)

        with self.metrics.log_time((TIMERS, SYNCH_WORKER_WEIGHTS_TIMER)):
            # queued behind the request in flight: the batch after it samples with these
            group.sync_weights(
                from_worker_or_learner_group=self.learner_group,
                policies=set(learner_results[0].keys()) - {ALL_MODULES},
                inference_only=True,
            )

    def _request(self) -> None:
        self._in_flight = self.env_runner_group.foreach_env_runner_async(_sample, tag=_TAG)

    def drain(self) -> int:
        """Wait for and drop a sample request still in flight; the env steps it sampled."""
        if not self._in_flight:
            return 0
        results = self.env_runner_group.fetch_ready_async_reqs(tags=_TAG, timeout_seconds=None)
        self._in_flight = 0
        return sum(e.env_steps() for _, (eps, _) in results for e in eps)
