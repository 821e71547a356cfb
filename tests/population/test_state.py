"""The coordinator's decisions and the run directory, without Ray."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from hola_ray.population.coordinator import total_variation
from hola_ray.population.files import TorchFile
from hola_ray.population.rules import InverseValue
from hola_ray.population.rundir import RunDir, phi_departure, phi_tie
from hola_ray.population.state import EdgeResult, Population, edge_seed


def edge(nodes, weight):
    return EdgeResult(tuple(nodes), weight, 0.5, 0.0, 100.0, 4)


def worked_example(max_size=4, top_m=3):
    """Members 0..3 and candidate 4 with these hyperedge weights:

    {0,1,2} 5, {0,1,3} 1, {0,2,3} 1, {1,2,3} 2 | {4,1,2} 9, {4,0,3} 0, {4,0,1} 3.
    Best edges: 0→{0,1,2}, 1→{1,2,4}, 2→{1,2,4}, 3→{1,2,3}, 4→{1,2,4}.
    In-degrees (other nodes whose best edge holds i): d0 = 0, d1 = 4, d2 = 4, d3 = 0,
    d4 = 2 (from 1 and 2), so η = d/(5 − 1) = 0, 1, 1, 0, 0.5 and the candidate's
    competition rank is 1 + 2 = 3.
    """
    p = Population(l=3, max_size=max_size, top_m=top_m)
    p.add_initial(4)
    p.record([edge((0, 1, 2), 5), edge((0, 1, 3), 1), edge((0, 2, 3), 1), edge((1, 2, 3), 2)])
    assert p.propose() == 4
    p.record([edge((4, 1, 2), 9), edge((4, 0, 3), 0), edge((4, 0, 1), 3)])
    return p


def test_accepted_candidate_replaces_the_lowest_eta_member_when_full():
    p = worked_example(max_size=4, top_m=3)
    d = p.decide()
    assert d.accepted and d.rank == 3 and d.eta == pytest.approx(0.5)
    # 0 and 3 tie at η = 0; the earlier inserted (0) makes room and its slot is reused.
    assert d.replaced == 0 and d.slot == 0
    assert p.slots == {1: 1, 2: 2, 3: 3, 4: 0}
    assert 0 not in p.hyfog and p.candidate is None
    assert p.members == [1, 2, 3, 4]


def test_an_adopted_generation_zero_takes_the_runs_own_m_and_size():
    """A generation 0 adopted from a build with m 2 and room for 4 (its state.json) plays
    the run's open-ended phase: the run's m 3 and size 6, so the worked example's candidate
    (rank 3) joins, into a free slot; a run too small for the members is refused."""
    from hola_ray.config.population import PopulationConfig
    from hola_ray.population.coordinator import saved_population

    built = worked_example(max_size=4, top_m=2)
    assert not built.decide().accepted  # the build's m turns it away: four members, as shipped
    state = {"population": built.to_dict()}
    run = PopulationConfig(max_size=6, initial_size=4, top_m=3, preferred_only=True)
    p = saved_population(state, run)
    assert (p.max_size, p.top_m, p.preferred_only) == (6, 3, True)
    assert p.members == [0, 1, 2, 3]
    candidate = p.propose()
    p.record([edge((candidate, 1, 2), 9), edge((candidate, 0, 3), 0), edge((candidate, 0, 1), 3)])
    d = p.decide()
    assert d.rank == 3 and d.accepted and d.replaced is None and d.slot == 4
    with pytest.raises(ValueError, match="more than population.max_size 3"):
        saved_population(state, PopulationConfig(max_size=3, initial_size=3, top_m=3))


def test_a_candidate_nobody_prefers_joins_by_rank_alone_unless_preferred_only():
    """A candidate whose hyperedges all weigh 0: no member's best hyperedge holds it (η 0),
    and it ties member 3 (η 0) at competition rank 4. Under the paper's rule (rank alone,
    m = 4) it joins; with `preferred_only` it is turned away, and the setting persists."""
    for preferred_only, joins in ((False, True), (True, False)):
        p = Population(l=3, max_size=4, top_m=4, preferred_only=preferred_only)
        p.add_initial(4)
        members = [edge((0, 1, 2), 5), edge((0, 1, 3), 1), edge((0, 2, 3), 1)]
        p.record([*members, edge((1, 2, 3), 2)])
        assert p.propose() == 4
        p.record([edge((4, 1, 2), 0), edge((4, 0, 3), 0), edge((4, 0, 1), 0)])
        d = p.decide()
        assert d.eta == 0 and d.rank == 4 and d.accepted is joins, (preferred_only, d)
        assert Population.from_dict(p.to_dict()).preferred_only is preferred_only


def test_candidate_outside_top_m_is_removed():
    p = worked_example(max_size=4, top_m=2)
    d = p.decide()
    assert not d.accepted and d.rank == 3 and d.replaced is None and d.slot is None
    assert 4 not in p.hyfog and p.slots == {0: 0, 1: 1, 2: 2, 3: 3}
    assert len(p.hyfog.edges) == 4  # the candidate's hyperedges went with it
    assert p.propose() == 5  # ids are never reused


def test_accepted_candidate_takes_a_free_slot_when_not_full():
    p = worked_example(max_size=6, top_m=3)
    d = p.decide()
    assert d.accepted and d.replaced is None and d.slot == 4
    assert p.members == [0, 1, 2, 3, 4]


def test_phi_and_eta_leave_the_undecided_candidate_out():
    p = worked_example()
    phi = InverseValue("myerson", 0.1).phi(p)  # HOLA-Drone's rules
    assert set(phi) == {0, 1, 2, 3} and sum(phi.values()) == pytest.approx(1.0)
    # Among members only: best edges 0→{0,1,2}, 1→{0,1,2}, 2→{0,1,2}, 3→{1,2,3}:
    # d0 = 2, d1 = 3, d2 = 3, d3 = 0 → η = d/3.
    assert p.eta() == pytest.approx({0: 2 / 3, 1: 1.0, 2: 1.0, 3: 0.0})


def test_a_generations_phi_is_measured_against_its_rival_and_uniform_draws():
    """The worked example's members (η 2/3, 1, 1, 0): HOLA-Drone's φ against the mean
    reward's (`phi_tv`) and against uniform draws over the same members, which it is not."""
    from hola_ray.population.coordinator import phi_distances

    p = worked_example()
    p.decide()  # the candidate joins: members 1, 2, 3, 4 on their own hyperedges
    phi = InverseValue("myerson", 0.1).phi(p)
    got = phi_distances(phi, p, InverseValue("mean_reward", 0.1), None)
    uniform = {v: 1 / len(p.members) for v in p.members}
    assert got["phi_tv_uniform"] == pytest.approx(total_variation(phi, uniform))
    assert got["phi_tv_uniform"] > 0.01
    rival = InverseValue("mean_reward", 0.1).phi(p)
    assert got["phi_tv"] == pytest.approx(total_variation(phi, rival))
    assert phi_distances(phi, p, InverseValue("myerson", 0.1), None)["phi_tv"] == 0.0


