"""Each trial of an experiment runs in a placement group of its own, on a Ray cluster of a
CPU-less head (the driver) and two 2-CPU workers (raylets on this machine): its task takes
the first bundle and whatever it starts (an env runner's CPU, a member actor) lands in the
same group, trials run side by side on different nodes, a trial that does not fit yet
waits as "waiting for CPUs", one bigger than a node spreads over nodes, and every group is
removed afterwards. A trial whose node is lost mid-experiment is resubmitted and resumes
on a live node, in place or mirrored, losing nothing it had completed (the last test)."""

from __future__ import annotations

import json
import sys
import threading
import time
from pathlib import Path

import pytest
import ray
import yaml
from ray.cluster_utils import Cluster

from hola_ray.experiment import Experiment, Runner
from hola_ray.population.rundir import RunDir
from hola_ray.process import worker_runtime_env
from hola_ray.third_party import lean_local_ray

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module", autouse=True)
def two_nodes():
    lean_local_ray(log_monitor=False)  # its head's agent on a free port (another Ray runs)
    # no dashboard: Ray starts one best-effort on a Cluster's head, and where another
    # Ray of the suite holds its port the start waited out Ray's 60 s for it
    head = {"num_cpus": 0, "include_dashboard": False}
    cluster = Cluster(initialize_head=True, head_node_args=head)
    for _ in range(2):
        cluster.add_node(num_cpus=2)
    cluster.wait_for_nodes()
    # raylets on this machine inherit PYTHONHASHSEED as a local Ray's do (conftest sets it)
    ray.init(address=cluster.address, include_dashboard=False, runtime_env=worker_runtime_env())
    # the stand-in trials below travel by value: Ray's workers cannot import a test module
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    yield cluster
    ray.shutdown()
    cluster.shutdown()


def experiment(tmp_path: Path, env_runners: int, methods=("hola", "sp"), parallel=0):
    config = {
        "base": str(ROOT / "configs" / "smoke.yaml"),
        "overrides": {"oracle": {"env_runners": env_runners}},
        "methods": {m: {} for m in methods},
        "seeds": [0],
        "parallel": parallel,
    }
    path = tmp_path / "exp.yaml"
    path.write_text(yaml.safe_dump(config))
    return Experiment.from_yaml(path)


def stand_in(meet: int, until_one_waits: bool = False):
    """A stand-in trial: it starts what a trial starts (one CPU per env runner, a member
    actor asking for no CPU of its own), notes where each of them and itself run, and waits
    until `meet` trials have started (so that it fails unless they run side by side).
    until_one_waits: it also does not end before the progress view has shown two trials
    running and one waiting for its CPUs (else a trial could end, and free its CPUs, before
    the view ever looked at the one that waits)."""

    def trial(config: dict, run_dir: str, *where_to_store) -> str:
        @ray.remote(num_cpus=1)
        class EnvRunner:
            def where(self):
                return (
                    ray.util.get_current_placement_group().id.hex(),
                    ray.get_runtime_context().get_node_id(),
                )

        @ray.remote
        class Member:
            def where(self):
                return (
                    ray.util.get_current_placement_group().id.hex(),
                    ray.get_runtime_context().get_node_id(),
                )

        runners = [EnvRunner.remote() for _ in range(config.oracle.env_runners)]
        member = Member.remote()
        root = Path(run_dir)
        root.mkdir(parents=True)
        (root.parent / f"{root.name}.started").touch()
        wait_until(lambda: len(list(root.parent.glob("*.started"))) >= meet, f"{meet} trials")
        seen = {
            "trial": [
                ray.util.get_current_placement_group().id.hex(),
                ray.get_runtime_context().get_node_id(),
            ],
            "runners": ray.get([r.where.remote() for r in runners]),
            "member": ray.get(member.where.remote()),
        }
        # until the runner's progress view (DIR/progress.json) has shown this trial running
        progress = root.parent.parent / "progress.json"
        wait_until(lambda: _status(progress, root.name) == "running", f"{root.name} shown")
        if until_one_waits:
            seen_one = root.parent / "one-waited"

            def one_waits() -> bool:
                shown = list(_statuses(progress).values())
                if shown.count("running") == 2 and "placing" in shown:
                    seen_one.touch()
                return seen_one.exists()

            wait_until(one_waits, "two trials shown running and one waiting for CPUs")
        (root / "where.json").write_text(json.dumps(seen))
        return run_dir

    return trial


