#!/usr/bin/env python3
"""This machine's speed against the reference machine, for wall-time figures.

Training here mixes three kinds of work, and machines differ in each by different factors
(a machine 2.5× faster at a torch MLP was barely faster at training), so three fixed
workloads are timed, each best of five (single runs vary by ±20 % on a shared machine; run
it when the machine is otherwise idle):
- torch: a 64×64 tanh MLP on batches of 1024, forward, backward, Adam, 2 threads;
- numpy: small-array arithmetic of the sampler's sizes (64×3 rows), many calls;
- python: a pure-Python loop of dict and list work (episode bookkeeping, RLlib's glue).
`scale` is the geometric mean of reference_s / here_s over the three: multiply a wall time
measured here by `scale` to state it in reference-machine time (scale < 1: this machine is
slower). Prints one JSON line. Needs only torch and numpy.

usage: python benchmarks/calib.py [--best-of 5]

A copy of the workplace's calibration script (the reference machine's seconds below are its
own), kept here so that a clone states wall times in the same reference-machine time.
"""

import json
import math
import time

import numpy as np
import torch

REFERENCE_S = {"torch": 3.40, "numpy": 2.60, "python": 1.88}
"""best-of-five seconds of each workload on the reference machine (the machine of 2026-12-03,
within 3–7 % of the one the earlier single-workload calibration was anchored on)"""


def _torch(fraction: float = 1.0) -> None:
    torch.set_num_threads(2)
    torch.manual_seed(0)
    net = torch.nn.Sequential(
        torch.nn.Linear(40, 64),
        torch.nn.Tanh(),
        torch.nn.Linear(64, 64),
        torch.nn.Tanh(),
        torch.nn.Linear(64, 2),
    )
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    x, y = torch.randn(1024, 40), torch.randn(1024, 2)
    for _ in range(round(1500 * fraction)):
        loss = ((net(x) - y) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()


def _numpy(fraction: float = 1.0) -> None:
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((192, 3)), rng.standard_normal((192, 3))
    for _ in range(round(100_000 * fraction)):
        d = np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])
        a[:, 2] = np.arctan2(np.sin(a[:, 2] + d * 1e-3), np.cos(a[:, 2]))
        np.clip(a, -5.0, 5.0, out=a)


def _python(fraction: float = 1.0) -> None:
    rows: list = []
    for i in range(round(3_000_000 * fraction)):
        step = {"agent": f"pursuer_{i % 3}", "reward": i * 0.5, "done": i % 97 == 0}
        rows.append(step)
        if step["done"]:
            total = sum(r["reward"] for r in rows[-97:])
            rows = [{"total": total}]


WORKLOADS = {"torch": _torch, "numpy": _numpy, "python": _python}


def best(fn, repeats: int = 5, fraction: float = 1.0) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(fraction)
        times.append(time.perf_counter() - t0)
    return min(times)


def main(argv: list[str] | None = None) -> int:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--best-of", type=int, default=5, help="runs of each workload")
    parser.add_argument(
        "--fraction",
        type=float,
        default=1.0,
        help="of each workload (a smoke test: the scale is only meaningful at 1)",
    )
    args = parser.parse_args(argv)
    here = {name: round(best(fn, args.best_of, args.fraction), 3) for name, fn in WORKLOADS.items()}
    reference = {k: v * args.fraction for k, v in REFERENCE_S.items()}
    scale = math.exp(sum(math.log(reference[k] / here[k]) for k in here) / len(here))
    print(json.dumps({"calib_s": here, "reference_s": REFERENCE_S, "scale": round(scale, 3)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
