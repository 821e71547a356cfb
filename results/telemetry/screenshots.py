"""The screenshots of docs/telemetry.md (written to docs/img/telemetry/), taken in a real
headless browser (Debian's `chromium`) beside Debian's `prometheus`, both installed apart
from the project:

    sudo apt-get install chromium prometheus
    python results/telemetry/screenshots.py [--out docs/img/telemetry]

A local Ray with its dashboard (token auth off: a local screenshot) and the run's figures
on a metrics port; Prometheus scraping it every 2 s on the configuration Ray writes; the
default run, short, trained to generation 2 and resumed to 4; then the dashboard's Actors
tab (the coordinators' Repr) and Prometheus's graph of `ray_hola_ray_learner_success`."""

from __future__ import annotations

import argparse
import os
import shutil
import socket
import subprocess
import tempfile
import time
import urllib.parse
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def shoot(url: str, path: Path, height: int = 900, wait_ms: int = 15000) -> None:
    subprocess.run(
        [
            "chromium",
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            f"--virtual-time-budget={wait_ms}",
            f"--window-size=1500,{height}",
            f"--screenshot={path}",
            url,
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "img" / "telemetry")
    args = parser.parse_args()
    os.environ["RAY_AUTH_MODE"] = "disabled"
    import ray
    import yaml

    from hola_ray.methods.config import RunConfig
    from hola_ray.methods.trainer import Trainer
    from hola_ray.process import NAMESPACE, init_ray

    port = free_port()
    url = init_ray(NAMESPACE, 2, dashboard=True, metrics_port=port)
    session = Path(ray._private.worker.global_worker.node.get_session_dir_path())
    scratch = Path(tempfile.mkdtemp())
    config = (session / "metrics/prometheus/prometheus.yml").read_text()
    (scratch / "prometheus.yml").write_text(
        config.replace("scrape_interval: 10s", "scrape_interval: 2s")
    )
    prometheus = subprocess.Popen(
        [
            "prometheus",
            f"--config.file={scratch / 'prometheus.yml'}",
            f"--storage.tsdb.path={scratch / 'tsdb'}",
            "--web.listen-address=127.0.0.1:9090",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        # the default run, short: its learner starts from a shipped member, so its success
        # is a curve; trained to generation 2, then resumed to 4 (a second coordinator,
        # whose Repr has the state it resumed from)
        raw = yaml.safe_load((ROOT / "configs" / "default.yaml").read_text())
        raw["oracle"] |= {"env_steps": 16384}
        raw["grapher"] |= {"episodes_per_edge": 16}
        raw["validation"] = {"episodes": 24}
        tags = {"run": "screenshot", "trial": ""}
        for generations in (2, 4):
            config = RunConfig.from_dict(raw | {"generations": generations})
            Trainer(config, scratch / "run", progress=False, tags=tags).fit()
        time.sleep(25)  # the last values through Ray's exporter and two scrapes
        args.out.mkdir(parents=True, exist_ok=True)
        shoot(f"{url}/#/actors", args.out / "actors_tab.png", height=1300)
        # one series per run and trial (a resumed run's coordinators are two workers)
        expr = "max by (run, trial) (ray_hola_ray_learner_success)"
        query = f"g0.expr={urllib.parse.quote(expr)}&g0.tab=0&g0.range_input=3m"
        shoot(f"http://127.0.0.1:9090/graph?{query}", args.out / "prometheus_learner_success.png")
        print(f"wrote {args.out}/actors_tab.png and prometheus_learner_success.png")
    finally:
        prometheus.terminate()
        ray.shutdown()
        shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    main()
