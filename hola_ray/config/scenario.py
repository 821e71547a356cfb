"""Typed, validated configuration of the pursuit arena (contract §1) and its evader (contract §2).

Every number of the scenario lives here as a field with a default; nothing downstream
hard-codes one. A bad value fails at construction, naming the field and the allowed range.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hola_ray.config.layout import ObsLayout
from hola_ray.config.reader import (
    ConfigError,
    _is_number,
    consume_fields,
    load_yaml,
    located,
    require,
)

Rect = tuple[float, float, float, float]
"""An axis-aligned box as (centre_x, centre_y, width, height), metres."""

Region = tuple[float, float, float, float]
"""A spawn region as (x_min, x_max, y_min, y_max), metres."""

Disc = tuple[float, float, float]
"""A round obstacle as (centre_x, centre_y, radius), metres."""

PAPER_BARS: tuple[Rect, ...] = (
    (1.225, 1.05, 0.65, 0.10),
    (2.375, 1.05, 0.65, 0.10),
    (1.80, 2.50, 0.65, 0.10),
    (1.225, 3.95, 0.65, 0.10),
    (2.375, 3.95, 0.65, 0.10),
)
"""The paper's five bars (Table I), in its 3.6 m × 5 m arena."""

ARENAS: dict[str, tuple[tuple[Rect, ...], tuple[Disc, ...]]] = {
    "open": ((), ()),
    "bar": (((1.80, 2.50, 2.40, 0.10),), ()),
    "blocks": (((0.95, 1.70, 0.50, 0.50), (2.65, 3.30, 0.50, 0.50)), ((1.80, 2.50, 0.35),)),
    "paper": (PAPER_BARS, ()),
}
"""The named layouts of the 3.6 m × 5 m arena, easiest first (contract §6): walls only; one
bar across the middle, 0.6 m gaps at its ends; two 0.5 m squares and a disc of 0.35 m
radius; the paper's five bars. Each as (boxes, discs); the spawn strips stay clear."""

CUSTOM_ARENA = "custom"
"""`env.arena` of a scenario that gives its own `obstacles` and `discs`"""


@dataclass(frozen=True)
class EvaderConfig:
    """The DACOOP escaper (contract §2); distances in metres (DACOOP's are millimetres)."""

    sensitivity_range: float = 2.0
    """pursuers farther than this are ignored by the flee force and the panic level"""
    panic_threshold: float = 0.2
    """below this panic level (and clear of obstacles) the evader wanders"""
    wander_clearance: float = 0.3
    """wandering needs the nearest obstacle farther than this"""
    wander_hold_min: int = 10
    """fewest steps a wander heading is held"""
    wander_hold_max: int = 15
    """most steps a wander heading is held"""
    repulsion_gain: float = 0.01
    """η of the obstacle repulsion η·(1/(d − r) − 1/R)/(d − r)²  (DACOOP's 1e7 in mm units)"""
    repulsion_range: float = 0.8
    """R: obstacles farther than this do not repel"""
    repulsion_offset: float = 0.1
    """r: the drone safe radius subtracted from obstacle distances in the repulsion"""
    wall_follow_switch_distance: float = 0.4
    """a pursuer nearer than this may make the evader switch wall-following tangent"""
    wall_follow_push_distance: float = 0.05
    """nearer than this to an obstacle, the repulsion is added to the wall-following tangent"""
    slip_range: float = 0.5
    """slipping is considered when two pursuers are nearer than this"""
    slip_start_clearance: float = 0.3
    """a slip starts only with an obstacle nearer than this (DACOOP)"""
    slip_keep_clearance: float = 0.1
    """a slip continues only while obstacles are farther than this (DACOOP)"""
    max_turn: float = math.pi / 6
    """most heading change per step, radians (30°)"""
    min_clearance: float = 0.03
    """a step that would end nearer than this to an obstacle or wall is not taken (DACOOP)"""

    def __post_init__(self) -> None:
        for name in (
            "sensitivity_range",
            "repulsion_range",
            "wall_follow_switch_distance",
            "slip_range",
        ):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0, f"evader.{name}", "> 0", value)
        for name in (
            "repulsion_gain",
            "repulsion_offset",
            "wall_follow_push_distance",
            "slip_start_clearance",
            "slip_keep_clearance",
            "min_clearance",
            "wander_clearance",
        ):
            value = getattr(self, name)
            require(math.isfinite(value) and value >= 0, f"evader.{name}", ">= 0", value)
        require(
            0 <= self.panic_threshold <= 1,
            "evader.panic_threshold",
            "in [0, 1]",
            self.panic_threshold,
        )
        require(self.wander_hold_min >= 1, "evader.wander_hold_min", ">= 1", self.wander_hold_min)
        require(
            self.wander_hold_max >= self.wander_hold_min,
            "evader.wander_hold_max",
            f">= wander_hold_min ({self.wander_hold_min})",
            self.wander_hold_max,
        )
        require(0 < self.max_turn <= math.pi, "evader.max_turn", "in (0, π]", self.max_turn)
        require(
            self.repulsion_offset < self.repulsion_range,
            "evader.repulsion_offset",
            f"< repulsion_range ({self.repulsion_range})",
            self.repulsion_offset,
        )


