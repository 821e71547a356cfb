"""RLlib's fixes in `hola_ray.third_party`: RLlib's connectors record the same constructor
arguments with the fast frame lookup as with RLlib's own `inspect.stack`, and a pipeline
rebuilt from them is the same."""

from __future__ import annotations

import ray
from ray.rllib.connectors.connector_v2 import ConnectorV2
from ray.rllib.connectors.learner.general_advantage_estimation import GeneralAdvantageEstimation

from hola_ray.oracle.connectors import DropFrozenModules, PopulationEntropyBonus
from hola_ray.third_party import RLLIB_VERSION, fast_connectors


class Plain(ConnectorV2):
    """A connector without its own __init__: RLlib records the spaces alone."""

    def __call__(self, *, rl_module, batch, episodes, **kwargs):
        return batch


class Twice(PopulationEntropyBonus):
    """Two levels of __init__: RLlib records the arguments of the one that called it (the
    parent's, which this class does not take: RLlib's own quirk, kept)."""

    def __init__(self, *, alpha: float, extra: int = 3):
        super().__init__(alpha=alpha, module_ids=["m"])
        self.extra = extra


def test_fast_connectors_record_what_rllibs_own_init_records():
    assert ray.__version__ == RLLIB_VERSION and fast_connectors()
    assert ConnectorV2.__init__._fast
    rllib = ConnectorV2.__init__._rllib

    def built(make):
        fast = make()
        ConnectorV2.__init__ = rllib
        try:
            slow = make()
        finally:
            ConnectorV2.__init__ = fast_init
        return fast, slow

    fast_init = ConnectorV2.__init__
    makers = [
        lambda: PopulationEntropyBonus(alpha=0.05, module_ids=["member_0", "member_1"]),
        lambda: DropFrozenModules(trained=["learner"]),
        lambda: GeneralAdvantageEstimation(gamma=0.99, lambda_=0.95),
        lambda: Plain(),
        lambda: Twice(alpha=0.1, extra=7),
    ]
    for make in makers:
        fast, slow = built(make)
        assert fast._ctor_kwargs.keys() == slow._ctor_kwargs.keys()
        for key, value in slow._ctor_kwargs.items():
            assert fast._ctor_kwargs[key] == value, key
        assert fast.get_ctor_args_and_kwargs() == slow.get_ctor_args_and_kwargs()
        if not isinstance(fast, Twice):  # RLlib records Twice's parent's arguments: no rebuild
            args, kwargs = fast.get_ctor_args_and_kwargs()
            assert type(fast)(*args, **kwargs)._ctor_kwargs == fast._ctor_kwargs
    assert ConnectorV2.__init__ is fast_init


SEEDED = """
import sys, json, torch
from ray.rllib.utils.debug import deterministic, update_global_seed_if_necessary
from hola_ray.third_party import light_seeding

def seeded():
    update_global_seed_if_necessary("torch", 1234)
    return {
        "draws": torch.randn(5).tolist(),
        "deterministic": torch.are_deterministic_algorithms_enabled(),
        "warn_only": torch.is_deterministic_algorithms_warn_only_enabled(),
        "cudnn": [torch.backends.cudnn.deterministic, torch.backends.cudnn.benchmark],
        "inductor_loaded": "torch._inductor.config" in sys.modules,
    }

assert light_seeding()  # torch loaded, the inductor not yet
light = seeded()
deterministic.set_torch_seed = deterministic.set_torch_seed._rllib  # RLlib's own again
torch._C._set_deterministic_algorithms(False)
rllib = seeded()
print(json.dumps({"light": light, "rllib": rllib}))
"""


def test_light_seeding_seeds_torch_as_rllib_does_without_loading_the_inductor():
    """In a fresh interpreter, the light seeding and then RLlib's own: the same draws and
    the same deterministic-algorithms setting; only RLlib's loads the inductor."""
    import json
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", SEEDED], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    seen = json.loads(out.stdout.strip().splitlines()[-1])
    light, rllib = seen["light"], seen["rllib"]
    assert not light.pop("inductor_loaded") and rllib.pop("inductor_loaded")
    assert light == rllib and rllib["deterministic"]


OPTIMIZED = """
import json, sys, torch
from hola_ray.third_party import lazy_dynamo

def trained(optimizer_class, **options):
    torch.manual_seed(7)
    model = torch.nn.Sequential(torch.nn.Linear(4, 8), torch.nn.Tanh(), torch.nn.Linear(8, 2))
    optimizer = optimizer_class(model.parameters(), **options)
    for _ in range(3):
        optimizer.zero_grad()
        model(torch.randn(16, 4)).pow(2).mean().backward()
        optimizer.step()  # in its own grad mode (off), the caller's (on) back after it
        assert torch.is_grad_enabled()
    optimizer.load_state_dict(optimizer.state_dict())
    return [p.tolist() for p in model.parameters()]

if sys.argv[1] == "lazy":
    assert lazy_dynamo()
runs = [trained(torch.optim.Adam, lr=0.01), trained(torch.optim.SGD, lr=0.1, momentum=0.9)]
loaded = "torch._dynamo" in sys.modules
import torch._dynamo  # loaded now: the fixed methods do as torch's own from here
runs.append(trained(torch.optim.Adam, lr=0.01))
print(json.dumps({"runs": runs, "dynamo_loaded_while_training": loaded}))
"""


def test_lazy_dynamo_trains_as_torchs_own_optimizers_without_loading_dynamo():
    """In fresh interpreters, torch's optimizers with `lazy_dynamo` and without: the same
    weights after the same steps (Adam, SGD with momentum; zero_grad, step, a state dict's
    round trip), and only the fixed ones did not load `torch._dynamo`; once it is loaded the
    fixed ones train the same again."""
    import json
    import subprocess
    import sys

    seen = {}
    for how in ("lazy", "torch"):
        out = subprocess.run([sys.executable, "-c", OPTIMIZED, how], capture_output=True, text=True)
        assert out.returncode == 0, out.stderr[-2000:]
        seen[how] = json.loads(out.stdout.strip().splitlines()[-1])
    assert not seen["lazy"]["dynamo_loaded_while_training"]
    assert seen["torch"]["dynamo_loaded_while_training"]
    assert seen["lazy"]["runs"] == seen["torch"]["runs"]
    assert seen["lazy"]["runs"][2] == seen["lazy"]["runs"][0]
