"""What the Oracle's learner keeps per trained module between updates, and how a run
resets or resumes it: the optimizers' states, the KL coefficient, the schedules of the
learning rate and the entropy coefficient, and the process's global generators. A mixin of
`OracleLearner` (an RLlib `TorchLearner`, whose attributes it reads)."""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any

import numpy as np


class ModuleTraining:
    """The per-module training state of an RLlib torch learner (`OracleLearner`)."""

    def reset_module(self, module_id: str, lr: float, entropy_coeff: float) -> None:
        """Train `module_id` from now on with these lr and entropy coefficient and a fresh
        Adam state (PBT: another agent's weights were just loaded into it)."""
        from ray.rllib.utils.schedules.scheduler import Scheduler

        for _, optim in self.get_optimizers_for_module(module_id):
            optim.state.clear()
            self._optimizer_lr_schedules[optim] = Scheduler(
                fixed_value_or_schedule=lr, framework=self.framework, device=self._device
            )
            self._set_optimizer_lr(optim, lr=lr)
        self.entropy_coeff_schedulers_per_module[module_id] = Scheduler(
            fixed_value_or_schedule=entropy_coeff, framework=self.framework, device=self._device
        )

    def training_state(self, module_id: str) -> dict[str, Any]:
        """What `module_id`'s training carries from one generation into the next besides its
        weights: its optimizers' states (Adam's moments and step count) and its KL
        coefficient (adapted when the KL penalty is on)."""
        return {
            "optimizers": {
                name: copy.deepcopy(optim.state_dict())
                for name, optim in self.get_optimizers_for_module(module_id)
            },
            "kl_coeff": float(self.curr_kl_coeffs_per_module[module_id]),
        }

    def set_training_state(self, module_id: str, state: dict[str, Any], env_steps: int) -> None:
        """Take up `training_state`'s output, `env_steps` env steps into the schedules."""
        for name, optim in self.get_optimizers_for_module(module_id):
            optim.load_state_dict(state["optimizers"][name])
        self.curr_kl_coeffs_per_module[module_id].data.fill_(state["kl_coeff"])
        self._env_steps_before = int(env_steps)

    def start_schedules_at(self, env_steps: int) -> None:
        """The schedules (the learning rate's) `env_steps` in, with fresh optimizers: a
        stopped build resumed from its last check, whose decay goes on from there."""
        self._env_steps_before = int(env_steps)
        for names in self._module_optimizers.values():
            for name in names:
                optimizer = self._named_optimizers[name]
                schedule = self._optimizer_lr_schedules.get(optimizer)
                if schedule is not None:
                    self._set_optimizer_lr(optimizer, lr=schedule.update(timestep=env_steps))

    def reseed(self, words: Sequence[int]) -> None:
        """This process's global generators (the minibatches' shuffles) from `words`."""
        from hola_ray.process import seed_torch

        np.random.seed(np.random.SeedSequence(list(words)).generate_state(4))  # noqa: NPY002
        seed_torch(words)

    def hyperparameters(self, module_id: str) -> dict[str, float]:
        """The lr and entropy coefficient `module_id` trains with now."""
        (_, optim), *_ = self.get_optimizers_for_module(module_id)
        return {
            "lr": float(self._get_optimizer_lr(optim)),
            "entropy_coef": float(
                self.entropy_coeff_schedulers_per_module[module_id].get_current_value()
            ),
        }
