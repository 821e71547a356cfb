"""Generation zero as one value: where a run's G_0 comes from and where its learner starts,
resolved from the config and the run directory before Ray starts (`resolve`), then
carried out by the trainer (`take`, `starting_member`).

Where G_0 comes from (`GenerationZero.source`):
- "resume": the run directory holds generation 0 or later already; nothing to build;
- "none": a self-play method has no population;
- "adopt": another run of the same `generation_zero_key` built it (`adopt_from`, an
  experiment's methods of one seed that share MEP's population): copied in whole;
- "shipped": a shipped population built in this run's scenario: copied in whole;
- "reweigh": a shipped population built in another scenario (reward included): its members
  are taken and G_0 is weighed again under the run's own (a hyperedge's weight is a team
  return, and η compares the learner's hyperedges with G_0's);
- "build": pre-trained here by the method (`Method.build_population`).

Where the learner starts (`GenerationZero.learner_start`): "random" (RLlib's
initialisation from the run's seed), "member" (generation 0's member with the highest η,
the lowest node on a tie), "shipped" (self-play: the most preferred member of the
shipped population `pretrain.population` names, without the population) or "agent" (the
last node of the shipped population `pretrain.start_agent` names: one neutral start for
every method, refused if it is a member of the run's own generation 0).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from hola_ray.methods.config import RunConfig
from hola_ray.population import shipped
from hola_ray.population.rundir import RunDir

KEY_FILE = "generation_zero_key.json"
"""in a generation-0 folder: the `generation_zero_key` it was built with"""

Source = Literal["resume", "none", "adopt", "shipped", "reweigh", "build"]
Start = Literal["random", "member", "shipped", "agent"]


@dataclass(frozen=True)
class GenerationZero:
    """Where a run's generation 0 comes from and where its learner starts (module doc)."""

    source: Source
    learner_start: Start = "random"
    donor: Path | None = None
    """the run or shipped population folder generation 0 is taken from"""
    manifest: dict[str, Any] | None = dataclasses.field(default=None, compare=False)
    """a shipped population's manifest"""
    said: str = ""
    """what the run's log says of where it came from"""
    differ: str = ""
    """"reweigh": the scenario's fields that differ from the population's, as dotted names"""

    @property
    def taken(self) -> bool:
        """Generation 0 is copied from another folder (`take`)."""
        return self.source in ("adopt", "shipped")


def resolve(config: RunConfig, run: RunDir, adopt_from: Sequence[Path] = ()) -> GenerationZero:
    """Generation zero of a run of `config` in `run` (see the module doc). A shipped
    population that does not fit the run raises `shipped.PopulationError` here, before
    anything is written or started, and so does a start it may not take (`check_start`)."""
    zero = _resolve(config, run, adopt_from)
    check_start(config, zero)
    return zero


def _resolve(config: RunConfig, run: RunDir, adopt_from: Sequence[Path]) -> GenerationZero:
    c, method = config, config.strategy
    start = _learner_start(c)
    if run.last_completed() is not None:
        return GenerationZero("resume", start)
    if method.trains_alone():
        return GenerationZero("none", start)
    if c.pretrain.shipped and method.origin.kind is not None:
        return _shipped(c, start)
    key = c.generation_zero_key()
    for folder in adopt_from if key is not None else ():
        marker = RunDir(folder).generation(0) / KEY_FILE
        if Path(folder).resolve() == run.root.resolve() or not marker.is_file():
            continue
        if marker.read_text() == key:
            name = Path(folder).name
            said = f"adopted from {name} (the same pre-training and G_0)"
            return GenerationZero("adopt", start, Path(folder), said=said)
    return GenerationZero("build", start)


def _learner_start(c: RunConfig) -> Start:
    method = c.strategy
    if method.origin.sets_learner:
        return "random"  # PBT: each generation starts from one of its agents
    if c.pretrain.start_agent != "none":
        return "agent"
    if c.pretrain.learner_start != "member":
        return "random"
    if method.origin.kind is not None:
        return "member"
    return "shipped" if c.pretrain.shipped else "random"


def _shipped(c: RunConfig, start: Start) -> GenerationZero:
    method = c.strategy
    size = method.population_size(c)
    kinds = (method.origin.kind, *method.origin.also)
    donor, manifest = shipped.load(c.pretrain.population, c.seed, c.layout(), kinds)
    if len(manifest["members"]) != size:
        raise shipped.PopulationError(
            f"population {donor.root.name} holds {len(manifest['members'])} members; "
            f"method {c.method} with this config builds {size}"
        )
    said = (
        f"the shipped population {donor.root.name} ({size} members, built at commit "
        f"{str(manifest.get('commit'))[:8]}, seed {manifest.get('seed')})"
    )
    built_in = RunConfig.from_dict(manifest["config_values"]).env
    if built_in != c.env:
        differ = _differences(built_in, c.env)
        return GenerationZero("reweigh", start, donor.root, manifest, said, differ)
    return GenerationZero("shipped", start, donor.root, manifest, said)