def test_hola_and_hola_r_part_only_when_a_sampled_candidate_joins():
    """On G_0 (complete, 4 members, l = 3: every member in 3 hyperedges) φ from the Myerson
    value and from the mean reward are one distribution; a candidate judged on 2 sampled
    hyperedges and accepted is a member in 2, its partners in 4 or 5: they part."""
    rng = np.random.default_rng(0)
    pops = {kind: Population(l=3, max_size=6, top_m=5) for kind in ("myerson", "mean_reward")}
    rules = {kind: InverseValue(kind, 0.1) for kind in pops}
    g0 = [
        edge(e, float(w))
        for e, w in zip(
            [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)], rng.normal(20, 3, 4), strict=True
        )
    ]
    for p in pops.values():
        p.add_initial(4)
        p.record(g0)
    phi = {kind: rules[kind].phi(p) for kind, p in pops.items()}
    assert phi["myerson"] == pytest.approx(phi["mean_reward"], rel=1e-12)
    for p in pops.values():
        p.propose()
        sets = p.candidate_edges(2, np.random.default_rng(1))
        assert len(sets) == 2
        p.record([edge(e, 18.0 + k) for k, e in enumerate(sets)])
        assert p.decide().accepted
    mv, mr = (rules[kind].phi(p) for kind, p in pops.items())
    assert set(mv) == set(mr) == {0, 1, 2, 3, 4}
    assert max(abs(mv[v] - mr[v]) for v in mv) > 0.01
    # what a run logs as phi_tv, and says when it never passed PHI_TIE
    assert total_variation(phi["myerson"], phi["mean_reward"]) == pytest.approx(0, abs=1e-12)
    tv = total_variation(mv, mr)
    assert tv == pytest.approx(0.5 * sum(abs(mv[v] - mr[v]) for v in mv)) and tv > 0.01
    assert total_variation({0: 1.0}, {1: 1.0}) == 1.0
    rows = [{"generation": 0}, {"phi_tv": 0.0}, {"phi_tv": 0.004}]
    assert phi_departure(rows) == 0.004 and phi_departure(rows[:1]) is None
    assert "never departed from myerson's by more than 0.01" in phi_tie(rows, "myerson")
    assert phi_tie([*rows, {"phi_tv": tv}], "myerson") is None