def wait_until(event, what: str, limit_s: float = 900.0) -> None:
    """Wait for `event()` to hold (polled); the limit only ends a test that would hang."""
    deadline = time.monotonic() + limit_s
    while not event():
        if time.monotonic() > deadline:
            raise TimeoutError(f"never happened: {what}")
        time.sleep(0.05)


def _statuses(progress: Path) -> dict[str, str]:
    try:
        return {t: row["status"] for t, row in json.loads(progress.read_text()).items()}
    except (OSError, ValueError, KeyError):
        return {}  # not written yet, or caught mid-replace


def _status(progress: Path, trial: str) -> str | None:
    return _statuses(progress).get(trial)


def run(
    exp: Experiment, out: Path, meet: int, until_one_waits: bool = False
) -> tuple[Runner, list[str]]:
    class Probe(Runner):
        trial_fn = staticmethod(stand_in(meet, until_one_waits))

    lines: list[str] = []
    runner = Probe(exp, out, say=lines.append, poll_s=0.2)
    runner.train()
    return runner, lines


def seen(runner: Runner, trial: str) -> dict:
    return json.loads((runner.trial_dir(trial) / "where.json").read_text())


def test_trials_run_side_by_side_each_with_what_it_starts_in_its_own_group(tmp_path):
    exp = experiment(tmp_path, env_runners=1)
    runner = Runner(exp, tmp_path / "out")
    assert runner.bundles("hola-s0") == [{"CPU": 1.0}, {"CPU": 1.0}]
    assert runner.fit_now() == 2  # 4 CPUs, 2 per trial
    runner, lines = run(exp, tmp_path / "out", meet=2)  # fails unless both run at once
    assert (
        "training 2 trial(s), all asking Ray for CPUs at once; "
        "this cluster holds 2 side by side now" in lines
    )
    where = {t: seen(runner, t) for t in exp.trials()}
    for t, w in where.items():
        group, node = w["trial"]
        assert w["runners"] == [[group, node]], (t, w)  # packed on the trial's node
        assert w["member"][0] == group, (t, w)
    assert where["hola-s0"]["trial"][0] != where["sp-s0"]["trial"][0]  # one group per trial
    assert where["hola-s0"]["trial"][1] != where["sp-s0"]["trial"][1]  # a node each
    table = ray.util.placement_group_table()
    for w in where.values():
        assert table[w["trial"][0]]["state"] == "REMOVED"
        assert list(table[w["trial"][0]]["bundles"].values()) == [{"CPU": 1.0}, {"CPU": 1.0}]


def test_a_trial_that_cannot_fit_yet_is_shown_waiting_for_cpus(tmp_path):
    # three trials asking for 2 CPUs each, on 4 CPUs: the third waits for CPUs rather
    # than starting with its env runner unplaced
    exp = experiment(tmp_path, env_runners=1, methods=("hola", "sp", "uniform"))
    runner, lines = run(exp, tmp_path / "out", meet=1, until_one_waits=True)
    assert any("2 running" in line and "1 waiting for CPUs (" in line for line in lines), lines
    assert len({seen(runner, t)["trial"][0] for t in exp.trials()}) == 3


def test_a_trial_bigger_than_a_node_spreads_and_one_bigger_than_the_cluster_is_reported(
    tmp_path,
):
    exp = experiment(tmp_path, env_runners=3, methods=("hola",))
    runner, _ = run(exp, tmp_path / "out", meet=1)
    w = seen(runner, "hola-s0")
    assert {g for g, _ in w["runners"]} == {w["trial"][0]}
    assert len({n for _, n in w["runners"]} | {w["trial"][1]}) == 2  # over both nodes

    lines: list[str] = []
    big = Runner(experiment(tmp_path, env_runners=4, methods=("hola",)), tmp_path / "big")
    big.say = lines.append
    big._check_fits(["hola-s0"])
    assert lines == [
        "warning: hola-s0 needs 5 CPU(s) and the cluster has 4: it waits until nodes join"
    ]


