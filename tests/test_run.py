"""The main job end to end: smoke run, SIGKILL and --resume, status, bad configs."""

from __future__ import annotations

import hashlib
import json
import math
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import ray
import torch
import yaml

from hola_ray.commands import run, status
from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.rollout import rollout
from hola_ray.methods.config import RunConfig
from hola_ray.policies.learned import MLPPolicy
from hola_ray.population.lock import RunLock
from hola_ray.population.rundir import MONITORS, RunDir

ROOT = Path(__file__).resolve().parent.parent
SMOKE = ROOT / "configs" / "smoke.yaml"


RECORDED = ROOT / "tests" / "data" / "smoke-metrics.json"
"""the smoke run's metrics as an earlier build of the package wrote them (its `what`)"""

COUNTS = ("env_steps", "pretrain_env_steps", "grapher_edges", "population_size", "monitored")
"""fields set by the config and the budget alone, not by the learned policies' play"""


def test_the_same_seed_gives_the_same_metrics_as_the_recorded_build(smoke_run):
    """The smoke config's seed gives the metrics an earlier build recorded: every field,
    wall times aside, where torch computes as it did there (the same build and CPU
    capability), and the fields the config and budget set wherever it runs. Redesigns keep
    behaviour.

    Where torch matches, counts and whole numbers match exactly and other floats to
    FLOAT_DIGITS: the CPU beyond its capability still sets the last digits (on a Sapphire
    Rapids Xeon, AVX512 like the recording machine, the learner's return and φ's entropy
    differ by 2e-8 relative, every other field equal, and no MKL branch (`MKL_CBWR`)
    reproduces the recorded digits). Elsewhere float rounding may differ and play diverges."""
    recorded = json.loads(RECORDED.read_text())
    assert smoke_run[1].returncode == 0, smoke_run[1].stderr[-3000:]
    rows = RunDir(smoke_run[0]).metrics_rows()
    assert len(rows) == len(recorded["rows"])
    same_torch = (torch.__version__, torch.backends.cpu.get_cpu_capability()) == (
        recorded["torch"],
        recorded["cpu_capability"],
    )
    for got, then in zip(rows, recorded["rows"], strict=True):
        fields = then if same_torch else {k: then[k] for k in COUNTS if k in then}
        for field, value in fields.items():
            now = got.get(field)
            assert _same_figure(now, value), (field, now, value)


FLOAT_DIGITS = 1e-6
"""the relative difference a float of the recorded run may show where torch matches"""


def _same_figure(now, then) -> bool:
    """Equal (NaN as NaN), or both floats, `then` not a whole number, within FLOAT_DIGITS."""
    if now == then or (now != now and then != then):
        return True
    fractional = isinstance(now, float) and isinstance(then, float) and not then.is_integer()
    return fractional and math.isclose(now, then, rel_tol=FLOAT_DIGITS)


