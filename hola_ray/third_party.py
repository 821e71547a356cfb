"""Fixes of Ray 2.60 and RLlib 2.60 in this process, all in this one module: each changes
what its library costs, never what it computes; each is applied by an explicit call, none
by an import; and each leaves a version of its library other than the one it was read from
alone.

Ray, `lean_local_ray`: a local Ray started without what a local Ray of this project never
uses (`LEAN_LOCAL_RAY`: the dashboard agent on a fixed port, the autoscaler monitor; the
dashboard head where the dashboard is off; the log monitor where nothing streams to the
driver), its workers started with the cyclic collector paused. Called by `hola_ray.process`
before each start of a local Ray, and by the suite's own starts.

RLlib, `apply_rllib`: its two fixes and torch's `lazy_dynamo`, called where RLlib's parts
are built.

`fast_connectors`: RLlib's `ConnectorV2.__init__` records its subclass's constructor
arguments (for `get_ctor_args_and_kwargs`, to rebuild a pipeline from a checkpoint) by
reading its caller's frame with `inspect.stack()[1].frame`. `inspect.stack` builds a
`FrameInfo` for every frame on the stack, reading each frame's source lines and walking
`sys.modules` to find each frame's module: with torch, Ray and RLlib loaded, 0.1–0.2 s
per connector here, and an algorithm builds 20–30 connectors (its learner pipeline and
each env runner's two), so 3–6 s per Oracle built, in the driver and in every env runner.
The frame it reads is `sys._getframe(1)` of the same call: replaced here by that, with the
same recorded arguments (tested against RLlib's own in tests/oracle/test_third_party.py).

`light_seeding`: RLlib seeds torch in every algorithm, learner and env runner
(`update_global_seed_if_necessary` → `set_torch_seed`), which calls
`torch.use_deterministic_algorithms(True)`; that function imports `torch._inductor.config`
(1.4 s here, in the driver and in every env runner, at every start) only to set the flag
that `torch.compile`'s inductor reads. The fix sets the same eager-mode flag
(`torch._C._set_deterministic_algorithms`) and the inductor's flag only when the inductor
is loaded already; what the eager ops compute is the same (tested in the same file).

torch, `lazy_dynamo`: an optimizer imports `torch._dynamo` (1.4 s here, sympy with it) at
its construction and at each step, only to mark its methods as never traced and to put
graph breaks around its step; while nothing has loaded `torch._dynamo` nothing is being
traced, and those marks do nothing. The fix calls the methods themselves until something
loads it, and torch's own wrappers from then on (tested in tests/oracle/test_third_party.py:
the same weights after the same steps).

`apply_rllib()` applies the three where RLlib's parts are built: the Oracle
(`hola_ray.oracle.trainer.Oracle`), each of its env runners (`BatchedEnvRunner`) and the
D3QN trainer; once per process (a second call finds them in place). The report for Ray's
maintainers is in docs/packages.md ("Two fixes of RLlib 2.60").
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

# ---- RLlib ------------------------------------------------------------------------------------
RLLIB_VERSION = "2.60.0"
"""the RLlib these fixes were read from; another version keeps its own code"""


def fast_connectors() -> bool:
    """Record a connector's constructor arguments from `sys._getframe(1)` instead of
    `inspect.stack()`; True when the fix is in place (now or before)."""
    import inspect

    import ray
    from ray.rllib.connectors.connector_v2 import ConnectorV2

    if getattr(ConnectorV2.__init__, "_fast", False):
        return True
    if ray.__version__ != RLLIB_VERSION:
        return False

    def __init__(self, input_observation_space=None, input_action_space=None, **kwargs):
        # RLlib 2.60's ConnectorV2.__init__, line for line, but the caller's frame
        self._observation_space = None
        self._action_space = None
        self._input_observation_space = None
        self._input_action_space = None

        self.input_action_space = input_action_space
        self.input_observation_space = input_observation_space

        if self.__class__.__dict__.get("__init__") is not None:
            caller_frame = sys._getframe(1)
            arg_info = inspect.getargvalues(caller_frame)
            caller_locals = arg_info.locals
            self._ctor_kwargs = {arg: caller_locals[arg] for arg in arg_info.args if arg != "self"}
        else:
            self._ctor_kwargs = {
                "input_observation_space": self.input_observation_space,
                "input_action_space": self.input_action_space,
            }

    __init__.__doc__ = ConnectorV2.__init__.__doc__
    __init__._fast = True
    __init__._rllib = ConnectorV2.__init__
    ConnectorV2.__init__ = __init__
    return True


def light_seeding() -> bool:
    """Seed torch as RLlib's `set_torch_seed` does, without importing the inductor to set a
    flag nothing here reads; True when the fix is in place (now or before)."""
    import ray
    from ray.rllib.utils.debug import deterministic

    if getattr(deterministic.set_torch_seed, "_light", False):
        return True
    if ray.__version__ != RLLIB_VERSION:
        return False
    rllib_set_torch_seed = deterministic.set_torch_seed

    def set_torch_seed(seed: int | None = None) -> None:
        # RLlib 2.60's set_torch_seed on a CPU build, but the inductor's import
        import torch

        if seed is None:
            return
        if torch.version.cuda is not None:
            rllib_set_torch_seed(seed)
            return
        torch.manual_seed(seed)
        torch._C._set_deterministic_algorithms(True, warn_only=False)
        inductor = sys.modules.get("torch._inductor.config")
        if inductor is not None:
            inductor.deterministic = True
        torch.backends.cudnn.deterministic = True
        torch.backends.cudnn.benchmark = False

    set_torch_seed.__doc__ = rllib_set_torch_seed.__doc__
    set_torch_seed._light = True
    set_torch_seed._rllib = rllib_set_torch_seed
    deterministic.set_torch_seed = set_torch_seed
    return True


# ---- torch -------------------------------------------------------------------------------------
TORCH_VERSION = "2.13.0"
"""the torch `lazy_dynamo` was read from; another keeps its own"""


def lazy_dynamo() -> bool:
    """torch's optimizers without `torch._dynamo` until something else loads it; True when
    the fix is in place (now or before)."""
    import torch
    from torch.optim import optimizer

    if getattr(optimizer, "_lazy_dynamo", False):
        return True
    if torch.__version__.split("+")[0] != TORCH_VERSION:
        return False
    disabled = torch._disable_dynamo(lambda: None).__code__  # the wrapper's code
    with_grad = optimizer._use_grad_for_differentiable(lambda self: None).__code__
    classes = [getattr(torch.optim, name) for name in torch.optim.__all__]
    for cls in [c for c in classes if isinstance(c, type) and issubclass(c, optimizer.Optimizer)]:
        for name, method in list(vars(cls).items()):
            code = getattr(method, "__code__", None)
            if code is disabled:
                closure = dict(zip(code.co_freevars, method.__closure__, strict=True))
                fn = closure["fn"].cell_contents
                if getattr(fn, "__dynamo_disable", None) is None:
                    fn.__dynamo_disable = _until_dynamo(fn, closure["recursive"].cell_contents)
            elif name == "step" and code is with_grad and not getattr(method, "hooked", False):
                setattr(cls, name, _grad_mode_step(method))
    optimizer._lazy_dynamo = True
    return True


def _until_dynamo(fn: Any, recursive: bool) -> Any:
    """What `torch._disable_dynamo`'s wrapper calls in `fn`'s place: `fn` itself while
    `torch._dynamo` is not loaded (nothing can be tracing), torch's own once it is."""

    def call(*args: Any, **kwargs: Any) -> Any:
        if "torch._dynamo" not in sys.modules:
            return fn(*args, **kwargs)
        import torch._dynamo  # loaded, or being loaded by another thread: wait for it

        fn.__dynamo_disable = torch._dynamo.disable(fn, recursive, wrapping=False)
        return fn.__dynamo_disable(*args, **kwargs)

    return call