# ---- a trial whose node cannot see the experiment's directory -------------------------------
def files(root: Path) -> dict[str, bytes]:
    return {
        p.relative_to(root).as_posix(): p.read_bytes()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name != ".lock"
    }


def test_a_directory_is_mirrored_change_by_change_and_packs_whole(tmp_path):
    from hola_ray.experiment.mirror import DirectorySync, Mirror, pack, unpack

    source, target = tmp_path / "source", tmp_path / "target"
    (source / "generations" / "gen_0000").mkdir(parents=True)
    (source / "generations" / "gen_0000" / "state.json").write_text("{}")
    (source / "population").mkdir()
    (source / "population" / "slot_0.pt").write_bytes(b"zero")
    (source / "learner.json").write_text('{"generation": 0}')
    (source / ".lock").write_text("pid")
    sync = DirectorySync(source, Mirror.remote(str(target)))
    assert sync() == 3
    assert files(target) == files(source) and not (target / ".lock").exists()
    assert sync() == 0  # nothing changed, nothing sent

    (source / "generations" / "gen_0001").mkdir()
    (source / "generations" / "gen_0001" / "metrics.json").write_text('{"g": 1}')
    (source / "population" / "slot_0.pt").unlink()  # population/ rewritten whole
    (source / "population" / "slot_1.pt").write_bytes(b"one")
    (source / "learner.json").write_text('{"generation": 1}')
    assert sync() == 3
    assert files(target) == files(source)
    assert not list((target / "generations").glob(".tmp*"))

    copy = tmp_path / "copy"
    unpack(pack(source), copy)
    assert files(copy) == files(source)


@pytest.mark.parametrize("filters", [True, False], ids=["filters", "python-3.11.2"])
def test_unpack_writes_plain_files_and_refuses_a_path_out_of_its_root(
    tmp_path, monkeypatch, filters
):
    """With tarfile's extraction filters (Python >= 3.11.4) or without them (3.11.2, where
    `filter=` is a TypeError): the packed files come back, a member aimed outside is refused."""
    import io
    import tarfile

    from hola_ray.experiment.mirror import pack, unpack

    if not filters:
        monkeypatch.delattr(tarfile, "data_filter", raising=False)
    source = tmp_path / "source"
    (source / "gen_0000").mkdir(parents=True)
    (source / "gen_0000" / "state.json").write_text("{}")
    (source / "learner.pt").write_bytes(b"weights")
    unpack(pack(source), tmp_path / "copy")
    assert files(tmp_path / "copy") == files(source)

    evil = io.BytesIO()
    with tarfile.open(fileobj=evil, mode="w:gz") as tar:
        info = tarfile.TarInfo("../outside.txt")
        info.size = 3
        tar.addfile(info, io.BytesIO(b"bad"))
    with pytest.raises(tarfile.TarError):
        unpack(evil.getvalue(), tmp_path / "copy2")
    assert not (tmp_path / "outside.txt").exists()


def test_a_partial_trial_on_a_node_without_the_directory_resumes_and_mirrors_it(
    tmp_path, smoke_run
):
    """The driver's copy of a trial cut short after generation 0 is shipped to the trial,
    which trains in its node's staging folder and mirrors every file back."""
    import shutil
    import tempfile

    from hola_ray.experiment import trial_state
    from hola_ray.policies.learned import MLPPolicy
    from hola_ray.population.rundir import RunDir

    exp = experiment(tmp_path, env_runners=0, methods=("hola",))
    runner = Runner(exp, tmp_path / "out", poll_s=0.5)
    lines: list[str] = []
    runner.say = lines.append
    runner.mirror = True  # as on a node that does not see DIR
    trial = runner.trial_dir("hola-s0")
    shutil.copytree(smoke_run[0], trial, ignore=shutil.ignore_patterns(".lock", "gen_0001"))
    for name in ("learner.pt", "learner.json", "best.pt", "best.json"):
        (trial / name).unlink()
    assert trial_state(trial, 1) == ("partial", 0)

    runner.train()
    assert any(
        line.startswith("hola-s0: done in") and "(mirrored to the driver's node)" in line
        for line in lines
    ), lines
    assert trial_state(trial, 1) == ("done", 1)
    r = RunDir(trial)
    assert r.completed() == [0, 1] and r.learner_generation() == 1 and r.best_generation() == 1
    assert [row["generation"] for row in r.metrics_rows()] == [0, 1]
    assert (trial / "population" / "members.json").is_file()
    assert MLPPolicy.load(trial / "learner.pt").config.n_pursuers == 3
    staging = Path(tempfile.gettempdir()) / "hola_ray-trials" / runner.token() / "hola-s0"
    assert not staging.exists()  # removed once all of it was mirrored