def test_smoke_run_writes_the_whole_run_directory(smoke_run, tmp_path):
    out, done = smoke_run
    assert done.returncode == 0, done.stderr[-3000:]
    assert "gen 1: learner success" in done.stdout
    r = RunDir(out)
    assert r.completed() == [0, 1]
    for g in (0, 1):
        for name in ("state.json", "hyfog.json", "phi.json", "eta.json", "metrics.json"):
            assert (r.generation(g) / name).is_file()
    assert (r.generation(1) / "learner.rllib.pt").is_file()
    assert len(list(r.members.glob("node_*.pt"))) >= 6  # export + RLlib state per member
    # TensorBoard (installed with the project) reads the run's event files
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(r.tensorboard))
    events.Reload()
    tags = events.Tags()["scalars"]
    assert "learner_success" in tags and "iteration/std_median" in tags
    assert [e.step for e in events.Scalars("learner_success")] == [1]
    rows = r.metrics_rows()
    assert [row["generation"] for row in rows] == [0, 1]
    assert rows[1]["env_steps"] >= 2000 and 0.0 <= rows[1]["learner_success"] <= 1.0
    # the learner's own transitions and gradient steps, beside the env steps
    assert 0 < rows[1]["learner_samples"] <= rows[1]["env_steps"]
    assert rows[1]["gradient_steps"] >= 2 and rows[1]["wall_s"] > 0
    # hola's φ against hola_r's on the same hypergraph: G_0 is every l-set (regular), so the
    # two are one draw, and the run says so
    assert rows[1]["phi_tv"] == 0.0 and "phi_tv" not in rows[0]
    # and against uniform draws: a distance, on the rows that trained with a φ
    assert 0.0 <= rows[1]["phi_tv_uniform"] <= 1.0 and "phi_tv_uniform" not in rows[0]
    assert "φ never departed from mean_reward's by more than 0.01" in done.stdout
    # the validation teammates judged generation 1, and best.pt was chosen on them
    assert 0.0 <= rows[1]["val_success"] <= 1.0 and 0.0 <= rows[1]["val_learner_crash"] <= 1.0
    best = json.loads((out / "best.json").read_text())
    assert best["judged_by"].startswith("highest val_")
    # the commit that trained it, as best.pt holds it
    assert best["commit"] == torch.load(out / "best.pt", weights_only=True)["commit"]
    # the population measured as a team, every generation: each member with copies of
    # itself, and teams drawn from it
    for row in rows:
        for key in ("members_success", "members_crash", "population_team_success"):
            assert 0.0 <= row[key] <= 1.0, key
        assert row["members_success_min"] <= row["members_success"]
    assert "members_success" in tags and "val_success" in tags
    # The exported learner plays without Ray or RLlib.
    config = PursuitConfig.from_yaml(SMOKE)
    learner = MLPPolicy.load(config, r.learner)
    result = rollout(config, [learner] * 3, episodes=4)
    assert result.episodes == 4
    # Member checkpoints load the same way.
    MLPPolicy.load(config, r.member_export(0))
    # The final learner and the accepted population are kept apart and named.

    info = json.loads((out / "learner.json").read_text())
    state = json.loads((r.generation(1) / "state.json").read_text())
    assert info["generation"] == 1 and info["in_population"] == state["decision"]["accepted"]
    members = json.loads((r.population / "members.json").read_text())
    slots = {str(v): k for k, v in state["population"]["slots"].items()}
    assert members["generation"] == 1
    assert {s: m["node"] for s, m in members["members"].items()} == {
        s: int(n) for s, n in slots.items()
    }
    for m in members["members"].values():
        assert (r.population / m["file"]).read_bytes() == r.member_export(m["node"]).read_bytes()
    assert MLPPolicy.load(r.learner).config.horizon == 200  # the export's own scenario
    # what the reproducibility check compares sees a changed figure (and not a wall time)
    import shutil

    from hola_ray.population.rundir import metrics_differences

    twin = tmp_path / "twin"  # a copy of the shared run, never beside it
    shutil.copytree(out, twin)
    row = json.loads((twin / "generations" / "gen_0001" / "metrics.json").read_text())
    row["oracle_s"] += 1.0
    (twin / "generations" / "gen_0001" / "metrics.json").write_text(json.dumps(row))
    assert metrics_differences(out, twin) == {}
    row["learner_return"] += 0.5
    (twin / "generations" / "gen_0001" / "metrics.json").write_text(json.dumps(row))
    assert set(metrics_differences(out, twin)[1]) == {"learner_return"}
    # The status command reads it.
    assert status.main([str(out), "--plot"]) == 0
    assert (out / "progress.png").stat().st_size > 0
    # Per-iteration health of what was trained: the pre-trained members and the learner.
    its = r.iteration_rows()
    assert {row["generation"] for row in its} == {0, 1}
    assert all(0 < row["std_median"] <= 1 / 3**0.5 + 1e-6 for row in its)  # a Beta's bound
    assert r.iterations_csv.is_file() and "std_median" in rows[1] and "clipped" in rows[1]