def _grad_mode_step(use_grad: Any) -> Any:
    """An optimizer's `step` as `_use_grad_for_differentiable` makes it, without its two
    `torch._dynamo.graph_break()` calls while `torch._dynamo` is not loaded."""
    import functools

    import torch

    step_of = use_grad.__wrapped__

    @functools.wraps(step_of)
    def step(self: Any, *args: Any, **kwargs: Any) -> Any:
        if "torch._dynamo" in sys.modules:
            return use_grad(self, *args, **kwargs)
        grad = torch.is_grad_enabled()
        try:
            torch.set_grad_enabled(self.defaults["differentiable"])
            return step_of(self, *args, **kwargs)
        finally:
            torch.set_grad_enabled(grad)

    return step


def apply_rllib() -> dict[str, bool]:
    """RLlib's two fixes and torch's `lazy_dynamo` in this process (where RLlib builds its
    parts, its learner's optimizer among them); which are in place (False: another
    version)."""
    return {
        "fast_connectors": fast_connectors(),
        "light_seeding": light_seeding(),
        "lazy_dynamo": lazy_dynamo(),
    }


def rllib_in_place() -> dict[str, bool]:
    """Which of RLlib's fixes this process has, and whether it loaded torch's inductor."""
    from ray.rllib.connectors.connector_v2 import ConnectorV2
    from ray.rllib.utils.debug import deterministic

    return {
        "fast_connectors": getattr(ConnectorV2.__init__, "_fast", False),
        "light_seeding": getattr(deterministic.set_torch_seed, "_light", False),
        "lazy_dynamo": getattr(sys.modules.get("torch.optim.optimizer"), "_lazy_dynamo", False),
        "inductor_loaded": "torch._inductor.config" in sys.modules,
    }


