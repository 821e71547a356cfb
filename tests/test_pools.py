"""Pools: a member file that changed since the build is refused, an unknown pool is one
clear error, and a member trained for two evaders plays one as if the other were caught
(tests/policies/test_adapter.py: the adapter for other teams)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.pools import (
    FORMAT as POOL_FORMAT,
)
from hola_ray.evaluation.pools import (
    MANIFEST,
    PoolError,
    load_pool,
)
from hola_ray.homes import sha256
from hola_ray.policies.adapter import ScenarioAdapter
from hola_ray.policies.learned import MLPPolicy, random_export

TWO = PursuitConfig(n_evaders=2)
ONE = dataclasses.replace(TWO, n_evaders=1)


def export(config: PursuitConfig) -> dict:
    return random_export(config.obs_dim, hidden=(8,))


@pytest.fixture()
def pool(tmp_path):
    folder = tmp_path / "mine"
    folder.mkdir()
    torch.save(export(TWO), folder / "ppo-x.pt")
    manifest = {
        "format": POOL_FORMAT,
        "pool": "mine",
        "commit": "test",
        "members": {
            "ppo-x": {
                "name": "PPO (x)",
                "kind": "ppo",
                "file": "ppo-x.pt",
                "sha256": sha256(folder / "ppo-x.pt"),
                "scenario": {"n_pursuers": 3, "n_evaders": 2},
            },
            "greedy": {"name": "Greedy", "kind": "handwritten", "file": None},
        },
    }
    (folder / MANIFEST).write_text(json.dumps(manifest))
    return folder


def test_a_verified_pool_loads_and_a_tampered_file_is_refused(pool):
    members = load_pool(pool, TWO)
    assert sorted(members) == ["greedy", "ppo-x"]
    assert isinstance(members["ppo-x"], MLPPolicy)
    data = bytearray((pool / "ppo-x.pt").read_bytes())
    data[-20] ^= 0xFF  # one flipped byte
    (pool / "ppo-x.pt").write_bytes(bytes(data))
    with pytest.raises(PoolError, match="sha256 .* the file changed after the build"):
        load_pool(pool, TWO)
    (pool / "ppo-x.pt").unlink()
    with pytest.raises(PoolError, match="is missing"):
        load_pool(pool, TWO)


def test_an_unknown_pool_is_one_clear_error(tmp_path):
    with pytest.raises(PoolError, match="unknown pool 'nope': give one of hot, het"):
        load_pool("nope", TWO)
    with pytest.raises(PoolError, match="unknown pool"):
        load_pool(tmp_path, TWO)  # a folder without a manifest


def test_a_two_evader_member_plays_one_evader_as_if_the_other_were_caught(pool):
    member = load_pool(pool, ONE)["ppo-x"]
    assert isinstance(member, ScenarioAdapter)
    reference = MLPPolicy(TWO, export(TWO))
    rng = np.random.default_rng(0)
    obs1 = rng.uniform(-1, 1, (32, ONE.obs_dim)).astype(np.float32)
    # the same observation in the two-evader layout with evader 2 reading (2, 0, 0)
    obs2 = np.concatenate([obs1[:, :3], np.tile([2.0, 0.0, 0.0], (32, 1)), obs1[:, 3:]], axis=1)
    np.testing.assert_array_equal(member.act(obs1), reference.act(obs2.astype(np.float32)))
    five = load_pool(pool, dataclasses.replace(TWO, n_pursuers=5, n_evaders=3))["ppo-x"]
    assert isinstance(five, ScenarioAdapter) and five.policy.config.n_pursuers == 3


@pytest.mark.parametrize("name", ["hot", "het", "surround"])
def test_the_committed_pools_load_and_play_their_recorded_table_ii(name):
    from hola_ray.evaluation.pools import pool_dir, read_manifest
    from hola_ray.evaluation.table import measure, table_scenario

    config = table_scenario(TWO)
    members = load_pool(name, config)  # every hash verified
    manifest = read_manifest(pool_dir(name))
    assert set(members) == set(manifest["members"])
    for mid, entry in manifest["members"].items():  # hand-written members too
        recorded = entry["table_ii"]
        episodes = recorded["episodes"] // len(recorded["seeds"])
        again = measure(members[mid], config, episodes, recorded["seeds"])
        for key, value in recorded.items():
            if key in ("episodes", "seeds"):
                continue
            if entry["kind"] == "handwritten":  # numpy arithmetic: to the manifest's digits
                assert round(again[key], 4) == value, (mid, key)
            elif not key.endswith("_se"):
                # A network's float32 sums round differently on another CPU (this one has
                # AVX-512 and AMX; ppo-1 and ppo-2 then play other episodes than the build
                # machine's): the figure within 3 of its recorded standard errors. Another
                # member in its place is far outside (ppo-1 and ppo-2 differ by 0.33).
                bound = max(3 * recorded[f"{key}_se"], 1e-4)
                assert abs(again[key] - value) <= bound, (mid, key, again[key], value)


def test_d3qn_g_trained_against_one_evader_plays_two_as_it_is():
    from hola_ray.evaluation.rollout import rollout
    from hola_ray.policies.d3qn import D3QNG

    members = load_pool("het", TWO)
    for mid in ("d3qn-g-1", "d3qn-g-2"):
        assert isinstance(members[mid], D3QNG) and members[mid].config.n_evaders == 2
        result = rollout(TWO, [members[mid]] * 3, episodes=8)
        assert result.episodes == 8
    three = dataclasses.replace(TWO, n_evaders=3)  # PPO (1), trained for 2, sees the nearest 2
    assert isinstance(load_pool("hot", three)["ppo-1"], ScenarioAdapter)


def test_no_evaluation_pool_member_can_validate_or_train(tmp_path):
    """The validation set shares no member id and no file with the evaluation pools; a
    validation folder that does is refused, and so is a run config naming an evaluation
    pool; and no module of training or selection loads a pool other than through
    `load_validation`."""
    from pathlib import Path

    from hola_ray.config.reader import ConfigError
    from hola_ray.evaluation.pools import (
        EVALUATION_POOLS,
        POOLS_DIR,
        SURROUND,
        VALIDATION,
        load_validation,
        pool_dir,
        read_manifest,
    )
    from hola_ray.methods.config import RunConfig

    held_out = {mid for ids in EVALUATION_POOLS.values() for mid in ids}
    hashes = {
        e["sha256"]
        for name in EVALUATION_POOLS
        for e in read_manifest(pool_dir(name))["members"].values()
        if e.get("sha256")
    }
    for pool in (VALIDATION, SURROUND):
        validation = read_manifest(pool_dir(pool))["members"]
        assert not set(validation) & held_out
        assert not {e.get("sha256") for e in validation.values()} & hashes
        assert sorted(load_validation(pool, ONE)) == sorted(validation)
    # the third kind: hand-written, neither learned here nor an APF-A pair
    surround = read_manifest(pool_dir(SURROUND))["members"]
    assert {e["kind"] for e in surround.values()} == {"handwritten"}
    assert not any(mid.startswith("apf-a") for mid in surround)

    for name in EVALUATION_POOLS:  # an evaluation pool, by name or as a folder
        with pytest.raises(PoolError, match="evaluation pool"):
            load_validation(name, ONE)
        with pytest.raises(PoolError, match="belongs to an evaluation pool"):
            load_validation(POOLS_DIR / name, ONE)
        with pytest.raises(ConfigError, match="never an evaluation pool"):
            RunConfig.from_dict({"validation": {"pool": name}})
    # a validation folder holding a copy of an evaluation member's file, renamed
    sneaky = tmp_path / "sneaky"
    sneaky.mkdir()
    entry = dict(read_manifest(pool_dir("het"))["members"]["d3qn-g-1"])
    (sneaky / "mine.pt").write_bytes((POOLS_DIR / "het" / entry["file"]).read_bytes())
    manifest = {
        "format": POOL_FORMAT,
        "pool": "sneaky",
        "commit": "test",
        "members": {"mine": entry | {"file": "mine.pt", "name": "Mine"}},
    }
    (sneaky / MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(PoolError, match="an evaluation pool member's"):
        load_validation(sneaky, ONE)

    from hola_ray.config import run as run_config

    assert run_config.EVALUATION_POOLS == tuple(EVALUATION_POOLS)  # what a config refuses
    root = Path(__file__).resolve().parents[1] / "hola_ray"
    for package in ("config", "methods", "oracle", "population"):
        for source in (root / package).rglob("*.py"):
            text = source.read_text().replace("homes.read_manifest(", "")  # populations'
            for word in ("load_pool(", "read_manifest(", "POOLS_DIR", "import pools"):
                assert word not in text, (source, word)
            for line in text.splitlines():  # from the pools: the validation set alone,
                if "pools import" in line:  # and the pools' hashes (to refuse their files)
                    assert line.strip().startswith("from hola_ray.evaluation.pools import ")
                    names = {n.strip() for n in line.split(" import ", 1)[1].split(",")}
                    allowed = {"load_validation", "pooled_files", "sha256", "MANIFEST", "ROOT"}
                    assert names <= allowed, (source, names - allowed)


def test_a_pool_file_by_its_path_plays_in_the_scenario_its_manifest_names(tmp_path):
    """`export`, `fly`, `evaluate` and `replay` take a pool member's file by its path
    (pools/hot/ppo-1.pt, a shipped population's members/node_0002.pt): its export predates
    exports carrying their scenario, so the manifest beside it gives it. A copy away from
    its manifest is still refused in one line."""
    import shutil

    from hola_ray.commands.export import resolve
    from hola_ray.evaluation.pools import POOLS_DIR
    from hola_ray.policies.registry import trained_scenario

    hot = POOLS_DIR / "hot" / "ppo-1.pt"
    member = POOLS_DIR / "populations" / "fcp-3v1-s0" / "members" / "node_0002.pt"
    assert torch.load(hot, weights_only=True).get("scenario") is None  # the premise
    policy, source = resolve(str(hot))  # export and fly
    assert policy.config.n_evaders == 2 and source["file"] == str(hot)
    assert MLPPolicy.load(hot).config.n_evaders == 2
    assert trained_scenario(hot).n_evaders == 2  # evaluate, replay
    assert trained_scenario(member).n_evaders == 1
    assert trained_scenario(member).reward.approach == "distance"

    stray = tmp_path / "ppo-1.pt"
    shutil.copyfile(hot, stray)
    with pytest.raises(ValueError, match=r"ppo-1.pt does not say which scenario .* no manifest"):
        MLPPolicy.load(stray)