def test_a_run_killed_between_its_last_generation_and_learner_pt_is_not_done(smoke_run, tmp_path):
    """A kill after generation g's folder is committed but before learner.pt, learner.json
    and best.* are written: the run is not finished, the experiment's trial is not done,
    and resuming writes the same files again from the generation folders."""
    import json
    import shutil

    from hola_ray.experiment import trial_state
    from hola_ray.methods.config import RunConfig
    from hola_ray.methods.trainer import Trainer

    out = tmp_path / "killed"
    shutil.copytree(smoke_run[0], out, ignore=shutil.ignore_patterns(".lock"))
    kept = {n: (out / n).read_bytes() for n in ("learner.json", "best.json")}
    weights = torch.load(out / "learner.pt", weights_only=True)
    config = RunConfig.from_yaml(out / "config.yaml")
    assert trial_state(out, 1) == ("done", 1) and run.finished(out, config)
    for name in ("learner.pt", "learner.json", "best.pt", "best.json"):
        (out / name).unlink()
    assert trial_state(out, 1) == ("partial", 1)
    assert not run.finished(out, config)

    said: list[str] = []
    trainer = Trainer(config, out, progress=False)
    trainer.say = said.append
    trainer._catch_up(1)
    assert said == [
        "best.pt written again from generation 1",
        "learner.pt written again from generation 1",
    ]
    assert {n: (out / n).read_bytes() for n in kept} == kept
    for path in (out / "learner.pt", out / "best.pt"):
        again = torch.load(path, weights_only=True)
        assert json.dumps(again["scenario"]) == json.dumps(weights["scenario"])
        for key, value in weights.items():
            if isinstance(value, torch.Tensor):
                assert torch.equal(again[key], value), key
    assert trial_state(out, 1) == ("done", 1)
    trainer._catch_up(1)  # nothing left to write
    assert len(said) == 2


def test_a_generation_folder_plays_as_that_generations_learner(smoke_run, tmp_path):
    """`RUN/generations/gen_0001` loads (evaluate, replay) as generation 1's learner: the
    export kept in the folder equals learner.pt and the one made from its RLlib state with
    the run's config, so the folder plays on its own, copied anywhere."""
    import shutil

    from hola_ray.policies.registry import load_export, load_policy

    out = smoke_run[0]
    final = torch.load(out / "learner.pt", weights_only=True)
    again = load_export(out / "generations" / "gen_0001")
    assert again["scenario"] == final["scenario"]
    for w1, w2 in zip(again["weights"], final["weights"], strict=True):
        assert torch.equal(w1, w2)
    env = PursuitConfig.from_yaml(SMOKE)
    state = torch.load(out / "generations" / "gen_0001" / "learner.rllib.pt", weights_only=False)
    made = RunConfig.from_yaml(out / "config.yaml").export(state)
    for w1, w2 in zip(again["weights"], made["weights"], strict=True):
        assert torch.equal(w1, w2)
    assert load_policy(out / "generations" / "gen_0001", env).name == f"{out.name}-gen_0001"
    lone = tmp_path / "gen_0001"
    shutil.copytree(out / "generations" / "gen_0001", lone)
    assert load_export(lone)["scenario"] == final["scenario"]
    (lone / "learner.pt").unlink()  # as a folder written before generations kept exports
    with pytest.raises(ValueError, match="written before generations kept their export"):
        load_export(lone)
    with pytest.raises(ValueError, match="neither a run directory with learner.pt"):
        load_export(out / "generations" / "gen_0000")  # pre-training: no learner


def test_best_of_completed_is_what_keep_best_kept_generation_by_generation(tmp_path):
    r = RunDir(tmp_path)
    r.create("{}")
    scores = {1: (0.2, 0.9), 2: (0.5, 0.8), 3: (0.5, 0.4), 4: (0.5, 0.4), 5: (0.1, 0.0)}
    r.write_generation(0, {"metrics.json": {}}, None)
    for g, (success, collision) in scores.items():
        row = {"learner_success": success, "learner_collision": collision, "learner_length": 9.0}
        r.write_generation(g, {"metrics.json": row}, {"w": torch.zeros(1)})
        r.keep_best(g, row, {"g": g})
    assert r.best_generation() == 3  # more success, then less collision, the earlier of ties
    assert r.best_of_completed() == 3


def _digest(run_dir: RunDir, g: int) -> str:
    """Generation g's folder as committed (its monitors may be written after it)."""
    h = hashlib.sha256()
    for p in sorted(run_dir.generation(g).iterdir()):
        if p.name != MONITORS:
            h.update(p.name.encode() + p.read_bytes())
    return h.hexdigest()