APPROACH_MODES = ("distance", "own_move")
"""What the approach term's d_now measures (`RewardConfig.approach`)."""


@dataclass(frozen=True)
class RewardConfig:
    """Each pursuer's reward per step (contract §1). The defaults are the contract's;
    DACOOP-A's code used capture 20, collision 20, approach_scale 0.2 and obstacle_penalty 2
    within 0.15 m."""

    capture: float = 10.0
    """to every active pursuer, for each evader captured this step (shared)"""
    collision: float = 10.0
    """subtracted from the reward of a pursuer that collides this step"""
    approach_scale: float = 0.3
    """the approach term is Σ (d_prev − d_now) / approach_scale over live evaders"""
    approach: str = "distance"
    """what d_now measures: `distance`, the distance after both moves (contract §1), so an
    escaping evader costs the pursuer up to (v_e − v_p)·dt / approach_scale a step; or
    `own_move`, the distance from the pursuer's new position to where the evader was, so the
    term credits only the pursuer's own move and an escape costs it nothing"""
    obstacle_penalty: float = 0.0
    """subtracted each step a pursuer ends nearer than obstacle_distance to an obstacle"""
    obstacle_distance: float = 0.15
    """reach of obstacle_penalty, metres (walls, bars and disabled pursuers)"""
    teammate_penalty: float = 0.0
    """subtracted each step, per active teammate nearer than teammate_distance"""
    teammate_distance: float = 0.3
    """reach of teammate_penalty, metres"""
    teammate_graded: bool = False
    """False: teammate_penalty in full per teammate nearer than teammate_distance; True:
    graded, rising linearly from 0 at teammate_distance to teammate_penalty at κ (AT-Drone's
    proximity penalty between 0.4 and 0.2 m), so a pursuer feels a teammate coming"""
    shared: bool = False
    """the paper's common reward (§III): every pursuer active at the start of a step (one
    that the step disables included; a disabled pursuer's agent has terminated) receives the
    team's reward for the step, the mean over the n_p pursuers of the terms above (their sum
    / n_p: the scale of the per-pursuer reward, so the same PPO settings apply); False:
    each pursuer its own terms (contract §1)"""

    def __post_init__(self) -> None:
        for name in ("capture", "collision", "obstacle_penalty", "teammate_penalty"):
            value = getattr(self, name)
            require(
                _is_number(value) and math.isfinite(value) and value >= 0,
                f"reward.{name}",
                "a finite number >= 0",
                value,
            )
        require(isinstance(self.shared, bool), "reward.shared", "true or false", self.shared)
        require(
            isinstance(self.teammate_graded, bool),
            "reward.teammate_graded",
            "true or false",
            self.teammate_graded,
        )
        require(
            self.approach in APPROACH_MODES,
            "reward.approach",
            " or ".join(APPROACH_MODES),
            self.approach,
        )
        for name in ("approach_scale", "obstacle_distance", "teammate_distance"):
            value = getattr(self, name)
            require(
                _is_number(value) and math.isfinite(value) and value > 0,
                f"reward.{name}",
                "a finite number > 0",
                value,
            )