# ---- a node lost mid-experiment -----------------------------------------------------------
LOST_GENERATIONS = 2


def lost_experiment(tmp_path: Path) -> Experiment:
    """Two self-play trials (no pre-training: each is past generation 1 soon)."""
    config = {
        "base": str(ROOT / "configs" / "smoke.yaml"),
        "overrides": {"generations": LOST_GENERATIONS},
        "methods": {"sp": {}},
        "seeds": [0, 1],
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


def alive(class_name: str) -> list[str]:
    """The nodes (ids) of `class_name`'s live actors, from the GCS's actor table (the state
    API would ask the head's dashboard, which this module's cluster does not start)."""
    from ray._private import state

    return [
        actor["Address"]["NodeID"]
        for actor in state.actors().values()
        if actor["ActorClassName"] == class_name and actor["State"] == "ALIVE"
    ]


class HalfMirrored(Runner):
    """Seed 0's trial in place, seed 1's mirrored to the driver's node."""

    def mirror_of(self, trial: str) -> bool | None:
        return trial.endswith("-s1")


def test_a_worker_node_lost_mid_experiment_loses_nothing(two_nodes, tmp_path):
    """Once a trial of a smoke experiment is past generation 1, every worker node its
    trials run on is removed (processes and all; as many nodes joined meanwhile). The Runner
    resubmits each lost trial with a fresh pack of its folder, it resumes on a live node
    after its last complete generation, and the experiment ends with every trial in
    results.json: one trial in place (a filesystem every node sees), the other mirrored to
    the driver's node (one it does not). No completed generation is rewritten; no actor is
    left."""
    cluster = two_nodes
    runner = HalfMirrored(lost_experiment(tmp_path), tmp_path / "out", poll_s=0.2)
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
    spare = [cluster.add_node(num_cpus=2) for _ in range(2)]  # while the trials start
    cluster.wait_for_nodes()
    dirs = [runner.trial_dir(t) for t in runner.exp.trials()]
    # a trial past generation 1 and still running: lose every node a trial runs on (a
    # trial's coordinator lives on its node). Both conditions at one poll: on a fast machine
    # a trial has finished generation 2 by the time a later look for its coordinator asks
    hosts: set[str] = set()

    def past_one() -> bool:
        hosts.clear()
        if any(1 in RunDir(d).completed() for d in dirs):
            hosts.update(alive("Coordinator"))
        return bool(hosts) or not thread.is_alive()

    wait_until(past_one, "a trial past generation 1 with its coordinator alive")
    before = stamps(dirs)
    doomed = [n for n in [*cluster.worker_nodes] if n.node_id in hosts]
    assert doomed and len(doomed) <= len(spare), (hosts, outcome, lines)  # two 2-CPU workers stay
    for node in doomed:
        cluster.remove_node(node)

    thread.join(timeout=300)
    assert not thread.is_alive(), lines
    [results] = outcome
    assert isinstance(results, dict), f"{results!r}\n" + "\n".join(lines)
    lost = [line for line in lines if "lost with its node" in line and "resubmitted" in line]
    assert lost, lines
    assert not any("FAILED" in line for line in lines), lines
    done = {line.split(":")[0]: line for line in lines if ": done in" in line}
    assert "in place" in done["sp-s0"] and "mirrored" in done["sp-s1"], done
    assert set(results["trials"]) == set(runner.exp.trials())
    for d in dirs:
        run = RunDir(d)
        assert run.completed() == list(range(1, LOST_GENERATIONS + 1)), d  # no generation 0
        assert [r["generation"] for r in run.metrics_rows()] == run.completed()
        assert not list((d / "generations").glob(".tmp*"))
    after = stamps(dirs)
    assert {f: after[f] for f in before} == before  # no completed generation rewritten
    assert not alive("Coordinator") and not alive("Mirror")
