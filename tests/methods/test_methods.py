"""Each method draws partners as it says: through its `Rules` (what the coordinator asks
for φ and for its verdicts) and the Oracle's `PartnerMapping`, checked by counting the
partners of many Oracle episodes. Pure Python, no Ray."""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
import pytest

from hola_ray.config.reader import ConfigError
from hola_ray.methods.config import METHODS, RunConfig
from hola_ray.oracle.mapping import LEARNER, PartnerMapping, member_module
from hola_ray.population.rules import rank_priorities
from hola_ray.population.state import EdgeResult, Population


def edge(nodes, weight):
    return EdgeResult(tuple(nodes), weight, 0.5, 0.0, 100.0, 4)


class Ruled:
    """A population with a method's rules bound to it, as the coordinator holds them."""

    def __init__(self, method: str, members: int, max_size: int = 6, top_m: int = 3, **config):
        self.population = Population(3, max_size, top_m)
        run = RunConfig.from_dict({"method": method, **config})
        self.rules = run.strategy.rules(run)
        self.population.add_initial(members)
        self.rules.setup(self.population)

    def __getattr__(self, name):
        return getattr(self.population, name)

    def phi(self, exclude_slot=None):
        return self.rules.phi(self.population, exclude_slot)

    def decide(self, slot=None, rng=None):
        return self.rules.decide(self.population, slot, rng)


def population(method: str, members: int = 4) -> Ruled:
    p = Ruled(method, members)
    # unequal hyperedge weights, so a φ that reads them would not be uniform
    p.record([edge((0, 1, 2), 9.0), edge((0, 1, 3), 1.0), edge((1, 2, 3), 4.0)])
    return p


def drawn(phi: dict[int, float], episodes: int = 40_000) -> dict[int, float]:
    """How often the Oracle seats each member in a partner slot over many episodes."""
    mapping = PartnerMapping(3, {member_module(n): w for n, w in phi.items()}, learner=True)
    counts: Counter[str] = Counter()
    for k in range(episodes):
        seats = mapping.assignment(f"episode-{k}")
        assert seats.count(LEARNER) == 1
        counts.update(s for s in seats if s != LEARNER)
    total = sum(counts.values())
    return {n: counts[member_module(n)] / total for n in phi}


def test_uniform_draws_every_member_equally_whatever_the_hyperedges():
    p = population("uniform")
    assert p.phi() == {v: 0.25 for v in range(4)}
    freq = drawn(p.phi())
    assert all(abs(f - 0.25) < 0.01 for f in freq.values())
    # the HOLA-Drone φ over the same hyperedges is far from uniform: the control differs
    hola = population("hola").phi()
    assert max(hola.values()) - min(hola.values()) > 0.2


def test_mep_draws_by_rank_of_the_learners_return_to_the_power_beta():
    p = population("mep")
    assert p.phi() == {v: 0.25 for v in range(4)}  # no learner measured yet: uniform
    node = p.propose()
    # the learner's hyperedges: mean return with 0: 8, with 1: (8 + 2)/2 = 5, with 2: 2;
    # member 3 is in none of them
    p.record([edge((node, 0, 1), 8.0), edge((node, 1, 2), 2.0)])
    assert p.learner_returns == {0: 8.0, 1: 5.0, 2: 2.0}
    decision = p.decide()
    assert not decision.accepted and p.members == [0, 1, 2, 3]  # the population stays fixed
    # ranks 1 (best, 0), 2, 3, and 4 for the unmeasured member 3: p ∝ rank³
    expected = np.array([1, 8, 27, 64]) / 100
    np.testing.assert_allclose([p.phi()[v] for v in range(4)], expected)
    freq = drawn(p.phi())
    np.testing.assert_allclose([freq[v] for v in range(4)], expected, atol=0.01)
    # persisted and read back with its returns
    again = Population.from_dict(p.to_dict())
    assert p.rules.phi(again) == p.phi()


