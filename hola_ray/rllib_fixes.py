"""Fixes of RLlib 2.60 in this process that change what it costs, never what it computes.

`fast_connectors`: RLlib's `ConnectorV2.__init__` records its subclass's constructor
arguments (for `get_ctor_args_and_kwargs`, to rebuild a pipeline from a checkpoint) by
reading its caller's frame with `inspect.stack()[1].frame`. `inspect.stack` builds a
`FrameInfo` for every frame on the stack, reading each frame's source lines and walking
`sys.modules` to find each frame's module: with torch, Ray and RLlib loaded, 0.1–0.2 s
per connector here, and an algorithm builds 20–30 connectors (its learner pipeline and
each env runner's two), so 3–6 s per Oracle built, in the driver and in every env runner.
The frame it reads is `sys._getframe(1)` of the same call: replaced here by that, with the
same recorded arguments (tested against RLlib's own in tests/oracle/test_rllib_fixes.py).

`light_seeding`: RLlib seeds torch in every algorithm, learner and env runner
(`update_global_seed_if_necessary` → `set_torch_seed`), which calls
`torch.use_deterministic_algorithms(True)`; that function imports `torch._inductor.config`
(1.4 s here, in the driver and in every env runner, at every start) only to set the flag
that `torch.compile`'s inductor reads. The fix sets the same eager-mode flag
(`torch._C._set_deterministic_algorithms`) and the inductor's flag only when the inductor
is loaded already; what the eager ops compute is the same (tested in the same file).

Applied by an explicit call, `apply()`, where RLlib's parts are built: the Oracle
(`hola_ray.oracle.trainer.Oracle`), each of its env runners (`BatchedEnvRunner`) and the
D3QN trainer; once per process (a second call finds them in place). RLlib other than the
version they were written for is left alone. The report for Ray's maintainers is in
docs/packages.md ("Two fixes of RLlib 2.60").
"""

from __future__ import annotations

import sys

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


def apply() -> dict[str, bool]:
    """Both fixes in this process; which are in place (False: another RLlib version)."""
    return {"fast_connectors": fast_connectors(), "light_seeding": light_seeding()}


def in_place() -> dict[str, bool]:
    """Which fixes this process has, and whether it loaded torch's inductor."""
    from ray.rllib.connectors.connector_v2 import ConnectorV2
    from ray.rllib.utils.debug import deterministic

    return {
        "fast_connectors": getattr(ConnectorV2.__init__, "_fast", False),
        "light_seeding": getattr(deterministic.set_torch_seed, "_light", False),
        "inductor_loaded": "torch._inductor.config" in sys.modules,
    }
