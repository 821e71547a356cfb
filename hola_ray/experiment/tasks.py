"""What runs as Ray tasks: a trial's training (in place, or in a staging folder mirrored to
the driver's node: `hola_ray.experiment.mirror`), a pool's reference returns and a trial's
evaluation against the pools (`hola_ray.evaluation.zero_shot`)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hola_ray.config.scenario import PursuitConfig
from hola_ray.methods.config import RunConfig
from hola_ray.process import pin_threads


def trial_state(run_dir: Path, generations: int) -> tuple[str, int | None]:
    """('done' | 'partial' | 'new', last complete generation) of a trial's run directory.
    Done: its last generation is complete and so is learner.pt (written just after it)."""
    from hola_ray.population.rundir import RunDir

    restored = Path(run_dir) / RESTORED
    if restored.is_file():  # a published trial brought back to a new machine: done
        return "done", int(json.loads(restored.read_text())["generation"])
    run = RunDir(run_dir)
    last = run.last_completed()
    if last is None:
        return "new", None
    return ("done" if run.finished(generations) else "partial"), last


RESTORED = "restored.json"
"""a trial folder brought back from its published files (`publish --restore`): the trial is
done, its figures and chosen learner are there, its generations are not"""

MARK = ".experiment"
"""DIR/.experiment: a token that says which nodes see the experiment's directory"""


def sees(run_dir: Path, token: str | None) -> bool:
    """Whether this node sees the experiment directory of `run_dir` (DIR/trials/<t>)."""
    mark = Path(run_dir).parent.parent / MARK
    try:
        return token is not None and mark.read_text() == token
    except OSError:
        return False


def _run_trial(
    config: RunConfig,
    run_dir: str,
    token: str | None = None,
    driver_node: str | None = None,
    seed: bytes | None = None,
    mirror: bool | None = None,
    adopt_from: Sequence[str] = (),
) -> str:
    """One trial. Where its node sees the experiment directory (one machine, or a shared
    filesystem), it trains there, taking generation 0 from a sibling trial that built the
    same one (`adopt_from`: the trials of its seed whose methods share MEP's population).
    Elsewhere it trains in a staging folder of its node (from `seed`, the driver's copy of
    a partial trial, if given) and mirrors it to the driver's node after every generation
    (`hola_ray.experiment.mirror`). Returns how it stored its folder."""
    import shutil
    import tempfile

    import ray
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    from hola_ray.experiment.mirror import DirectorySync, Mirror, unpack
    from hola_ray.methods.trainer import Trainer
    from hola_ray.process import quiet_ray_noise

    quiet_ray_noise()  # before its trainer builds RLlib's algorithm
    # Not `pin_threads`: the learner's torch threads set how its gradients are summed, and
    # a trial must train as `python -m hola_ray.run` of its config does (a test compares
    # them); pinned to its one CPU it read returns 1e-8 apart.
    root, run_config = Path(run_dir), config
    tags = {"run": root.parent.parent.name, "trial": root.name}  # DIR/trials/<trial>
    if mirror is None:
        mirror = not sees(root, token)
    if not mirror:
        donors = tuple(Path(d) for d in adopt_from)
        Trainer(run_config, root, progress=False, adopt_from=donors, tags=tags).fit()
        return "in place"
    staging = Path(tempfile.gettempdir()) / "hola_ray-trials" / str(token) / root.name
    if seed is not None:
        unpack(seed, staging)
    else:
        shutil.rmtree(staging, ignore_errors=True)
    where = NodeAffinitySchedulingStrategy(node_id=driver_node, soft=False)
    actor = Mirror.options(scheduling_strategy=where).remote(str(root))
    sync = DirectorySync(staging, actor)
    if seed is not None:
        sync.mark_seen()  # the driver has all of it already
    try:
        Trainer(run_config, staging, progress=False, saved=sync, tags=tags).fit()
        sync()
    finally:
        ray.kill(actor)
    shutil.rmtree(staging, ignore_errors=True)  # all of it is on the driver's node now
    return "mirrored to the driver's node"


def _reference(pool: str, settings: dict[str, Any], config: PursuitConfig) -> dict[str, Any]:
    """A pool's reference returns for the BR-Prox score and the learner's scale's reference
    seats on the evaluation's episodes: computed once, for every trial."""
    pin_threads(1)  # its one CPU: two such tasks side by side otherwise spin each other
    from hola_ray.evaluation.players import pool_label, pools
    from hola_ray.evaluation.scale import load_references, play_references
    from hola_ray.evaluation.zero_shot import cell_returns

    members = list(pools([pool], [], config)[pool_label(pool)].values())
    seeds = settings["seeds"]
    return {
        "returns": cell_returns(members, members, config, settings["cell_episodes"], seeds),
        "seats": play_references(
            load_references(config), members, config, settings["episodes"], seeds
        ),
    }


def _evaluate_trial(
    learner: bytes, settings: dict[str, Any], config: PursuitConfig, references: dict[str, dict]
) -> dict[str, Any]:
    """A learner (its file's bytes, read by the driver: any node can evaluate it) against
    the pools."""
    pin_threads(1)  # its one CPU (see `_reference`)
    import tempfile

    from hola_ray.evaluation.players import load_learner, pool_label, pools
    from hola_ray.evaluation.zero_shot import evaluate_learner

    members = pools(list(settings["pools"]), [], config)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "learner.pt"
        path.write_bytes(learner)
        _, policy = load_learner(path, config)
    return {
        pool: evaluate_learner(
            policy,
            list(members[pool_label(pool)].values()),
            references[pool]["returns"],
            config,
            settings["episodes"],
            list(settings["seeds"]),
            settings["cell_episodes"],
            references[pool]["seats"],
        )
        for pool in settings["pools"]
    }