def interrupted_run(commands, folder: Path) -> dict:
    """The commands of the test below: a run killed
    by SIGKILL once it said generation 1 was saved, resumed and interrupted by Ctrl-C
    while it trains generation 2, resumed to its end, then resumed once more. What each
    said and left on disk on the way."""
    config = yaml.safe_load(SMOKE.read_text())
    config["generations"] = 2
    config["oracle"]["env_steps"] = 2000
    path = folder / "resume.yaml"
    path.write_text(yaml.safe_dump(config))
    out = folder / "run"
    r = RunDir(out)
    seen: dict = {"out": out}

    def start(*args: str) -> subprocess.Popen:
        cmd = [sys.executable, "-m", "hola_ray.run", *args, "--no-dashboard", "--quiet"]
        pipes = {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE, "text": True}
        return commands.popen(cmd, **pipes)

    def wait_for(driver: subprocess.Popen, start: str) -> bool:
        """Read the driver's lines until one starts with `start` (True), or its end: an
        event, not a guess at how long it takes."""
        for line in driver.stdout:
            seen.setdefault("said", []).append(line)
            if line.startswith(start):
                return True
        return False

    driver = start("--config", str(path), "--out", str(out))
    seen["gen 1 said"] = wait_for(driver, "gen 1:")  # once generation 1's files are written
    seen["then saved"] = r.completed()
    os.killpg(driver.pid, signal.SIGKILL)  # the driver and the local Ray it started
    driver.communicate()
    seen["killed"] = r.completed()
    seen["digests"] = {g: _digest(r, g) for g in seen["killed"]}

    driver = start("--resume", str(out))
    seen["resuming said"] = wait_for(driver, "resuming after generation 1")  # trains gen 2
    os.killpg(driver.pid, signal.SIGINT)  # what Ctrl-C in a terminal does
    _, err = driver.communicate(timeout=120)
    seen["interrupted"] = (driver.returncode, err, r.completed())

    for step in ("resumed", "again"):
        done = start("--resume", str(out))
        stdout, stderr = done.communicate(timeout=300)
        seen[step] = subprocess.CompletedProcess(done.args, done.returncode, stdout, stderr)
    return seen


@pytest.mark.e2e
@pytest.mark.timeout(600)
def test_sigkill_then_ctrl_c_then_resume_loses_nothing(commands, tmp_path):
    """SIGKILL after generation 1 (nothing gets to clean up), a resume interrupted by
    Ctrl-C while it trains generation 2 (one line, exit 130), a last resume: every
    completed generation kept untouched, the run finished; then it says so, and
    --generations N extends it. (Its commands: `interrupted_run`.)"""
    seen = interrupted_run(commands, tmp_path)
    out = seen["out"]
    r = RunDir(out)
    said = "".join(seen.get("said", []))[-2000:]
    assert seen["gen 1 said"] and 1 in seen["then saved"], said
    assert seen["killed"] == [0, 1], seen["killed"]

    assert seen["resuming said"], said
    code, err, saved = seen["interrupted"]
    assert code == 130, err[-3000:]
    assert saved == [0, 1]  # generation 2 was in progress
    lines = [line for line in err.splitlines() if line.startswith("interrupted:")]
    assert lines == [
        f"interrupted: generations 0–1 are saved in {out}; continue with: "
        f"python -m hola_ray.run --resume {out}"
    ]
    assert "Traceback" not in err

    done = seen["resumed"]
    assert done.returncode == 0, done.stderr[-3000:]
    assert "resuming after generation 1" in done.stdout
    assert r.completed() == [0, 1, 2]
    digests = seen["digests"]
    assert {g: _digest(r, g) for g in digests} == digests  # completed ones untouched
    assert all(r.monitored(g) for g in r.completed())  # and their monitors written
    assert [row["generation"] for row in r.metrics_rows()] == [0, 1, 2]
    lines = r.metrics_csv.read_text().strip().splitlines()
    assert len(lines) == 1 + 3  # header + one row per generation
    steps = [row["env_steps"] for row in r.metrics_rows()]
    assert steps == sorted(steps) and steps[-1] >= 2 * 2000
    lock = RunLock(out)
    assert lock.acquire() is None  # released, no stale holder left behind
    lock.release()

    # a finished run says so (before Ray starts); --generations N extends it
    again = seen["again"]
    assert again.returncode == 0 and f"{out} is finished: generation 2 of 2" in again.stdout
    assert "Ray" not in again.stdout
    config_more, out_more = run.resolve(
        run.parse_args(["--resume", str(out), "--generations", "4"])
    )
    assert out_more == out and config_more.generations == 4
    assert not run.finished(out, config_more)  # so main trains generations 3 and 4