@dataclass(frozen=True)
class TeamChangeConfig:
    """Teammates who join and leave within an episode (contract §6.3). Off by default: every
    pursuer in play from the start to the end, as the paper has it."""

    present: int | tuple[int, int] | None = None
    """pursuers in play at the start, the first `fixed` seats among them and the rest drawn;
    the others wait, out of play, to join. A pair [low, high]: drawn per episode, uniformly
    (a team of any size in one batch); unset: all `n_pursuers`"""
    changes: int = 0
    """team changes per episode: at each, a teammate in play and not crashed leaves (it
    lands: out of play, no obstacle, not observed) or one that waits joins at the pursuers'
    spawn, a coin deciding where both can happen"""
    window: tuple[float, float] = (0.1, 0.6)
    """the share of the horizon the changes' times are drawn in, uniformly"""
    min_team: int = 1
    """no leave takes the pursuers flying (in play, not crashed) below this"""
    fixed: int = 1
    """seats 0..fixed−1 start in play and never leave: the seats a learner controls (one at
    least where the team changes)"""

    def __post_init__(self) -> None:
        for name, low in (("changes", 0), ("min_team", 1), ("fixed", 0)):
            value = getattr(self, name)
            ok = isinstance(value, int) and not isinstance(value, bool) and value >= low
            require(ok, f"team.{name}", f"an integer >= {low}", value)
        if self.present is not None:
            value = self.present
            pair = tuple(value) if isinstance(value, list | tuple) else (value, value)
            ok = len(pair) == 2 and all(
                isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in pair
            )
            ok = ok and pair[0] <= pair[1]
            require(ok, "team.present", "an integer >= 1 or a pair [low, high] of them", value)
            if isinstance(value, list | tuple):
                object.__setattr__(self, "present", pair)
        ok = len(self.window) == 2 and all(_is_number(v) for v in self.window)
        require(ok, "team.window", "two numbers (start, end)", self.window)
        object.__setattr__(self, "window", tuple(float(v) for v in self.window))
        lo, hi = self.window
        require(0.0 <= lo < hi <= 1.0, "team.window", "0 <= start < end <= 1", self.window)

    @property
    def present_range(self) -> tuple[int, int] | None:
        """(low, high) of the pursuers in play at the start; None: all."""
        if self.present is None:
            return None
        return self.present if isinstance(self.present, tuple) else (self.present, self.present)

    def start_range(self, n_pursuers: int) -> tuple[int, int]:
        """(low, high) of the pursuers in play at the start of an episode of `n_pursuers`
        seats."""
        return self.present_range or (n_pursuers, n_pursuers)

    def sizes(self, n_pursuers: int) -> tuple[int, ...]:
        """The sizes the team in play can have in an episode of `n_pursuers` seats: the
        paper's team alone where it is closed; where it changes, of two or more, from the
        smallest start less a leave at each change (none below `min_team` or the fixed
        seats) to the largest start plus a join at each (none beyond the seats)."""
        lo, hi = self.start_range(n_pursuers)
        if not self.open:
            return (n_pursuers,)
        lo = min(lo, max(lo - self.changes, self.min_team, self.fixed))
        hi = min(n_pursuers, hi + self.changes)
        return tuple(range(max(lo, 2), max(hi, 2) + 1)) if n_pursuers > 1 else (1,)

    @property
    def open(self) -> bool:
        """The team may differ from all pursuers in play throughout."""
        return self.changes > 0 or self.present is not None

    @property
    def learner_seats(self) -> tuple[int, ...] | None:
        """The learner's seats in every episode of a team that changes within it: the
        fixed ones, 0 … fixed − 1, which never leave (contract §6.3); None for a team kept
        whole, where the learner takes one uniformly random seat."""
        return tuple(range(self.fixed)) if self.open else None


