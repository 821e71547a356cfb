"""The population's and the Grapher's configuration (the `population` and `grapher`
sections of a run config)."""

from __future__ import annotations

from dataclasses import dataclass

from hola_ray.config.reader import finite_in, positive_int, require


@dataclass(frozen=True)
class PopulationConfig:
    """The population that the HyFoG describes (docs/contract.md §4–5)."""

    max_size: int = 10
    """hypergraph size: most members in the population"""
    initial_size: int = 4
    """members pre-trained with MEP to build G_0"""
    top_m: int = 3
    """the learner joins when its η rank is within the top m (the approximate oracle)"""
    preferred_only: bool = False
    """true: the learner joins only when some member also prefers it (η > 0); false: the
    paper's rule, rank alone, under which a learner at η = 0 joins when ties put it within
    the top m (results/NOTEBOOK.md: 59 of hola's 68 joins at 3 vs 2)"""
    phi_shift: float = 0.1
    """φ = normalised 1/(x − x_min + shift·(x_max − x_min)), x the node values"""
    rank_beta: float = 3.0
    """β of MEP's prioritised partner sampling p ∝ rank^β (method mep)"""

    def validate(self, l: int) -> None:  # noqa: E741 - the paper's l
        s = "population"
        positive_int(s, self, "max_size", "initial_size", "top_m", maximum=100)
        require(
            self.max_size >= l,
            "population.max_size (the hypergraph size)",
            f">= l = env.n_pursuers = {l}",
            self.max_size,
        )
        require(
            l <= self.initial_size <= self.max_size,
            "population.initial_size",
            f"in [l = {l}, population.max_size = {self.max_size}]",
            self.initial_size,
        )
        require(
            self.top_m <= self.max_size,
            "population.top_m",
            f"<= population.max_size ({self.max_size})",
            self.top_m,
        )
        finite_in(s, self, "phi_shift", 1e-6, 10.0, "in [1e-6, 10]")
        finite_in(s, self, "rank_beta", 0.0, 100.0, "in [0, 100]")


@dataclass(frozen=True)
class GrapherConfig:
    """How the Grapher weighs hyperedges by simulation."""

    episodes_per_edge: int = 32
    """evaluation episodes behind each hyperedge weight"""
    edges_per_learner: int = 3
    """(l − 1)-sets of members sampled for the learner's hyperedges, as the paper's Grapher
    builds them (§IV-B); 0 = every one, which keeps the hypergraph regular, and then φ
    from the Myerson value is φ from the mean reward (results/NOTEBOOK.md, on hola_r)"""
    initial_edges: int = 0
    """hyperedges of a taken G_0 (a shipped or adopted build) the run keeps, drawn with its
    seed so that every member keeps one; 0 = every one. G_0 is complete, so regular: φ from
    the Myerson value is φ from the mean reward until a learner joins, and with
    `population.preferred_only` few join. With 4 members and l 3, 3 of the 4 make hola's
    φ depart from hola_r's from generation 1 (docs/plan.md)"""
    workers: int = 2
    """evaluation actors (`hola_ray.population.evaluators`): they play a generation's
    hyperedge chunks side by side, and the monitors while the next generation trains; 0 =
    play everything in the driver, no actors (small populations, tests)"""
    chunks: int = 2
    """batches a generation's hyperedges are cut into, each one vectorised rollout; a
    weight depends on its chunk to within the float rounding of the stacked forward pass,
    never on which worker plays it (so `workers` changes no weight); give each worker one"""

    def validate(self) -> None:
        positive_int("grapher", self, "episodes_per_edge", maximum=10**6)
        positive_int("grapher", self, "workers", minimum=0, maximum=10_000)
        positive_int("grapher", self, "chunks", maximum=10_000)
        positive_int("grapher", self, "edges_per_learner", minimum=0, maximum=10**6)
        positive_int("grapher", self, "initial_edges", minimum=0, maximum=10**6)