def test_a_thinned_generation_zero_parts_hola_from_hola_r_before_any_join():
    """`grapher.initial_edges` 3 of G_0's 4: every member keeps a hyperedge, one member is
    in all three (degree 3 against 2), and φ from the Myerson value leaves φ from the mean
    reward at once; the draw is the generator's alone, and 0 keeps every hyperedge."""
    from hola_ray.population.coordinator import INITIAL_EDGES_STREAM

    def g0():
        p = Population(l=3, max_size=6, top_m=4, preferred_only=True)
        p.add_initial(4)
        p.record([edge(e, w) for e, w in zip(
            [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)], [96.8, 90.7, 97.4, 91.8], strict=True
        )])  # fmt: skip
        return p

    whole = g0()
    assert whole.thin(0, np.random.default_rng(0)) == [] and len(whole.hyfog.edges) == 4
    assert whole.thin(4, np.random.default_rng(0)) == []
    rules = [InverseValue(kind, 0.1) for kind in ("myerson", "mean_reward")]
    assert total_variation(*(r.phi(whole) for r in rules)) == pytest.approx(0, abs=1e-12)
    removed = set()
    for seed in range(12):
        p = g0()
        rng = np.random.default_rng([seed, 0, INITIAL_EDGES_STREAM])
        gone = p.thin(3, rng)
        again = g0().thin(3, np.random.default_rng([seed, 0, INITIAL_EDGES_STREAM]))
        assert gone == again and len(gone) == 1 and len(p.hyfog.edges) == 3
        degrees = sorted(sum(v in e.nodes for e in p.hyfog.edges) for v in p.members)
        assert degrees == [2, 2, 2, 3]
        assert total_variation(*(r.phi(p) for r in rules)) > 0.15
        removed.add(gone[0])
    assert len(removed) > 1  # the seed decides which
    with pytest.raises(ValueError, match="no 1 of the 4 hyperedges hold every member"):
        g0().thin(1, np.random.default_rng(0))