def take(zero: GenerationZero, run: RunDir, say: Callable[[str], None]) -> None:
    """Copy a taken generation 0 (`zero.taken`) into the run directory."""
    if not zero.taken:
        return
    run.adopt_generation_zero(RunDir(zero.donor))
    say(f"gen 0: {zero.said}")


def starting_member(
    zero: GenerationZero, config: RunConfig, coord: Any, say: Callable[[str], None]
) -> tuple[int, dict[str, Any]] | None:
    """The node and RLlib state the learner starts from (`zero.learner_start`), or None
    for RLlib's own initialisation. `coord`: the run's coordinator actor."""
    import ray

    if zero.learner_start == "member":
        members = ray.get(coord.view.remote())["members"]
        node = shipped.most_preferred({m["node"]: m["eta"] for m in members})
        best = next(m for m in members if m["node"] == node)
        say(
            f"gen 1: the learner starts from member {node} (η {best['eta'] or 0:.3f}, "
            f"the highest of {len(members)})"
        )
        return node, ray.get(coord.member_states.remote([node]))[node].load()
    if zero.learner_start == "shipped":
        c = config
        donor, manifest, node, eta = shipped.preferred_member(
            c.pretrain.population, c.seed, c.layout()
        )
        say(
            f"gen 1: the learner starts from member {node} of the shipped population "
            f"{donor.root.name} (η {eta:.3f}, the highest of {len(manifest['members'])})"
        )
        return node, donor.load_member_state(node)
    if zero.learner_start == "agent":
        node, state, named = start_agent(config)
        say(f"gen 1: the learner starts from {named}")
        return node, state
    return None


def start_member(config: RunConfig) -> tuple[RunDir, dict[str, Any], dict[str, Any]]:
    """The shipped population `pretrain.start_agent`, verified as a shipped population is,
    its manifest and the manifest's entry of its last node (the start)."""
    c = config
    folder = shipped.population_dir(c.pretrain.start_agent, c.seed)
    donor, manifest = shipped.load(folder, c.seed, c.layout(), str(shipped.read(folder)["kind"]))
    return donor, manifest, max(manifest["members"].values(), key=lambda e: int(e["node"]))


def start_agent(config: RunConfig) -> tuple[int, dict[str, Any], str]:
    """The common start (`start_member`; `check_start` has refused it if a partner holds
    it): its node, its RLlib state and a phrase naming it."""
    donor, manifest, entry = start_member(config)
    node = int(entry["node"])
    named = (
        f"{donor.root.name}'s node {node} ({entry['role']}; the common start, built at "
        f"commit {str(manifest.get('commit'))[:8]})"
    )
    return node, donor.load_member_state(node), named


def check_start(config: RunConfig, zero: GenerationZero) -> None:
    """Refuse, before anything starts, a `pretrain.start_agent` whose start is a member of
    the run's shipped generation 0 (a start is no partner of its learner), and PBT's with a
    shipped population (its agents are copies of the start: it builds them)."""
    c = config
    if c.pretrain.start_agent == "none" or zero.source == "resume":
        return
    donor, start, entry = start_member(c)
    if c.strategy.origin.sets_learner and zero.source != "build":
        raise shipped.PopulationError(
            f"method {c.method} with pretrain.start_agent makes its agents copies of the "
            "start: set pretrain.population: none"
        )
    held = {e["state_sha256"] for e in (zero.manifest or {}).get("members", {}).values()}
    if any(e["state_sha256"] in held for e in start["members"].values()):
        raise shipped.PopulationError(
            f"pretrain.start_agent {donor.root.name}: a member of it (node {entry['node']} is "
            f"the start) is in this run's generation 0, {Path(zero.donor or '').name}; a start "
            "must be no partner of its learner"
        )


def _differences(a: Any, b: Any, prefix: str = "env") -> str:
    """The fields in which two (nested) config dataclasses differ, as dotted names."""
    out = []
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if dataclasses.is_dataclass(x) and x != y:
            out.append(_differences(x, y, f"{prefix}.{f.name}"))
        elif x != y:
            out.append(f"{prefix}.{f.name}")
    return ", ".join(out)