# ---- Ray ---------------------------------------------------------------------------------------
RAY_VERSION = "2.60.0"
"""the Ray whose start `lean_local_ray` was read from; another keeps its own"""

LEAN_LOCAL_RAY = {
    "dashboard_agent_listen_port": 0,
    "no_monitor": True,
    "worker_path": str(Path(__file__).with_name("ray_worker.py")),
}
"""What a local Ray of this project starts differently from Ray 2.60's defaults (`RayParams`
fields; `ray.init` takes neither):

- `dashboard_agent_listen_port` 0: the dashboard agent's HTTP server on a port the system
  picks, not the fixed 52365. With a second Ray on the machine (the suite's two workers, a
  command beside a run or a population build) the fixed port is taken: the agent retries it
  through its back-offs and gives up, and the raylet waits for the agent before it
  registers, so every such `ray.init` waits for nothing and runs without the agent's server
  (Ray Jobs). 0 is Ray's own "any free port": the agent records the port it bound where
  the dashboard looks it up.
- `no_monitor`: no autoscaler monitor, a process that only drives an autoscaler, which a
  local Ray has none of (part of each start, and a poll every few seconds). A cluster's
  nodes, started by `ray start`, keep theirs.
- `worker_path`: each Python worker runs `hola_ray/ray_worker.py`, which runs Ray's own
  `default_worker.py` with the cyclic collector paused while the worker starts
  (`hola_ray.process.pause_collector`). A cluster's nodes run Ray's own.

And with `include_dashboard=False`, no dashboard head (`lean_local_ray`): Ray 2.60 starts
one regardless, serving only its usage-stats module (usage reporting off) with its HTTP
server off, and `ray.init` waits for it to announce itself before it starts the raylet,
so without it a start is shorter and costs less CPU (results/NOTEBOOK.md, "No dashboard
head where the dashboard is off"). Nothing this project runs without the dashboard asks
the head for anything (Ray's state API and Ray Jobs need its HTTP server, on only with
the dashboard); the metrics a run exports (`--metrics-port`) are the dashboard agent's,
which stays."""


def lean_local_ray(log_monitor: bool = True) -> bool:
    """Every local Ray this process starts from now on takes `LEAN_LOCAL_RAY`, no dashboard
    head where the dashboard is off, and no log monitor unless `log_monitor` (the process
    that streams the workers' output to the driver: nothing to stream where `log_to_driver`
    is off); True when that is in place."""
    import ray
    from ray._private import node, parameter

    if ray.__version__ != RAY_VERSION:
        return False
    init = getattr(parameter.RayParams.__init__, "_ray_default", parameter.RayParams.__init__)
    lean = {**LEAN_LOCAL_RAY, "include_log_monitor": log_monitor}

    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        init(self, *args, **{**lean, **kwargs})

    __init__._ray_default = init  # type: ignore[attr-defined]
    parameter.RayParams.__init__ = __init__

    api = getattr(node.Node.start_api_server, "_ray_default", node.Node.start_api_server)

    def start_api_server(self: Any, *, include_dashboard: bool | None, **kwargs: Any) -> None:
        if include_dashboard is False:  # no head: what Ray's own says without its server
            self._webui_url = ""
            return
        api(self, include_dashboard=include_dashboard, **kwargs)

    start_api_server._ray_default = api  # type: ignore[attr-defined]
    node.Node.start_api_server = start_api_server
    return True
