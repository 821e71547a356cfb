"""A worker node lost mid-experiment loses nothing (issue 36): on a Ray cluster of a
CPU-less head (the driver) and one 2-CPU worker (raylets on this machine), both trials of
a smoke experiment run on the worker; once one has completed a generation, a second
worker joins and the first is removed, processes and all. The Runner resubmits each lost
trial with a fresh pack of its directory, it resumes from its last complete generation on
the new node, and the experiment ends with every trial in results.json. One trial trains
in place (a filesystem every node sees), the other in a staging folder mirrored to the
driver's node (as on a node that does not see it)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest
import ray
import yaml
from ray.cluster_utils import Cluster

from hola_ray.experiment import Experiment, Runner
from hola_ray.population.rundir import RunDir
from hola_ray.progress import RAY_RUNTIME_ENV

ROOT = Path(__file__).resolve().parent.parent
GENERATIONS = 3


@pytest.fixture(scope="module")
def cluster():
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0})
    cluster.add_node(num_cpus=2)
    cluster.wait_for_nodes()
    ray.init(address=cluster.address, include_dashboard=False, runtime_env=RAY_RUNTIME_ENV)
    yield cluster
    ray.shutdown()
    cluster.shutdown()


def experiment(tmp_path: Path) -> Experiment:
    config = {
        "base": str(ROOT / "configs" / "smoke.yaml"),
        "overrides": {"generations": GENERATIONS},
        "methods": {"hola": {}, "sp": {}},
        "seeds": [0],
        "evaluation": {
            "episodes": 1,
            "seeds": [0],
            "cell_episodes": 1,
            "pools": ["hot"],
            "learner": "final",
        },
    }
    path = tmp_path / "exp.yaml"
    path.write_text(yaml.safe_dump(config))
    return Experiment.from_yaml(path)


def stamps(trial_dirs: list[Path]) -> dict[str, tuple[bytes, int]]:
    """Every file of every completed generation folder: its bytes and its mtime."""
    out = {}
    for root in trial_dirs:
        run = RunDir(root)
        for g in run.completed():
            for f in sorted(run.generation(g).iterdir()):
                out[str(f)] = (f.read_bytes(), f.stat().st_mtime_ns)
    return out


def alive(class_name: str) -> list:
    from ray.util.state import list_actors

    return list_actors(filters=[("class_name", "=", class_name), ("state", "=", "ALIVE")])


class HalfMirrored(Runner):
    """hola's trial in place, sp's mirrored to the driver's node."""

    def mirror_of(self, trial: str) -> bool | None:
        return trial.startswith("sp-")


def test_a_worker_node_lost_mid_experiment_loses_nothing(cluster, tmp_path):
    runner = HalfMirrored(experiment(tmp_path), tmp_path / "out", poll_s=0.2)
    lines: list[str] = []
    runner.say = lines.append
    outcome: list = []

    def drive():
        try:
            outcome.append(runner.run())
        except BaseException as err:  # noqa: BLE001 - the test reads it below
            outcome.append(err)

    thread = threading.Thread(target=drive, daemon=True)
    thread.start()
    dirs = [runner.trial_dir(t) for t in runner.exp.trials()]
    deadline = time.monotonic() + 180
    while not any(1 in RunDir(d).completed() for d in dirs if (d / "generations").is_dir()):
        assert time.monotonic() < deadline and thread.is_alive(), lines
        time.sleep(0.05)
    before = stamps(dirs)
    assert all(len(RunDir(d).completed()) < GENERATIONS + 1 for d in dirs), "none left to lose"
    [doomed] = cluster.worker_nodes  # the one worker both trials run on
    cluster.add_node(num_cpus=2)
    cluster.wait_for_nodes()
    cluster.remove_node(doomed)

    thread.join(timeout=300)
    assert not thread.is_alive(), lines
    [results] = outcome
    assert isinstance(results, dict), f"{results!r}\n" + "\n".join(lines)
    assert any("lost with its node" in line and "resubmitted" in line for line in lines), lines
    assert not any("FAILED" in line for line in lines), lines
    done = {line.split(":")[0]: line for line in lines if ": done in" in line}
    assert "in place" in done["hola-s0"] and "mirrored" in done["sp-s0"], done
    assert set(results["trials"]) == set(runner.exp.trials())
    for d in dirs:
        run = RunDir(d)
        first = 1 if d.name.startswith("sp-") else 0  # self-play has no generation 0
        assert run.completed() == list(range(first, GENERATIONS + 1)), d
        assert [r["generation"] for r in run.metrics_rows()] == run.completed()
        assert not list((d / "generations").glob(".tmp*"))
    after = stamps(dirs)
    assert {f: after[f] for f in before} == before  # no completed generation rewritten
    assert not alive("Coordinator") and not alive("Mirror")
