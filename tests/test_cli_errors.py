"""Every command's bad input is one line on stderr and exit code 2, never a traceback:
replay, Table II and the pools (the evaluation's own: tests/evaluation/test_evaluate.py)."""

from __future__ import annotations

import json
import shutil

import pytest
import torch

from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.pools import POOLS_DIR
from hola_ray.policies.learned import random_export


def one_line(capsys, message: str) -> None:
    err = capsys.readouterr().err.strip()
    assert message in err, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err


@pytest.fixture()
def truncated(tmp_path):
    path = tmp_path / "cut.pt"
    torch.save(random_export(PursuitConfig().obs_dim, hidden=(8,)), path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 3])
    return path


@pytest.mark.parametrize(
    ("team", "message"),
    [
        (["runs/nowhere/learner.pt"], "no such file or directory"),
        (["nobody"], "unknown policy 'nobody'"),
        (["greedy", "vicsek"], "--team needs 1 or 3 names, got 2"),
        (["truncated"], "not a torch export"),
    ],
)
def test_replay_bad_inputs(tmp_path, capsys, truncated, team, message):
    from hola_ray.commands.replay import main

    team = [str(truncated) if t == "truncated" else t for t in team]
    assert main(["--team", *team, "--out", str(tmp_path / "r")]) == 2
    one_line(capsys, message)


def test_replay_refuses_another_scenario_for_a_learner_in_one_line(tmp_path, capsys):
    from hola_ray.commands.replay import main

    one = PursuitConfig(n_evaders=1)
    path = tmp_path / "one.pt"
    torch.save(random_export(one.obs_dim, hidden=(8,)) | {"scenario": one.to_dict()}, path)
    assert main(["--team", str(path), "--evaders", "2", "--out", str(tmp_path / "r")]) == 2
    one_line(capsys, "was trained for 3 pursuers vs 1 evader(s); this scenario has 3 vs 2")


def test_table_ii_bad_input(capsys):
    from hola_ray.evaluation.table import main

    assert main(["--episodes", "0"]) == 2
    one_line(capsys, "--episodes must be at least 1")


def test_pools_bad_inputs(tmp_path, capsys):
    from hola_ray.commands.pools import main

    assert main(["show", "--pool", "nope"]) == 2
    one_line(capsys, "unknown pool 'nope'")
    broken = tmp_path / "broken"
    shutil.copytree(POOLS_DIR / "het", broken)
    (broken / "manifest.json").write_text("{ not json")
    assert main(["show", "--pool", str(broken)]) == 2
    one_line(capsys, "not valid JSON")
    shutil.rmtree(broken)
    shutil.copytree(POOLS_DIR / "het", broken)
    manifest = json.loads((broken / "manifest.json").read_text())
    (broken / "d3qn-g-1.pt").write_bytes(b"\0" * 64)  # changed after the build
    assert main(["show", "--pool", str(broken)]) == 2
    one_line(capsys, "the file changed after the build")
    # a file that matches its manifest but is no torch export
    (broken / "d3qn-g-1.pt").write_text("not torch")
    from hola_ray.homes import sha256

    manifest["members"]["d3qn-g-1"]["sha256"] = sha256(broken / "d3qn-g-1.pt")
    (broken / "manifest.json").write_text(json.dumps(manifest))
    from hola_ray.commands.evaluate import main as evaluate

    learner = tmp_path / "mine.pt"
    torch.save(random_export(PursuitConfig().obs_dim, hidden=(8,)), learner)
    assert evaluate([str(learner), "--pool", str(broken)]) == 2
    one_line(capsys, "member d3qn-g-1")


@pytest.mark.parametrize("command", ["run", "experiment"])
def test_an_out_that_cannot_be_created_is_one_line_naming_it(tmp_path, capsys, command):
    """`--out` through a regular file: refused before Ray starts, naming the path."""
    import importlib

    blocker = tmp_path / "a-file"
    blocker.write_text("")
    out = blocker / "run"
    argv = ["--out", str(out)]
    if command == "experiment":
        argv += ["--config", str(POOLS_DIR.parent / "configs" / "experiments" / "smoke.yaml")]
    module = {"run": "hola_ray.commands.run", "experiment": "hola_ray.experiment"}[command]
    assert importlib.import_module(module).main(argv) == 2
    one_line(capsys, f"--out {out} cannot be created: Not a directory")


@pytest.mark.parametrize("command", ["run", "experiment"])
def test_a_bad_or_taken_metrics_port_is_one_line_before_ray_starts(
    tmp_path, capsys, monkeypatch, command
):
    """Out of range, or held by another process: one line, before Ray starts (Ray would
    wait about 30 s for its metrics agent and end in a traceback)."""
    import socket

    from hola_ray.commands.run import main as run
    from hola_ray.experiment.command import main as experiment
    from hola_ray.homes import ROOT

    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    main, args = {
        "run": (run, ["--out", str(tmp_path / "run")]),
        "experiment": (
            experiment,
            [
                "--config",
                str(ROOT / "configs/experiments/smoke.yaml"),
                "--out",
                str(tmp_path / "e"),
            ],
        ),
    }[command]
    with pytest.raises(SystemExit) as ended:
        main([*args, "--metrics-port", "99999"])
    assert ended.value.code == 2
    one_line(capsys, "argument --metrics-port: a port is in 1–65535, not 99999")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as held:
        held.bind(("127.0.0.1", 0))
        held.listen()
        taken = held.getsockname()[1]
        assert main([*args, "--metrics-port", str(taken)]) == 2
    one_line(capsys, f"--metrics-port {taken}: Address already in use; choose a free port")
    import ray

    assert not ray.is_initialized()
