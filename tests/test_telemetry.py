"""Watching a run from Ray: its figures as Prometheus series on the metrics port
(`--metrics-port`), equal to metrics.csv, and the coordinator's Repr in the state API."""

from __future__ import annotations

import re
import socket
import time
import urllib.request

import pytest
import yaml

from hola_ray.homes import ROOT
from hola_ray.methods.config import RunConfig
from hola_ray.methods.trainer import Trainer
from hola_ray.population.rundir import RunDir
from hola_ray.population.telemetry import SERIES

SMOKE = ROOT / "configs" / "smoke.yaml"
pytestmark = pytest.mark.ray  # its own Ray, with the dashboard


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def watched():
    """A local Ray as `python -m hola_ray.run --metrics-port PORT` starts it, with its
    dashboard: the metrics port and the dashboard's URL."""
    import ray

    from hola_ray.process import NAMESPACE, init_ray

    port = free_port()
    url = init_ray(NAMESPACE, 2, dashboard=True, metrics_port=port)
    yield port, url
    ray.shutdown()


def scrape(port: int) -> dict[tuple[str, str, str], float]:
    """(series, run, trial) → value of every `hola_ray_*` series Ray serves."""
    text = urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=5).read().decode()
    out = {}
    for line in text.splitlines():
        found = re.match(r"^ray_(hola_ray_\w+)\{(.*)\} (\S+)$", line)
        if found:
            tags = dict(re.findall(r'(\w+)="([^"]*)"', found[2]))
            out[(found[1], tags["run"], tags["trial"])] = float(found[3])
    return out


def test_a_runs_figures_are_served_as_metrics_equal_to_its_csv(watched, tmp_path):
    """A smoke run's figures appear on the metrics port as `hola_ray_*` gauges tagged by
    run and trial, each equal to the last metrics.csv row's column, the generation series
    at the last generation; the coordinator's Repr names the run and its state."""
    from ray.util.state import list_actors

    metrics_port, dashboard = watched
    config = RunConfig.from_dict(yaml.safe_load(SMOKE.read_text()))
    tags = {"run": "watched", "trial": "hola-s0"}
    Trainer(config, tmp_path / "run", progress=False, tags=tags).fit()
    last = RunDir(tmp_path / "run").metrics_rows()[-1]
    wanted = {f"hola_ray_{name}": float(last[column]) for name, (column, _) in SERIES.items()}
    assert wanted["hola_ray_generation"] == config.generations == 1
    assert wanted["hola_ray_acceptances"] == int(last["accepted"])
    deadline, seen = time.monotonic() + 60, {}
    while time.monotonic() < deadline:  # Ray exports on an interval of its own
        seen = {s: v for (s, run, trial), v in scrape(metrics_port).items() if run == "watched"}
        if seen == wanted:
            break
        time.sleep(1)
    assert seen == wanted
    assert all(trial == "hola-s0" for (_, run, trial) in scrape(metrics_port) if run == "watched")

    # the dashboard's state API (this test's Ray's, not another's on the machine)
    [actor] = list_actors(dashboard, filters=[("class_name", "=", "Coordinator")], detail=True)
    assert actor.repr_name == "coordinator:watched/hola-s0 (hola; starting at generation 0)"


def test_a_local_ray_is_lean_and_serves_its_agent_on_a_free_port(watched):
    """This module's Ray, started as a command starts it (another Ray may run beside it:
    the suite's other worker, a build), has its dashboard agent's HTTP server on a port the
    system picked, recorded where the dashboard looks it up, and serving; never Ray's fixed
    52365, which a second Ray on the machine could not bind (it retried for 3.4 s before its
    raylet registered, then ran without the server: -1). No autoscaler monitor; the log
    monitor kept (a command's workers print to its terminal); the dashboard, asked for,
    with its head."""
    import json

    import ray
    from ray._private import ray_constants
    from ray._private.parameter import RayParams
    from ray.dashboard import consts
    from ray.experimental.internal_kv import _internal_kv_get

    from hola_ray.third_party import LEAN_LOCAL_RAY, lean_local_ray

    assert lean_local_ray()  # in place, and a second call keeps Ray's own underneath
    assert RayParams().dashboard_agent_listen_port == 0
    assert RayParams(dashboard_agent_listen_port=52365).dashboard_agent_listen_port == 52365
    assert {k: getattr(RayParams(), k) for k in LEAN_LOCAL_RAY} == LEAN_LOCAL_RAY
    node_id = ray.get_runtime_context().get_node_id()
    key = f"{consts.DASHBOARD_AGENT_ADDR_NODE_ID_PREFIX}{node_id}".encode()
    answer = _internal_kv_get(key, namespace=ray_constants.KV_NAMESPACE_DASHBOARD)
    ip, http_port, _ = json.loads(answer)
    assert http_port not in (-1, 52365)
    with urllib.request.urlopen(f"http://{ip}:{http_port}/api/local_raylet_healthz") as served:
        assert served.status == 200
    started = ray._private.worker._global_node.all_processes
    assert ray_constants.PROCESS_TYPE_MONITOR not in started
    assert ray_constants.PROCESS_TYPE_LOG_MONITOR in started
    assert ray_constants.PROCESS_TYPE_DASHBOARD in started  # asked for: its head stays


def test_the_grafana_dashboard_plots_every_series_per_run_and_trial():
    import json

    dashboard = json.loads((ROOT / "cluster" / "grafana" / "hola_ray_dashboard.json").read_text())
    exprs = [p["targets"][0]["expr"] for p in dashboard["panels"]]
    plotted = {re.search(r"ray_(hola_ray_\w+)\{", e)[1] for e in exprs}
    assert plotted == {f"hola_ray_{name}" for name in SERIES}
    assert all(e.startswith("max by (run, trial) (") for e in exprs)
    assert [v["name"] for v in dashboard["templating"]["list"]] == ["datasource", "run", "trial"]


def test_run_and_experiment_take_a_metrics_port(monkeypatch, capsys):
    """`--metrics-port PORT` reaches the Ray the command starts (`init_ray`, as the test
    above starts it)."""
    from hola_ray import process
    from hola_ray.commands import run
    from hola_ray.experiment import command

    asked = []
    monkeypatch.setattr(process, "init_ray", lambda *a, **k: asked.append(a))
    run.init_ray(run.parse_args(["--metrics-port", "8080", "--no-dashboard"]))
    assert asked == [("hola_ray", None, False, 8080)]
    # a local run starts Ray's dashboard only when asked (it costs 2-3 s of the start)
    run.init_ray(run.parse_args([]))
    run.init_ray(run.parse_args(["--dashboard"]))
    assert [a[2] for a in asked[1:]] == [False, True]
    with pytest.raises(SystemExit):
        command.main(["--help"])
    assert "--metrics-port PORT" in capsys.readouterr().out
