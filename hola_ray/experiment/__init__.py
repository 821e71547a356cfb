"""The paper's experiment on Ray: every method × seed, then the zero-shot evaluation.

    python -m hola_ray.experiment --config configs/experiments/X.yaml [--out DIR]
    python -m hola_ray.experiment --resume DIR

An experiment config names a base run config, the methods (each with its own overrides
of the base), the seeds and the evaluation:

    base: configs/default.yaml        # relative to the repository root or to this file
    overrides: {env: {n_evaders: 2}}  # applied to every trial (optional)
    methods:                          # method → overrides for its trials ({} for none)
      hola: {}
      sp: {generations: 12}
      hola_long: {method: hola, pretrain: {env_steps: 1000000}}   # a variant: an ablation row
    seeds: [0, 1, 2]
    parallel: 0                       # trials started at once; 0: all (Ray runs those that fit)
    evaluation: {episodes: 50, seeds: [0, 1, 2], cell_episodes: 10, pools: [hot, het],
                 learner: final,      # final: learner.pt; best: best.pt
                 pairs: [[uniform, sp]]}  # differences beyond hola − every other method

Each trial (method × seed) is one `Trainer` run in `DIR/trials/<method>-s<seed>/`, run as a
Ray task in a placement group of its own: one bundle for the trial's process (its PPO
learner, with `oracle.gpus_per_learner` GPUs) and one CPU per env runner, packed onto one
node where one has room. The env runners and evaluation actors the trial starts are placed in
that group (its coordinator, which holds no CPU, on the trial's own node), so a trial never
waits for a CPU another trial took. With `parallel: 0` every trial asks Ray for its group
at once: Ray runs as many as the CPUs hold and the rest wait for CPUs ("waiting for CPUs"
in the progress view), and on an autoscaling cluster their demand is what adds nodes;
`parallel: N` starts at most N at a time. A trial whose node cannot see DIR (a cluster
without a shared filesystem) trains in a staging folder there and mirrors it to DIR on the
driver's node after every generation (`hola_ray.experiment.mirror`). A trial whose run
directory holds its last generation is done and never rerun: `--resume DIR` skips it,
continues a trial that was cut short from its last complete generation and starts the rest.
Then every trial's learner is evaluated against the pools (`hola_ray.evaluation.zero_shot`,
one Ray task per trial, cached in `DIR/evaluation/` under the pools' manifest hashes, so a
rebuilt pool is evaluated again), and the experiment writes `DIR/results.json` (per
trial, per method, and the paired differences between methods), `DIR/results.md` and
`DIR/figure.png` (the paper's Fig. 4 layout and AT-Drone's two metrics, one bar per
method: the mean over its seeds, whiskers its 95 % interval). Intervals and differences:
`hola_ray.evaluation.compare` (a bootstrap over training seeds within each method and over
episodes within each partner combination; every trial plays the same episodes, so
differences are paired).
With `evaluation: {protocol: open-teams, arenas: [...], modes: [...], sizes: [...]}` the
trials are played through contract §6.4's grid instead (`hola_ray.evaluation.open_teams`:
every arena, team size and mode, each method over its seeds, every pair of methods'
differences per cell and over each mode's cells), written to `DIR/results.json`,
`DIR/results.md` and `DIR/open-teams-<arena>.png`; the trials may then train in scenarios
that differ in the team and the arena.
While it runs, a line every few seconds (and `DIR/progress.json`) says which trials run,
wait or are done.

The modules: `config` (the experiment config, `Experiment`), `tasks` (what runs as Ray
tasks: a trial, a pool's reference returns, a trial's evaluation), `mirror` (a trial's
folder mirrored to the driver's node), `runner` (`Runner`, the driver), `inflight` (its
trials in the air, resubmitted when their node is lost), `results` (per
method, the paired differences, results.md) and `command` (`python -m hola_ray.experiment`,
`hola-experiment`).
"""

from typing import TYPE_CHECKING

# Every name is imported from its module on first use (`__getattr__` below), so that `python
# -m hola_ray.experiment` re-runs itself under the fixed hash seed (`command.script`) before
# it imports the methods, torch, Ray or RLlib.
_WHERE = {
    "CONFIG_NAME": "config",
    "ROOT": "config",
    "EvaluationSettings": "config",
    "Experiment": "config",
    "deep_merge": "config",
    "parse_trial": "config",
    "trial_name": "config",
    "DirectorySync": "mirror",
    "Mirror": "mirror",
    "pack": "mirror",
    "unpack": "mirror",
    "write_tree": "mirror",
    "EVALUATION_FORMAT": "results",
    "aggregate": "results",
    "results_table": "results",
    "Runner": "runner",
    "MARK": "tasks",
    "sees": "tasks",
    "trial_state": "tasks",
    "main": "command",
    "script": "command",
}

if TYPE_CHECKING:
    from hola_ray.experiment.command import main, script
    from hola_ray.experiment.config import (
        CONFIG_NAME,
        ROOT,
        EvaluationSettings,
        Experiment,
        deep_merge,
        parse_trial,
        trial_name,
    )
    from hola_ray.experiment.mirror import DirectorySync, Mirror, pack, unpack, write_tree
    from hola_ray.experiment.results import EVALUATION_FORMAT, aggregate, results_table
    from hola_ray.experiment.runner import Runner
    from hola_ray.experiment.tasks import MARK, sees, trial_state

__all__ = [
    "CONFIG_NAME",
    "EVALUATION_FORMAT",
    "MARK",
    "ROOT",
    "DirectorySync",
    "EvaluationSettings",
    "Experiment",
    "Mirror",
    "Runner",
    "aggregate",
    "deep_merge",
    "main",
    "pack",
    "parse_trial",
    "results_table",
    "script",
    "sees",
    "trial_name",
    "trial_state",
    "unpack",
    "write_tree",
]


def __getattr__(name: str):
    """The public names, each imported from its module (`_WHERE`) on first use."""
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(f"hola_ray.experiment.{_WHERE[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