def test_a_run_going_on_from_a_shipped_generation_zero_thins_it_by_its_seed(tmp_path):
    """The coordinator, started on a run directory whose generation 0 is a shipped build,
    keeps `grapher.initial_edges` of G_0's hyperedges, the same ones for every method of a
    seed (hola and hola_r are paired) and on every start; the build's own files keep all."""
    from hola_ray.config.population import PopulationConfig
    from hola_ray.homes import POOLS
    from hola_ray.population.coordinator import Coordinator, CoordinatorSettings

    donor = RunDir(POOLS / "populations" / "mep-3v2-s0")
    actor = Coordinator.__ray_metadata__.modified_class  # the class, without Ray

    def start(folder, kind, seed, initial_edges=3):
        run = RunDir(tmp_path / folder)
        if not run.generations.is_dir():
            run.generations.mkdir(parents=True)
            run.adopt_generation_zero(donor)
        settings = CoordinatorSettings(
            rules=InverseValue(kind, 0.1),
            population=PopulationConfig(max_size=10, top_m=4, preferred_only=True),
            l=3,
            seed=seed,
            edges_per_learner=3,
            initial_edges=initial_edges,
            method=kind,
        )
        c = actor(str(run.root), settings)
        return c, {frozenset(e.nodes) for e in c.population.hyfog.edges}

    hola, edges = start("hola-s7", "myerson", 7)
    rival, rival_edges = start("hola_r-s7", "mean_reward", 7)
    assert len(edges) == 3 and edges == rival_edges
    assert start("hola-s7", "myerson", 7)[1] == edges  # a second start draws the same
    assert total_variation(hola.rules.phi(hola.population), rival.rules.phi(rival.population)) > 0.1
    assert len(start("whole-s7", "myerson", 7, initial_edges=0)[1]) == 4
    assert len(donor.read_json(0, "state.json")["population"]["hyfog"]["edges"]) == 4


