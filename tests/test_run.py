"""The main job and the replay command run end to end on small settings."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from hola_ray import replay, run
from hola_ray.env import ConfigError, PursuitConfig

ROOT = Path(__file__).resolve().parent.parent


def test_default_yaml_is_the_embedded_default():
    env, demo = run.load(ROOT / "configs" / "default.yaml")
    assert env == PursuitConfig() and demo == run.DemoConfig()


def test_run_demo_writes_replay_and_metrics(tmp_path, capsys):
    config = tmp_path / "small.yaml"
    config.write_text(
        yaml.safe_dump(
            {
                "env": {"horizon": 200},
                "demo": {"teams": [["vicsek", "greedy", "apf-a-3"]], "episodes": 8},
            }
        )
    )
    run.main(["--config", str(config), "--out", str(tmp_path / "out")])
    printed = capsys.readouterr().out
    assert "vicsek + greedy + apf-a-3" in printed and "success" in printed
    for name in ("replay.gif", "trajectory.png", "config.yaml"):
        assert (tmp_path / "out" / name).stat().st_size > 0


def test_run_rejects_bad_config_before_work(tmp_path):
    config = tmp_path / "bad.yaml"
    config.write_text(yaml.safe_dump({"demo": {"teams": [["vicsek", "vicsek"]]}}))
    with pytest.raises(ConfigError, match=r"demo.teams\[0\] must name 3"):
        run.main(["--config", str(config), "--out", str(tmp_path / "never")])
    assert not (tmp_path / "never").exists()
    config.write_text(yaml.safe_dump({"trainer": {}}))
    with pytest.raises(ConfigError, match="unknown top-level"):
        run.load(config)


def test_replay_writes_gif_and_png(tmp_path, capsys):
    replay.main(["--team", "vicsek", "--seed", "2", "--evaders", "1", "--out", str(tmp_path)])
    assert "wrote" in capsys.readouterr().out
    assert len(list(tmp_path.glob("*.gif"))) == 1 and len(list(tmp_path.glob("*.png"))) == 1