def test_rank_priorities_share_tied_ranks_and_work_for_negative_returns():
    phi = rank_priorities({0: -1.0, 1: -5.0, 2: -1.0}, beta=1.0)
    # ranks: 0 and 2 tie for 1 and 2 (1.5 each), 1 ranks 3
    np.testing.assert_allclose([phi[0], phi[1], phi[2]], np.array([1.5, 3, 1.5]) / 6)
    assert rank_priorities({0: None, 1: None}, beta=3.0) == {0: 0.5, 1: 0.5}


def test_fcp_draws_only_its_frozen_checkpoints_uniformly_and_never_admits_the_learner():
    p = Ruled("fcp", 6, top_m=6)  # 2 agents × (start, middle, end)
    for _ in range(3):
        node = p.propose()
        p.record([edge((node, 0, 1), 50.0)])  # the best team there is: rank 1
        decision = p.decide()
        assert not decision.accepted and decision.rank == 1
    assert p.members == list(range(6))
    freq = drawn(p.phi())
    assert set(freq) == set(range(6))
    assert all(abs(f - 1 / 6) < 0.01 for f in freq.values())


def test_methods_that_join_take_a_top_ranked_learner():
    for method in ("hola", "hola_r", "uniform"):
        p = Ruled(method, 3, top_m=1)
        p.record([edge((0, 1, 2), 1.0)])
        node = p.propose()
        p.record([edge((node, 0, 1), 50.0), edge((node, 1, 2), 50.0), edge((node, 0, 2), 50.0)])
        assert p.decide().accepted and node in p.members, method


def test_every_method_is_configured_by_its_name_alone():
    for name, method in METHODS.items():
        config = RunConfig(method=name)
        assert config.strategy is method
        assert config.strategy.trains_alone() == (name == "sp")
    with pytest.raises(ConfigError, match=r"fcp.agents must be such that l = 3 <= 3 · fcp.agents"):
        RunConfig.from_dict({"method": "fcp", "fcp": {"agents": 4}})


def test_pbt_trains_each_agent_with_the_others_drawn_uniformly():
    p = Ruled("pbt", 4, max_size=4)
    for slot in range(4):
        phi = p.phi(exclude_slot=slot)
        others = [v for v in p.members if p.slots[v] != slot]
        assert set(phi) == set(others) and all(w == pytest.approx(1 / 3) for w in phi.values())
        freq = drawn(phi, episodes=20_000)
        assert all(abs(f - 1 / 3) < 0.015 for f in freq.values())


def test_pbt_replaces_the_parent_then_the_bottom_agent_exploits_the_top_and_explores():
    p = Ruled(
        "pbt",
        3,
        max_size=3,
        oracle={"lr": 1e-3, "entropy_coef": 0.01},
        pbt={"quantile": 0.34, "perturb": [0.5, 2.0]},
    )
    scores, hyper = p.extra["agent_scores"], p.extra["agent_hyper"]
    assert hyper == {str(s): {"lr": 1e-3, "entropy_coef": 0.01} for s in range(3)}
    p.record([edge((0, 1, 2), 0.0)])
    rng = np.random.default_rng(0)
    returns = {0: 5.0, 1: 9.0, 2: 1.0}  # the agents' returns after their training
    for slot in range(3):
        node = p.propose()
        others = [v for v in p.members if p.slots[v] != slot]
        p.record([edge((node, *others), returns[slot])])
        d = p.decide(slot, rng)
        assert d.accepted and d.slot == slot and d.replaced == slot  # the parent's node
        assert p.slots[node] == slot and d.replaced not in p.members
        if slot < 2:  # not every agent has a score yet: no exploit
            assert d.copied_from is None and scores[str(slot)] == returns[slot]
    # after the third: agent 2 scores lowest and copies agent 1 (the top), perturbed
    assert d.copied_from == next(v for v, s in p.slots.items() if s == 1)
    assert scores["2"] == returns[1]
    for h, base in (("lr", 1e-3), ("entropy_coef", 0.01)):
        assert hyper["2"][h] in (pytest.approx(base * 0.5), pytest.approx(base * 2.0))
    assert not list(p.hyfog.incident(d.candidate))  # its hyperedges measured other weights
    again = Population.from_dict(json.loads(json.dumps(p.to_dict())))
    assert again.extra == p.extra
