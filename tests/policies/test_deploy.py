"""ONNX export: onnxruntime plays exactly `MLPPolicy.act`, and the manifest says what a
flight stack needs (observation entries, action, period, scenario, provenance, hash)."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hola_ray.commands.export import resolve
from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.pools import load_pool
from hola_ray.evaluation.probe import reference_observations
from hola_ray.policies.deploy import OnnxPolicy, export_onnx, manifest, onnx_actions, write_manifest
from hola_ray.policies.learned import MLPPolicy

ROOT = Path(__file__).resolve().parents[2]


def played(policy: MLPPolicy, episodes: int = 12) -> np.ndarray:
    """Observations of the policy's own episodes, as the whole team, every step."""
    team = [policy] * policy.config.n_pursuers
    return reference_observations(policy.config, episodes, every=1, seed=5, team=team)


def test_a_pool_ppo_member_exports_to_onnx_that_acts_as_the_torch_policy(tmp_path):
    policy, source = resolve("ppo-1")
    assert policy.feature_indices  # its proximity features are computed inside the graph
    path = export_onnx(policy, tmp_path / "ppo-1.onnx")
    obs = played(policy)
    assert obs.shape[0] > 3000
    action, turn = onnx_actions(path, obs)
    np.testing.assert_allclose(action, policy.act(obs), atol=1e-5, rtol=0)
    np.testing.assert_allclose(turn, (2 * action - 1) * policy.config.max_turn, atol=1e-6)
    assert action.min() < 0.3 and action.max() > 0.7  # it really turns both ways
    # the same member, loaded as the evaluation loads it, plays the same actions
    config = policy.config
    member = load_pool("hot", config)["ppo-1"]
    np.testing.assert_allclose(member.act(obs[:500]), action[:500], atol=1e-5, rtol=0)
    assert source["pool"] == "hot" and len(source["commit"]) >= 40


def test_the_manifest_describes_every_observation_entry_and_the_action(tmp_path):
    policy, source = resolve("ppo-1")
    path = export_onnx(policy, tmp_path / "a.onnx")
    data = manifest(policy, path, source)
    write_manifest(tmp_path / "a.json", data)
    layout = policy.config.layout
    entries = data["observation"]
    assert [e["index"] for e in entries] == list(range(layout.dim))
    assert entries[layout.obstacle]["name"] == "obstacle.distance"
    assert entries[layout.own]["name"] == "own.x"
    assert all({"measures", "frame", "units", "scale", "unobserved"} <= set(e) for e in entries)
    assert data["action"]["max_turn_rad"] == policy.config.max_turn
    assert data["action"]["speed_m_s"] == policy.config.pursuer_speed
    assert data["control_period_s"] == policy.config.dt
    assert data["onnx"]["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert data["scenario"]["n_evaders"] == 2
    # the teams it plays: any its slots hold; the ones it was trained with
    team = data["team"]
    assert (team["pursuers"], team["evaders"], team["trained_pursuers"]) == ([1, 3], [1, 2], [3, 3])
    assert (team["trained_evaders"], team["arena"], team["team_changes"]) == (2, "paper", 0)
    assert team["arenas"] == ["paper"]
    # OnnxPolicy reads it back and refuses a file changed after the export
    obs = played(policy, 2)
    np.testing.assert_allclose(OnnxPolicy(path).act(obs), policy.act(obs), atol=1e-5, rtol=0)
    # it flies a team of 2 in its 3 slots, and refuses a scenario of other slots
    pair = PursuitConfig(n_pursuers=2, obs_pursuers=3)
    assert OnnxPolicy(path, pair).config.n_pursuers == 2
    with pytest.raises(ValueError, match="reads 3 pursuers and 2 evaders"):
        OnnxPolicy(path, PursuitConfig(n_pursuers=4))
    path.write_bytes(path.read_bytes() + b"\0")
    with pytest.raises(ValueError, match="sha256"):
        OnnxPolicy(path)


def test_the_export_command_takes_a_run_directory_and_says_where_it_came_from(smoke_run, tmp_path):
    run_dir, done = smoke_run
    assert done.returncode == 0, done.stderr[-2000:]
    out = tmp_path / "learner.onnx"
    cmd = [sys.executable, "-m", "hola_ray", "export", str(run_dir), "--onnx", str(out)]
    got = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert got.returncode == 0, got.stderr[-2000:]
    assert "largest difference" in got.stdout
    data = json.loads(out.with_suffix(".json").read_text())
    assert data["source"]["run"] == str(run_dir) and data["source"]["generation"] == 1
    assert len(data["source"]["commit"]) >= 40  # the commit that trained it
    learner = MLPPolicy.load(run_dir / "learner.pt")
    obs = played(learner, 16)
    assert obs.shape[0] > 1000
    action, _ = onnx_actions(out, obs)
    np.testing.assert_allclose(action, learner.act(obs), atol=1e-5, rtol=0)


def test_a_bad_export_request_is_one_line(tmp_path):
    cmd = [
        sys.executable,
        "-m",
        "hola_ray",
        "export",
        "d3qn-g-1",
        "--onnx",
        str(tmp_path / "x.onnx"),
    ]
    got = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert got.returncode == 2 and "only MLP learners export" in got.stderr
    assert len(got.stderr.strip().splitlines()) == 1