@dataclass(frozen=True)
class PursuitConfig:
    """The pursuit scenario of contract §1 (paper Table I). Units: metres, seconds, radians."""

    arena_width: float = 3.6
    """arena extent along x; the walls are obstacles"""
    arena_height: float = 5.0
    """arena extent along y"""
    arena: str | None = None
    """the layout: `open`, `bar`, `blocks` or `paper` (`ARENAS`), or `custom` with the
    `obstacles` and `discs` given; unset: `paper`, or `custom` when either is given"""
    obstacles: tuple[Rect, ...] | None = None
    """boxes (bars and squares) as (centre_x, centre_y, width, height); unset: the arena's"""
    discs: tuple[Disc, ...] | None = None
    """round obstacles as (centre_x, centre_y, radius); unset: the arena's"""
    arenas: tuple[str, ...] = ()
    """named arenas (`ARENAS`) each episode draws its layout from, uniformly, from its own
    stream (contract §6.1); `arena` is then one of them, the first unless given, and names
    the layout of what draws no episode (a drawing's default). Empty: every episode in
    `arena`"""
    n_pursuers: int = 3
    """pursuers per episode (the learner and its teammates)"""
    n_evaders: int = 2
    """evaders per episode"""
    pursuer_spawn: Region = (0.2, 3.4, 0.2, 0.8)
    """pursuer spawn region (x_min, x_max, y_min, y_max); pursuers start heading +y"""
    evader_spawn: Region = (0.2, 3.4, 4.2, 4.8)
    """evader spawn region (x_min, x_max, y_min, y_max); evaders start heading −y"""
    spawn_separation: float = 0.3
    """drones of one team spawn at least this far apart"""
    dt: float = 0.1
    """seconds per step (10 fps)"""
    horizon: int = 1000
    """steps before truncation (100 s)"""
    pursuer_speed: float = 0.3
    """constant pursuer speed, m/s"""
    evader_speed: float = 0.6
    """constant evader speed, m/s"""
    max_turn: float = math.pi / 4
    """a pursuer action a ∈ [0, 1] turns the heading by (2a − 1)·max_turn"""
    pursuer_response: float = 1.0
    """the share of the way from its velocity to the commanded one (pursuer_speed along
    the heading) a pursuer's velocity goes each step: 1 = at once (the paper's
    kinematics); a Crazyflie measures about 0.37 with response_delay 1 (docs/flight.md)"""
    pursuer_response_delay: int = 0
    """steps before a commanded velocity starts to act: 0 or 1"""
    capture_distance: float = 0.2
    """d_c: an active pursuer nearer than this captures an evader"""
    perception_range: float = 2.0
    """d_p: teammates farther than this are not observed"""
    safe_radius: float = 0.1
    """d_s: a pursuer nearer than this to an obstacle, wall or disabled pursuer collides"""
    pursuer_collision_distance: float = 0.2
    """κ: two active pursuers nearer than this both collide"""
    obs_distance_scale: float = 5.0
    """observed distances are divided by this"""
    unobserved_distance: float = 2.0
    """the distance reading of a captured evader or an unobserved teammate"""
    observe_headings: bool = False
    """append each other pursuer's heading relative to the observer's (/ π; 0 beyond d_p or
    disabled) after the own block (`ObsLayout.headings`); the observation's first
    entries are unchanged, so policies trained without it read them"""
    obs_pursuers: int | None = None
    """pursuer slots of the observation (the observer and its teammates): a team smaller
    than this fills the rest as unobserved teammates; unset (or `n_pursuers`): the team's
    own (`pursuer_slots`). One policy then plays every team up to this size (contract
    §6.2); `dataclasses.replace` of `n_pursuers` keeps the slots"""
    obs_evaders: int | None = None
    """evader slots of the observation, the ones beyond `n_evaders` read as captured;
    unset (or `n_evaders`): the scenario's own (`evader_slots`)"""
    reward: RewardConfig = field(default_factory=RewardConfig)
    """each pursuer's reward (contract §1)"""
    team: TeamChangeConfig = field(default_factory=TeamChangeConfig)
    """teammates who join and leave within an episode (contract §6.3); off by default"""
    evader: EvaderConfig = field(default_factory=EvaderConfig)
    """the escaper's parameters (contract §2)"""

    def __post_init__(self) -> None:
        # In this order: the first failing check is the error a bad config raises, and
        # the later checks read values the earlier ones vouch for (a diagonal needs
        # positive sides, a packing bound needs ordered regions).
        self._check_magnitudes()
        self._check_pursuer_model()
        self._check_unobserved_distance()
        self._check_counts()
        self._resolve_arena()
        self._check_obstacles()
        self._check_layout()
        self._check_team()
        self._check_spawn()

    def _check_magnitudes(self) -> None:
        """Lengths, speeds, times and the turn: finite, and positive except the distances
        that may be 0 (no margin, no separation)."""
        positive = (
            "arena_width",
            "arena_height",
            "dt",
            "pursuer_speed",
            "evader_speed",
            "capture_distance",
            "perception_range",
            "obs_distance_scale",
            "max_turn",
        )
        for name in positive:
            value = getattr(self, name)
            require(
                isinstance(value, int | float) and math.isfinite(value) and value > 0,
                name,
                "a finite number > 0",
                value,
            )
        for name in (
            "safe_radius",
            "pursuer_collision_distance",
            "spawn_separation",
            "unobserved_distance",
        ):
            value = getattr(self, name)
            require(
                isinstance(value, int | float) and math.isfinite(value) and value >= 0,
                name,
                "a finite number >= 0",
                value,
            )
        require(self.max_turn <= math.pi, "max_turn", "in (0, π]", self.max_turn)

    def _check_pursuer_model(self) -> None:
        """What a pursuer observes beyond the paper's layout, and how its velocity follows a
        command: a bool, a share in (0, 1] and a delay of 0 or 1 steps (bools refused as
        numbers, so a YAML `true` cannot pass for 1)."""
        value = self.observe_headings
        require(isinstance(value, bool), "observe_headings", "true or false", value)
        value = self.pursuer_response
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        require(ok and 0 < value <= 1, "pursuer_response", "a number in (0, 1]", value)
        value = self.pursuer_response_delay
        ok = isinstance(value, int) and not isinstance(value, bool)
        require(ok and value in (0, 1), "pursuer_response_delay", "0 or 1", value)

    def _check_unobserved_distance(self) -> None:
        """The reading of what is not seen must exceed every reading of what is, or a policy
        could not tell a far teammate from an unobserved one."""
        diagonal = math.hypot(self.arena_width, self.arena_height) / self.obs_distance_scale
        require(
            self.unobserved_distance > diagonal,
            "unobserved_distance",
            f"> the largest observable distance reading ({diagonal:.3f}), so it is unambiguous",
            self.unobserved_distance,
        )

    def _check_counts(self) -> None:
        """Drones per team and steps per episode: integers, at least one of each, the
        horizon at most a million steps."""
        for name in ("n_pursuers", "n_evaders"):
            value = getattr(self, name)
            require(isinstance(value, int) and value >= 1, name, "an integer >= 1", value)
        value = self.horizon
        require(isinstance(value, int) and value >= 1, "horizon", "an integer >= 1", value)
        require(value <= 10**6, "horizon", "an integer in [1, 1,000,000]", value)
        for name, team in (("obs_pursuers", "n_pursuers"), ("obs_evaders", "n_evaders")):
            value = getattr(self, name)
            if value is None:
                continue
            at_least = getattr(self, team)
            ok = isinstance(value, int) and not isinstance(value, bool) and value >= at_least
            require(ok, name, f"an integer >= {team} ({at_least})", value)
            if value == at_least:  # no slot beyond the team: the same scenario as unset
                object.__setattr__(self, name, None)

    def _check_team(self) -> None:
        """The team's changes fit the team: the fixed seats and the smallest team within
        the pursuers, and at the start as many in play as the fixed seats at least."""
        team, n = self.team, self.n_pursuers
        require(team.fixed <= n, "team.fixed", f"<= n_pursuers ({n})", team.fixed)
        require(team.min_team <= n, "team.min_team", f"<= n_pursuers ({n})", team.min_team)
        if team.present is not None:
            low = max(team.fixed, 1)
            lo, hi = team.present_range
            ok = low <= lo and hi <= n
            require(ok, "team.present", f"in [{low}, n_pursuers = {n}]", team.present)
        if team.open:  # the learner's seats are the fixed ones: a team that changes has one
            require(team.fixed >= 1, "team.fixed", ">= 1 where the team changes", team.fixed)

    def _resolve_arena(self) -> None:
        """The arena's name and its obstacles, each from the other where unset: obstacles
        given without a name are the named arena they equal (an older manifest's paper bars
        are `paper`), else `custom`."""
        name = self.arena
        mix = tuple(self.arenas)
        object.__setattr__(self, "arenas", mix)
        for i, drawn in enumerate(mix):
            require(drawn in ARENAS, f"arenas[{i}]", f"one of {', '.join(ARENAS)}", drawn)
        require(len(set(mix)) == len(mix), "arenas", "arenas named once each", list(mix))
        if name is None and mix:
            name = mix[0]
        if mix:
            require(name in mix, "arena", f"one of arenas {list(mix)}", name)
        if name is None and self.obstacles is None and self.discs is None:
            name = "paper"
        elif name is None:
            given = (tuple(self.obstacles or ()), tuple(self.discs or ()))
            name = next((k for k, layout in ARENAS.items() if layout == given), CUSTOM_ARENA)
        known = [*ARENAS, CUSTOM_ARENA]
        require(name in known, "arena", f"one of {', '.join(known)}", name)
        boxes, discs = ARENAS.get(name, ((), ()))
        object.__setattr__(self, "arena", name)
        for key, layout in (("obstacles", boxes), ("discs", discs)):
            if getattr(self, key) is None:
                object.__setattr__(self, key, layout)

    def _check_layout(self) -> None:
        """A named arena's obstacles are its own."""
        if self.arena == CUSTOM_ARENA:
            return
        for key, layout in zip(("obstacles", "discs"), ARENAS[self.arena], strict=True):
            value = getattr(self, key)
            require(
                tuple(value) == layout, key, f"arena {self.arena}'s own (or arena: custom)", value
            )

    def _check_obstacles(self) -> None:
        """Each box of positive size and each disc of positive radius, wholly inside the
        arena."""
        for i, disc in enumerate(self.discs):
            name = f"discs[{i}]"
            require(len(disc) == 3, name, "(centre_x, centre_y, radius)", disc)
            cx, cy, r = disc
            require(r > 0, name, "of positive radius", disc)
            inside = r <= cx <= self.arena_width - r and r <= cy <= self.arena_height - r
            require(
                inside,
                name,
                f"inside the arena [0, {self.arena_width}] × [0, {self.arena_height}]",
                disc,
            )
        for i, rect in enumerate(self.obstacles):
            name = f"obstacles[{i}]"
            require(len(rect) == 4, name, "(centre_x, centre_y, width, height)", rect)
            cx, cy, w, h = rect
            require(w > 0 and h > 0, name, "of positive width and height", rect)
            inside = (
                cx - w / 2 >= 0
                and cx + w / 2 <= self.arena_width
                and cy - h / 2 >= 0
                and cy + h / 2 <= self.arena_height
            )
            require(
                inside,
                name,
                f"inside the arena [0, {self.arena_width}] × [0, {self.arena_height}]",
                rect,
            )

    def _check_spawn(self) -> None:
        """Both spawn regions ordered and inside the arena, then each large enough for its
        team: rejection sampling must be able to place every drone (a loose packing
        bound)."""
        for name in ("pursuer_spawn", "evader_spawn"):
            region = getattr(self, name)
            require(len(region) == 4, name, "(x_min, x_max, y_min, y_max)", region)
            x0, x1, y0, y1 = region
            inside = 0 <= x0 <= x1 <= self.arena_width and 0 <= y0 <= y1 <= self.arena_height
            require(
                inside,
                name,
                f"an ordered region inside [0, {self.arena_width}] × [0, {self.arena_height}]",
                region,
            )
        for name, count in (("pursuer_spawn", self.n_pursuers), ("evader_spawn", self.n_evaders)):
            x0, x1, y0, y1 = getattr(self, name)
            s = self.spawn_separation
            capacity = (
                (math.floor((x1 - x0) / s) + 1) * (math.floor((y1 - y0) / s) + 1) if s else 10**9
            )
            require(
                capacity >= 2 * count,
                name,
                f"large enough to place {count} drones {s} m apart with room to spare",
                getattr(self, name),
            )

    # ---- derived values -------------------------------------------------------------
    @property
    def layout(self) -> ObsLayout:
        """Where each reading sits in one pursuer's observation."""
        diagonal = math.hypot(self.arena_width, self.arena_height)
        far = max(self.unobserved_distance, diagonal / self.obs_distance_scale)
        return ObsLayout(self.pursuer_slots, self.evader_slots, self.observe_headings, far)

    @property
    def pursuer_slots(self) -> int:
        """Pursuers the observation holds: `obs_pursuers`, or the team's own."""
        return self.obs_pursuers or self.n_pursuers

    @property
    def evader_slots(self) -> int:
        """Evaders the observation holds: `obs_evaders`, or the scenario's own."""
        return self.obs_evaders or self.n_evaders

    def judged(self) -> PursuitConfig:
        """The scenario a learned member of this one is held to the contract's bar in, as
        a team of its own copies (§5.1): itself for a fixed team of 3 in one arena; for a
        team that changes, of another size or in drawn arenas (§6), the paper's 3 pursuers
        against its evaders in the paper's arena, observed in its own slots: the contract's
        bars are for 3 pursuers only. A scenario of fewer than 3 slots is judged in its own
        team size (as many as its slots)."""
        own = not self.team.open and not self.arenas
        if own and (self.n_pursuers == 3 or self.pursuer_slots < 3):
            return self  # below 3 slots: its own team, the only one it reads
        return dataclasses.replace(
            self.in_arena("paper"),
            n_pursuers=min(3, self.pursuer_slots),
            obs_pursuers=self.pursuer_slots,
            obs_evaders=self.evader_slots,
            team=TeamChangeConfig(),
        )

    def in_arena(self, name: str) -> PursuitConfig:
        """This scenario in the named arena (`ARENAS`), its obstacles with it."""
        if name not in ARENAS:
            raise ConfigError(f"arena must be one of {', '.join(ARENAS)}, got {name!r}")
        return dataclasses.replace(self, arena=name, obstacles=None, discs=None, arenas=())

    @property
    def layouts(self) -> tuple[tuple[tuple[Rect, ...], tuple[Disc, ...]], ...]:
        """The (boxes, discs) an episode may be played in: one per arena of `arenas`, in
        its order, else the scenario's own."""
        if self.arenas:
            return tuple(ARENAS[name] for name in self.arenas)
        return ((tuple(self.obstacles), tuple(self.discs)),)

    @property
    def obs_dim(self) -> int:
        """Length of one pursuer's observation."""
        return self.layout.dim

    # ---- (de)serialisation ----------------------------------------------------------
    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> PursuitConfig:
        """Build from a plain mapping (YAML); unknown keys are an error."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"a pursuit config must be a mapping, got {type(data).__name__}")
        kwargs = consume_fields(cls, data, "")
        for name, sub in (
            ("evader", EvaderConfig),
            ("reward", RewardConfig),
            ("team", TeamChangeConfig),
        ):
            section = kwargs.pop(name, None)
            if section is not None:
                if not isinstance(section, Mapping):
                    raise ConfigError(f"{name} must be a mapping, got {section!r}")
                kwargs[name] = sub(**consume_fields(sub, section, f"{name}."))
        for key in ("obstacles", "discs"):
            if kwargs.get(key) is not None:
                kwargs[key] = tuple(tuple(float(v) for v in rect) for rect in kwargs[key])
        for key in ("pursuer_spawn", "evader_spawn"):
            if key in kwargs:
                kwargs[key] = tuple(float(v) for v in kwargs[key])
        return cls(**kwargs)

    @classmethod
    def from_yaml(cls, path: str | Path) -> PursuitConfig:
        """Load from a YAML file holding the mapping (or an `env:` section of it)."""
        data = load_yaml(path) or {}
        nested = isinstance(data, Mapping) and isinstance(data.get("env"), Mapping)
        try:
            return cls.from_dict(data["env"] if nested else data)
        except ConfigError as err:
            raise located(err.within("env") if nested else err, path) from None

    def played(self) -> PursuitConfig:
        """This scenario as an evaluation plays it: every field kept but the reward, which
        is the default, so that every learner's returns are counted alike."""
        return dataclasses.replace(self, reward=RewardConfig())

    def to_dict(self) -> dict[str, Any]:
        """A plain, YAML-safe mapping that `from_dict` reads back to an equal config."""
        out = dataclasses.asdict(self)
        out["obstacles"] = [list(rect) for rect in self.obstacles]
        out["discs"] = [list(disc) for disc in self.discs]
        out["arenas"] = list(self.arenas)
        out["team"]["window"] = list(self.team.window)
        if isinstance(self.team.present, tuple):
            out["team"]["present"] = list(self.team.present)
        out["pursuer_spawn"] = list(self.pursuer_spawn)
        out["evader_spawn"] = list(self.evader_spawn)
        return out