@pytest.mark.parametrize(
    ("patch", "field"),
    [
        ({"method": "sp2"}, "method"),
        ({"population": {"max_size": 2}}, "population.max_size"),
        ({"oracle": {"env_steps": -1}}, "oracle.env_steps"),
        ({"oracle": {"action_dist": "normal"}}, "oracle.action_dist"),
        ({"oracle": {"sampler": "fast"}}, "oracle.sampler"),
        ({"oracle": {"update": "fast"}}, "oracle.update"),
        ({"oracle": {"lr_decay_env_steps": -5}}, "oracle.lr_decay_env_steps"),
        ({"oracle": {"lr_final": 2.0}}, "oracle.lr_final"),
        ({"oracle": {"gpus_per_learner": -1}}, "oracle.gpus_per_learner"),
        ({"env": {"reward": {"collision": -10}}}, "reward.collision"),
        ({"env": {"reward": {"teammate_distance": 0}}}, "reward.teammate_distance"),
        ({"env": {"reward": {"capture": "10"}}}, "reward.capture"),
        ({"env": {"reward": {"bonus": 1}}}, "reward.bonus"),
    ],
)
def test_bad_config_fails_before_ray_starts(tmp_path, capsys, patch, field):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(patch))
    assert run.main(["--config", str(path), "--out", str(tmp_path / "never")]) == 2
    assert field in capsys.readouterr().err
    assert not ray.is_initialized() and not (tmp_path / "never").exists()


def test_a_fresh_run_refuses_a_used_run_directory(tmp_path, capsys):
    r = RunDir(tmp_path / "used")
    r.create("method: hola\n")
    r.write_generation(0, {"metrics.json": {"generation": 0}}, None)
    assert run.main(["--config", str(SMOKE), "--out", str(r.root)]) == 2
    assert "--resume" in capsys.readouterr().err
    assert run.main(["--resume", str(tmp_path / "nothing")]) == 2
    assert not ray.is_initialized()


def blocked_write(commands, folder: Path, smoke: Path) -> tuple[Path, subprocess.CompletedProcess]:
    """The command of the test below: the smoke run,
    copied, with metrics.csv blocked by a folder of that name, resumed for a second
    generation."""
    import shutil

    out = folder / "blocked"
    shutil.copytree(smoke, out, ignore=shutil.ignore_patterns(".lock"))
    config = yaml.safe_load((out / "config.yaml").read_text())
    config["grapher"]["workers"] = 0  # no member actors to start: not what this is about
    (out / "config.yaml").write_text(yaml.safe_dump(config))
    (out / "metrics.csv").unlink()
    (out / "metrics.csv").mkdir()
    (out / "metrics.csv" / "keep").write_text("")
    cmd = [sys.executable, "-m", "hola_ray.run", "--resume", str(out), "--generations", "2"]
    cmd += ["--no-dashboard", "--quiet"]
    done = commands.popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stdout, stderr = done.communicate(timeout=300)
    return out, subprocess.CompletedProcess(cmd, done.returncode, stdout, stderr)


@pytest.mark.e2e
@pytest.mark.timeout(300)
def test_a_write_that_fails_during_a_generation_is_one_line_and_generations_stay_whole(
    smoke_run, commands, tmp_path
):
    """metrics.csv blocked by a folder of that name (a write no permission can bypass):
    resuming for a second generation ends with one line naming the file and exit code 1,
    and every generation on disk is whole and loads (what --resume starts from). (Its
    command: `blocked_write`, on a copy of `smoke_run`.)"""
    out, done = blocked_write(commands, tmp_path, smoke_run[0])
    err = done.stderr.strip().splitlines()
    assert done.returncode == 1, done.stderr[-2000:]
    assert err[-1].startswith(f"error: writing {out / 'metrics.csv'} failed (Is a directory)")
    assert "Traceback" not in done.stderr
    r = RunDir(out)
    assert r.completed() in ([0, 1], [0, 1, 2])
    for g in r.completed()[1:]:
        assert r.load_learner_state(g) and (r.generation(g) / "metrics.json").is_file()


def test_reading_a_run_config_imports_no_rllib():
    """`hola_ray.run` validates its config before Ray starts and imports RLlib while Ray
    starts (`process.init_ray_importing`): the config's modules must not import RLlib, nor
    must the evaluation actors' monitors (they would pay for it in every actor)."""
    import subprocess
    import sys

    script = (
        "import sys\n"
        "import hola_ray.commands.run, hola_ray.methods.config, hola_ray.methods.monitors\n"
        "from hola_ray.methods.config import RunConfig\n"
        "RunConfig.from_dict(hola_ray.commands.run.DEFAULT)\n"
        "heavy = ('ray.rllib', 'hola_ray.oracle.trainer')\n"
        "print(sorted(m for m in sys.modules if m.startswith(heavy)))\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[]"