def test_the_coordinators_process_never_loads_torch(tmp_path):
    """The coordinator writes and reads torch files as bytes (`TorchFile`), imports
    tensorboardX without torch, and unpickles every method's rules without importing the
    methods: its actor starts on a quarter of the CPU. What the driver packs, the run
    directory holds as torch would have written it."""
    import pickle
    import subprocess
    import sys

    import torch

    from hola_ray.methods.config import METHODS, RunConfig

    rules = []
    for method in METHODS:
        config = RunConfig.from_dict({"method": method})
        rules += [config.strategy.rules(config), config.strategy.rival(config)]
    (tmp_path / "rules.pkl").write_bytes(pickle.dumps(rules))
    script = (
        "import sys, pathlib, pickle; import hola_ray.population.coordinator; "
        "import hola_ray.population.telemetry as c; "
        f"c.summary_writer(pathlib.Path({str(tmp_path / 'tb')!r})).add_scalar('x', 1.0, 0); "
        f"pickle.loads(pathlib.Path({str(tmp_path / 'rules.pkl')!r}).read_bytes()); "
        "print(sorted(m for m in sys.modules"
        " if m.startswith(('torch', 'hola_ray.methods', 'hola_ray.oracle'))))"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[]"
    assert list((tmp_path / "tb").glob("events.out.tfevents.*"))
    run = RunDir(tmp_path / "run")
    run.members.mkdir(parents=True)
    export, state = {"w": torch.arange(3.0)}, {"w": np.arange(4, dtype=np.float32)}
    run.save_member(5, TorchFile.of(export), TorchFile.of(state))
    assert (run.load_member_export(5)["w"] == export["w"]).all()
    assert (run.load_member_state(5)["w"] == state["w"]).all()
    assert TorchFile.read(run.member_state(5)).load().keys() == {"w"}


def test_candidate_edges_sample_distinct_sets_reproducibly():
    p = Population(l=3, max_size=10, top_m=3)
    p.add_initial(5)
    c = p.propose()
    every = p.candidate_edges(0, np.random.default_rng(0))
    assert len(every) == 10 and all(e[0] == c for e in every)  # C(5, 2) = 10
    some = p.candidate_edges(4, np.random.default_rng(7))
    assert len(set(some)) == 4 and set(some) <= set(every)
    assert some == p.candidate_edges(4, np.random.default_rng(7))
    assert p.candidate_edges(50, np.random.default_rng(0)) == every


def test_population_round_trip_and_no_persisting_mid_decision():
    p = worked_example()
    with pytest.raises(ValueError, match="candidate is undecided"):
        p.to_dict()
    p.decide()
    q = Population.from_dict(p.to_dict())
    assert q.to_dict() == p.to_dict() and q.hyfog == p.hyfog


def test_edge_seed_depends_on_the_node_set_and_generation_only():
    assert edge_seed(0, 3, (4, 1, 2)) == edge_seed(0, 3, (1, 2, 4))
    assert edge_seed(0, 3, (1, 2, 4)) != edge_seed(0, 4, (1, 2, 4))
    assert edge_seed(0, 3, (1, 2, 4)) != edge_seed(1, 3, (1, 2, 4))


def test_generation_folders_are_all_or_nothing(tmp_path):
    run = RunDir(tmp_path / "run")
    run.create("method: hola\n")
    run.write_generation(0, {"metrics.json": {"generation": 0, "a": 1}}, None)
    run.write_generation(1, {"metrics.json": {"generation": 1, "a": 2, "b": 3}}, {"w": 1})
    with pytest.raises(FileExistsError):
        run.write_generation(1, {"metrics.json": {}}, None)
    # A driver killed while writing generation 2 leaves only a temporary folder.
    (run.generations / ".tmp_gen_0002_123").mkdir()
    assert run.completed() == [0, 1] and run.last_completed() == 1
    run.clean_partial()
    assert not (run.generations / ".tmp_gen_0002_123").exists()
    assert run.load_learner_state(1) == {"w": 1} and run.load_learner_state(0) is None
    run.rewrite_metrics_csv()
    rows = list(csv.DictReader(run.metrics_csv.open()))
    assert [r["generation"] for r in rows] == ["0", "1"]
    assert rows[0]["b"] == "" and rows[1]["b"] == "3"


def test_metrics_csv_has_the_runs_cumulative_wall_time(tmp_path):
    """cumulative_wall_s sums the generations' wall_s; a generation 0 written before it had
    one counts its phases (pre-training, Grapher, coordinator)."""
    run = RunDir(tmp_path / "run")
    run.create("method: hola\n")
    old_g0 = {"generation": 0, "pretrain_s": 100.0, "grapher_s": 5.5, "coordinator_s": 0.5}
    run.write_generation(0, {"metrics.json": old_g0}, None)
    run.write_generation(1, {"metrics.json": {"generation": 1, "wall_s": 20.25}}, None)
    run.write_generation(2, {"metrics.json": {"generation": 2, "wall_s": 9.75}}, None)
    run.rewrite_metrics_csv()
    rows = list(csv.DictReader(run.metrics_csv.open()))
    # 100 + 5.5 + 0.5 = 106; + 20.25 = 126.25; + 9.75 = 136
    assert [float(r["cumulative_wall_s"]) for r in rows] == [106.0, 126.25, 136.0]
    assert "cumulative_wall_s" not in run.read_json(1, "metrics.json")  # derived, not stored


def test_runs_in_folders_of_one_name_get_different_actor_names(tmp_path):
    from hola_ray.population.coordinator import coordinator_name, run_id

    a, b = tmp_path / "x" / "paper", tmp_path / "y" / "paper"
    assert coordinator_name(str(a)) != coordinator_name(str(b))
    assert run_id(str(a)).startswith("paper-") and run_id(str(a)) == run_id(str(a / ".." / "paper"))


def test_a_run_directory_file_that_would_run_code_is_refused(tmp_path):
    """`--resume` reads members' and the learner's RLlib states with `weights_only=True`:
    numpy arrays (float and integer) come back as they went in; a file whose unpickling
    would call a function (here os.system) is refused in one line, and nothing runs."""
    import os

    import torch

    from hola_ray.population.files import UnsafeFile

    run = RunDir(tmp_path / "run")
    run.members.mkdir(parents=True)
    state = {"w": np.arange(6, dtype=np.float32).reshape(2, 3), "n": np.arange(3)}
    run.save_member(0, {"plain": torch.zeros(2)}, state)
    back = run.load_member_state(0)
    assert set(back) == {"w", "n"} and all((back[k] == state[k]).all() for k in state)

    witness = tmp_path / "ran"

    class Crafted:
        def __reduce__(self):
            return (os.system, (f"touch {witness}",))

    torch.save({"w": Crafted()}, run.member_state(1))
    with pytest.raises(UnsafeFile) as err:
        run.load_member_state(1)
    said = str(err.value)
    assert "\n" not in said and str(run.member_state(1)) in said and "posix.system" in said
    assert not witness.exists()
    # the same bytes from the coordinator are refused alike
    with pytest.raises(UnsafeFile, match="posix.system"):
        TorchFile.read(run.member_state(1)).load()
    assert not witness.exists()


def test_a_generations_monitors_join_its_row_and_a_run_without_them_is_not_finished(tmp_path):
    """Monitors are written beside a saved generation (monitors.json) and joined into its
    metrics row; until then the row says `monitored: 0` and the run is not finished. A row
    that never said so (written before monitors came apart) counts as monitored."""
    run = RunDir(tmp_path / "run")
    run.create("method: hola\n")
    run.write_generation(0, {"metrics.json": {"generation": 0, "population_success": 0.9}}, None)
    assert run.monitored(0)  # an old row: no `monitored` key
    row = {"generation": 1, "monitored": 0, "learner_success": 0.5, "learner_collision": 0.2}
    run.write_generation(1, {"metrics.json": row}, {"w": 1})
    run.save_learner({"w": 1})
    run.save_learner_info({"generation": 1})
    assert not run.monitored(1) and not run.finished(1)
    assert run.metrics(1) == row
    run.complete(1, {"monitored": 1, "val_success": 0.75, "val_collision": 0.1})
    assert run.monitored(1) and run.finished(1)
    assert run.metrics(1) == row | {"monitored": 1, "val_success": 0.75, "val_collision": 0.1}
    assert run.read_json(1, "metrics.json") == row  # the committed row is never rewritten
    csv_row = list(csv.DictReader(run.metrics_csv.open()))[1]
    assert csv_row["val_success"] == "0.75" and csv_row["monitored"] == "1"


def test_a_population_for_teams_of_several_sizes():
    """Teams of 2 and 3 (contract §6.2): G_0 holds every pair and every triple of the
    members; a candidate gets `count` sets of each size; the sizes persist, and a saved
    population of other sizes is refused for the run."""
    from hola_ray.config.population import PopulationConfig
    from hola_ray.population.coordinator import saved_population

    p = Population(l=3, max_size=6, top_m=3, sizes=(2, 3))
    p.add_initial(4)
    g0 = p.initial_edges()
    assert len(g0) == 6 + 4 and [len(e) for e in g0] == [2] * 6 + [3] * 4
    p.record([edge(e, float(sum(e))) for e in g0])
    candidate = p.propose()
    picked = p.candidate_edges(2, np.random.default_rng(0))
    assert [len(e) for e in picked] == [2, 2, 3, 3] and all(e[0] == candidate for e in picked)
    assert len(p.candidate_edges(0, np.random.default_rng(0))) == 4 + 6
    # the candidate's returns, each less its size's mean: the member of its first pair sits
    # above both sizes' means, so it ranks first, though pairs return less than triples
    best = picked[0][1]

    def measured(e):
        return 10.0 * len(e) + (2.0 if best in e else 0.0)

    p.record([edge(e, measured(e)) for e in picked])
    offset = {k: np.mean([measured(e) for e in picked if len(e) == k]) for k in (2, 3)}
    for member, value in p.learner_returns.items():
        mine = [measured(e) - offset[len(e)] for e in picked if member in e]
        assert value == pytest.approx(np.mean(mine))
    assert max(p.learner_returns, key=p.learner_returns.get) == best
    p.decide()
    back = Population.from_dict(p.to_dict())
    assert back.sizes == (2, 3) and back.hyfog == p.hyfog
    state = {"population": p.to_dict()}
    run = PopulationConfig(max_size=6, initial_size=4, top_m=3)
    assert saved_population(state, run, (2, 3)).sizes == (2, 3)
    with pytest.raises(ValueError, match="teams of \\[2, 3\\]; this run flies teams of \\[3\\]"):
        saved_population(state, run, (3,))
